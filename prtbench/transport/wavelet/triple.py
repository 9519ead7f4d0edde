"""Haar triple-product integrals ∫ L·V·ρ̃ on a cubemap by Ng 2004's tree algorithm.

Ng, Ramamoorthi and Hanrahan 2004 (Triple Product Wavelet Integrals for All-Frequency
Relighting) light a point that changes view with the product of three signals in one basis:
the light L, the visibility V and the cosine-weighted BRDF ρ̃,

    B = Σ_t L_t V_t ρ̃_t = Σ_ijk L̂_i V̂_j ρ̂_k C_ijk,    C_ijk = Σ_t Ψ_i(t) Ψ_j(t) Ψ_k(t).

Convention (:mod:`prtbench.transport.wavelet`): the weights live in the transport, here its BRDF factor:
L_t is the texel-mean radiance, V_t the texel's visible fraction (no weight, no cosine) and
ρ̃_t = ∫_texel ρ̃ dω (solid angle folded in), so the texel sum is the cubemap integral.

For the orthonormal non-standard Haar basis of :mod:`prtbench.transport.wavelet.haar` (a function on a
support of S×S texels is ±1/S there; a face's scaling function is 1/N) C_ijk vanishes unless
the supports nest (Ng 2004, §4), which leaves, per face:

1. all three the face's scaling function: C = 1/N;
2. two the same wavelet w, the third the scaling function or a strictly coarser wavelet whose
   support holds w's: C = the third's (constant) value on supp(w). Summed over the third, the
   coefficients give x̄(w), the *mean of that signal over supp(w)*, so the term is
   L̂_w V̂_w ρ̄(w) + L̂_w ρ̂_w V̄(w) + V̂_w ρ̂_w L̄(w);
3. the three distinct wavelets (LH, HL, HH) of one node: their product is +1/S³ on all S²
   texels, C = 1/S, for each of the 6 ways to give the three signals the three types.

The mean x̄(w) is the *parent sum*: the face mean x̂_0/N plus, for every ancestor node of w,
its three wavelets' signs on the quadrant that leads to w, over the ancestor's support side.
:func:`mean_pyramid` runs it top-down over a dense signal (O(6N²), once per frame for the
light); :func:`parent_means` walks it for sparse per-point signals at arbitrary coefficients
(O(log N) lookups each). So :func:`triple_product` costs O((|L∩V| + |L∩ρ̃|)·log N + |V| + |ρ̃|)
per point, where |·| are stored (non-zero) coefficients: it never touches the 6N² texels, the
sublinearity Ng 2004 shows. :func:`brute_force` is the per-texel product it replaces.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from prtbench.api.errors import InvalidInputError
from prtbench.transport.wavelet.cubemap import check_resolution
from prtbench.transport.wavelet.haar import inverse

#: Sign of the LH, HL and HH wavelets of a node on its child quadrant (dy, dx): LH changes sign
#: across columns, HL across rows, HH across both (the in-place layout of haar.forward).
SIGNS = np.array([[[1, -1], [1, -1]],
                  [[1, 1], [-1, -1]],
                  [[1, -1], [-1, 1]]], dtype=np.float64)


def _resolution(n_coeffs: int) -> int:
    n = int(round((n_coeffs / 6) ** 0.5))
    if 6 * n * n != n_coeffs:
        raise InvalidInputError(f"{n_coeffs} coefficients; accepted: 6·N² for a cubemap")
    return check_resolution(n)


def mean_pyramid(coeffs: np.ndarray) -> np.ndarray:
    """Mean of a signal over every coefficient's support, from its Haar coefficients.

    Parameters
    ----------
    coeffs : ndarray, shape (..., 6, N, N)
        Non-standard Haar coefficients (any leading axes, e.g. channels).

    Returns
    -------
    ndarray, shape (..., 6, N, N), float64
        At a wavelet's slot, the mean over its support (what the strictly coarser coefficients
        sum to there); at the scaling slot ``[0, 0]``, the face mean.
    """
    c = np.asarray(coeffs, dtype=np.float64)
    if c.ndim < 3 or c.shape[-3] != 6 or c.shape[-1] != c.shape[-2]:
        raise InvalidInputError(f"Haar cubemap shape {c.shape}; accepted: (..., 6, N, N)")
    n = check_resolution(c.shape[-1])
    out = np.zeros_like(c)
    mean = c[..., 0:1, 0:1] / n  # (..., 6, 1, 1): face means
    out[..., 0:1, 0:1] = mean
    h = 1
    while h < n:
        side = n // h
        lh, hl, hh = c[..., :h, h:2 * h], c[..., h:2 * h, :h], c[..., h:2 * h, h:2 * h]
        out[..., :h, h:2 * h] = mean
        out[..., h:2 * h, :h] = mean
        out[..., h:2 * h, h:2 * h] = mean
        child = np.empty((*c.shape[:-2], h, 2, h, 2))
        for dy in (0, 1):
            for dx in (0, 1):
                child[..., :, dy, :, dx] = mean + (SIGNS[0, dy, dx] * lh + SIGNS[1, dy, dx] * hl
                                                   + SIGNS[2, dy, dx] * hh) / side
        mean = child.reshape(*c.shape[:-2], 2 * h, 2 * h)
        h *= 2
    return out


@dataclass
class SparseRows:
    """Per-point sparse coefficient vectors, sorted by (point, coefficient).

    Attributes
    ----------
    keys : ndarray, shape (nnz,), int64
        ``point · n_coeffs + coefficient``, strictly increasing.
    values : ndarray, shape (nnz,), float32 or float64
    n_points, n_coeffs : int
    points, coeffs : ndarray, shape (nnz,), int32 or int64
        The two halves of each key (derived from ``keys`` when not given): kept beside the
        keys so that a frame does not divide them out again.
    """

    keys: np.ndarray
    values: np.ndarray
    n_points: int
    n_coeffs: int
    points: np.ndarray | None = None
    coeffs: np.ndarray | None = None

    def __post_init__(self):
        if self.points is None or self.coeffs is None:
            small = self.n_points * self.n_coeffs < 1 << 31
            points, coeffs = np.divmod(self.keys, self.n_coeffs)
            self.points = points.astype(np.int32 if small else np.int64)
            self.coeffs = coeffs.astype(np.int32)

    @classmethod
    def from_entries(cls, points, coeffs, values, *, n_points: int, n_coeffs: int
                     ) -> "SparseRows":
        """From (point, coefficient, value) triples in any order (no duplicates); zeros dropped."""
        points, coeffs = np.asarray(points, np.int64), np.asarray(coeffs, np.int64)
        values = np.asarray(values)
        keep = values != 0
        keys = points[keep] * n_coeffs + coeffs[keep]
        order = np.argsort(keys, kind="stable")
        keys = keys[order]
        if len(keys) > 1 and np.any(keys[1:] == keys[:-1]):
            raise InvalidInputError("sparse rows have duplicate (point, coefficient) entries")
        return cls(keys, values[keep][order], int(n_points), int(n_coeffs))

    @classmethod
    def from_dense(cls, x: np.ndarray, *, keep: int | None = None) -> "SparseRows":
        """From a (P, M) matrix, keeping each row's ``keep`` largest magnitudes (all if None)."""
        x = np.asarray(x)
        p, m = x.shape
        if keep is None or keep >= m:
            rows, cols = np.nonzero(x)
            return cls.from_entries(rows, cols, x[rows, cols], n_points=p, n_coeffs=m)
        idx = np.argpartition(-np.abs(x), keep - 1, axis=1)[:, :keep]
        rows = np.broadcast_to(np.arange(p)[:, None], idx.shape)
        return cls.from_entries(rows.ravel(), idx.ravel(), np.take_along_axis(x, idx, 1).ravel(),
                                n_points=p, n_coeffs=m)

    @property
    def nnz(self) -> int:
        return len(self.keys)

    @property
    def nbytes(self) -> int:
        """Bytes of the keys, values and their point and coefficient halves."""
        return int(self.keys.nbytes + self.values.nbytes + self.points.nbytes
                   + self.coeffs.nbytes)

    def lookup(self, points: np.ndarray, coeffs: np.ndarray) -> np.ndarray:
        """Stored value at each (point, coefficient), 0 where none is stored; float64."""
        return self.lookup_keys(np.asarray(points, np.int64) * self.n_coeffs
                                + np.asarray(coeffs, np.int64))

    def lookup_keys(self, keys: np.ndarray) -> np.ndarray:
        """As :meth:`lookup` for ready-made keys."""
        if self.nnz == 0:
            return np.zeros(len(keys))
        pos = np.minimum(np.searchsorted(self.keys, keys), self.nnz - 1)
        return np.where(self.keys[pos] == keys, self.values[pos].astype(np.float64), 0.0)

    def dense(self) -> np.ndarray:
        """(P, M) float64 (tests and small cases)."""
        out = np.zeros((self.n_points, self.n_coeffs))
        out[self.points, self.coeffs] = self.values
        return out


def decode(coeffs: np.ndarray, n: int):
    """Face, level and node of flat coefficient indices of a 6×N×N Haar cubemap.

    Returns
    -------
    face, level, y, x, kind : ndarray, shape (Q,), int64
        ``level`` ℓ: the node is one of 2^ℓ × 2^ℓ at its level (support side N/2^ℓ texels),
        -1 for a scaling coefficient; ``(y, x)`` the node; ``kind`` 0, 1, 2 for LH, HL, HH
        (-1 for scaling).
    """
    c = np.asarray(coeffs, np.int64)
    face, rest = np.divmod(c, n * n)
    row, col = np.divmod(rest, n)
    top = np.maximum(row, col)
    # floor(log2(top)) exactly: frexp gives top = m·2^e with m in [0.5, 1).
    level = np.where(top > 0, np.frexp(np.maximum(top, 1))[1].astype(np.int64) - 1, -1)
    h = np.where(level >= 0, 1 << np.maximum(level, 0), 1)
    y, x = row & (h - 1), col & (h - 1)
    kind = np.where(level < 0, -1, np.where(row < h, 0, np.where(col < h, 1, 2)))
    return face, level, y, x, kind


def wavelet_index(face, level, y, x, kind, n: int) -> np.ndarray:
    """Flat index of the ``kind`` (0 LH, 1 HL, 2 HH) wavelet of node (y, x) at ``level``."""
    h = np.int64(1) << np.asarray(level, np.int64)
    kind = np.asarray(kind)
    row = y + np.where(kind >= 1, h, 0)
    col = x + np.where(kind != 1, h, 0)
    return np.asarray(face, np.int64) * n * n + row * n + col


def parent_means(signal: SparseRows, points: np.ndarray, coeffs: np.ndarray) -> np.ndarray:
    """x̄(w): mean of each point's signal over the support of wavelet ``coeffs``, (Q,) float64.

    The parent sum: the face mean x̂_0/N plus, for each ancestor node (levels above w's), its
    three wavelets' signs on the child quadrant towards w over the ancestor's side. Only the
    point's stored coefficients are read: 1 + 3·level lookups per query.
    """
    n = _resolution(signal.n_coeffs)
    points = np.asarray(points, np.int64)
    face, level, y, x, kind = decode(coeffs, n)
    if np.any(kind < 0):
        raise InvalidInputError("parent_means takes wavelet coefficients (not the scaling ones)")
    out = signal.lookup(points, face * n * n) / n
    for ancestor in range(int(level.max(initial=-1))):
        act = np.flatnonzero(level > ancestor)
        shift = level[act] - ancestor
        ay, ax = y[act] >> shift, x[act] >> shift
        dy, dx = (y[act] >> (shift - 1)) & 1, (x[act] >> (shift - 1)) & 1
        # The node's three wavelets in one search (3 × the queries, a third of the calls).
        idx = np.concatenate([wavelet_index(face[act], ancestor, ay, ax, k, n) for k in range(3)])
        found = signal.lookup(np.tile(points[act], 3), idx).reshape(3, -1)
        total = (SIGNS[0, dy, dx] * found[0] + SIGNS[1, dy, dx] * found[1]
                 + SIGNS[2, dy, dx] * found[2])
        out[act] += total / (n >> ancestor)
    return out


def triple_product(light: np.ndarray, visibility: SparseRows, brdf: SparseRows, *,
                   light_mean: np.ndarray | None = None) -> np.ndarray:
    """Σ_t L_t V_t ρ̃_t for every point by the tree algorithm (module docstring).

    Parameters
    ----------
    light : ndarray, shape (M, C)
        The light's Haar coefficients, already truncated to the frame's k terms (zeros
        elsewhere); shared by all points.
    visibility, brdf : SparseRows
        P × M each: V̂ and ρ̂ per point.
    light_mean : ndarray, shape (M, C), optional
        :func:`mean_pyramid` of ``light`` (flattened), when the caller already has it.

    Returns
    -------
    ndarray, shape (P, C), float64
    """
    light = np.asarray(light, dtype=np.float64)
    m = visibility.n_coeffs
    if light.ndim != 2 or light.shape[0] != m or brdf.n_coeffs != m \
            or brdf.n_points != visibility.n_points:
        raise InvalidInputError(f"triple product of a light {light.shape}, visibility "
                                f"{visibility.n_points}×{m} and BRDF {brdf.n_points}×"
                                f"{brdf.n_coeffs}; accepted: (M, C), P×M, P×M")
    n = _resolution(m)
    p, channels = visibility.n_points, light.shape[1]
    if light_mean is None:
        light_mean = mean_pyramid(light.T.reshape(channels, 6, n, n)).reshape(channels, m).T
    scaling = np.zeros(m, dtype=bool)
    scaling[np.arange(6) * n * n] = True
    lit = np.any(light != 0, axis=1) & ~scaling  # wavelets among the k terms
    out = np.zeros((p, channels))

    def add(points, weight, per_coeff):  # out[points] += weight · per_coeff (Q, C)
        for ch in range(channels):
            out[:, ch] += np.bincount(points, weights=weight * per_coeff[:, ch], minlength=p)

    vp, vc, vv = visibility.points, visibility.coeffs, visibility.values.astype(np.float64)
    bp, bc, bv = brdf.points, brdf.coeffs, brdf.values.astype(np.float64)
    # Cases 1 and 2c: V and ρ̃ share the coefficient; the light's mean over its support (the
    # face mean at the scaling slot gives case 1, L̂_0 V̂_0 ρ̂_0 / N).
    both = brdf.lookup_keys(visibility.keys)
    hit = np.flatnonzero(both)
    add(vp[hit], vv[hit] * both[hit], light_mean[vc[hit]])
    # Case 2a: L and V share a wavelet; ρ̃'s parent sum there.
    sel = np.flatnonzero(lit[vc])
    add(vp[sel], vv[sel] * parent_means(brdf, vp[sel], vc[sel]), light[vc[sel]])
    # Case 2b: L and ρ̃ share a wavelet; V's parent sum there.
    sel = np.flatnonzero(lit[bc])
    add(bp[sel], bv[sel] * parent_means(visibility, bp[sel], bc[sel]), light[bc[sel]])
    # Case 3: the three types of one node, one from each signal. Each V entry fixes V's type;
    # L and ρ̃ take the other two either way round.
    face, level, y, x, kind = decode(vc, n)
    wav = np.flatnonzero(kind >= 0)
    face, level, y, x, kind = face[wav], level[wav], y[wav], x[wav], kind[wav]
    first = wavelet_index(face, level, y, x, (kind + 1) % 3, n)
    second = wavelet_index(face, level, y, x, (kind + 2) % 3, n)
    need = np.flatnonzero(lit[first] | lit[second])
    pts = vp[wav][need]
    first, second = first[need], second[need]
    rho_first, rho_second = brdf.lookup(pts, first), brdf.lookup(pts, second)
    weight = vv[wav][need] / (n >> level[need])
    per = light[first] * rho_second[:, None] + light[second] * rho_first[:, None]
    add(pts, weight, per)
    return out


def brute_force(light: np.ndarray, visibility: np.ndarray, brdf: np.ndarray) -> np.ndarray:
    """The per-texel product the tree algorithm replaces: Σ_t L_t V_t ρ̃_t, (P, C) float64.

    Parameters
    ----------
    light : ndarray, shape (M, C)
        Haar coefficients of the light.
    visibility, brdf : ndarray, shape (P, M)
        Haar coefficients per point (dense).
    """

    light = np.asarray(light, dtype=np.float64)
    m, channels = light.shape
    n = _resolution(m)
    texel_l = inverse(light.T.reshape(channels, 6, n, n)).reshape(channels, m)
    texel_v = inverse(np.asarray(visibility).reshape(-1, 6, n, n)).reshape(-1, m)
    texel_b = inverse(np.asarray(brdf).reshape(-1, 6, n, n)).reshape(-1, m)
    return (texel_v * texel_b) @ texel_l.T
