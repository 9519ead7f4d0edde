"""The cosine-weighted Phong BRDF of DESIGN.md §4 on a cubemap, in Haar, per (n, ωo).

Ng 2004's third factor: for a surface point with normal n seen from ωo (mirror direction
r = reflect(ωo, n)),

    ρ̃(ω) = (kd/π + ks·(s+1)/(2π)·max(r·ω, 0)^s) · max(n·ω, 0)

which is linear in (kd, ks): ρ̃ = kd·D + ks·G with the *diffuse factor*
D(ω) = max(n·ω, 0)/π (depends on n only) and the *glossy factor*
G(ω) = (s+1)/(2π)·max(r·ω, 0)^s·max(n·ω, 0). Each is integrated over every texel (S×S
area-element-weighted midpoints, :func:`prtbench.transport.wavelet.cubemap.subsample_pattern`), so the
texel's solid angle is folded in, where :mod:`prtbench.transport.wavelet.triple` expects it; then
Haar-transformed per face and truncated to the ``keep`` largest magnitudes per point.

Ng 2004 tabulates ρ̃ over sampled normals × view directions. The wavelet triple-product method instead projects
G for each vertex's own (n, r) every frame (the normals are static, so D is projected once), so
the BRDF carries no direction-binning error and its cost, O(P·6N²·S²) per frame, is inside the
measured frame time (see :mod:`methods.wavelet.tp`).
"""

from __future__ import annotations

import math

import numpy as np

from prtbench.api.errors import InvalidInputError
from prtbench.transport.wavelet import haar
from prtbench.transport.wavelet.cubemap import (
    check_resolution,
    directions_to_texels,
    subsample_pattern,
    texel_directions,
)

#: Texel subsamples (points × 6N²·S²) evaluated at once: bounds a chunk's float32 scratch.
CHUNK_SAMPLES = 1 << 22


def reflect(view: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Mirror directions r = 2(n·ωo)n − ωo, (P, 3) (unit ``view`` ωo and ``normals``)."""
    return 2.0 * np.sum(normals * view, axis=-1, keepdims=True) * normals - view


def factor_texels(normals: np.ndarray, *, n: int, reflections: np.ndarray | None = None,
                  shininess: float | None = None, samples: int = 1) -> np.ndarray:
    """Texel integrals of the diffuse (``reflections`` None) or glossy factor, (P, 6N²) float32.

    Parameters
    ----------
    normals : ndarray, shape (P, 3)
        Unit normals.
    n : int
        Cubemap face resolution.
    reflections : ndarray, shape (P, 3), optional
        Unit mirror directions; given, the glossy factor G, else the diffuse factor D.
    shininess : float, optional
        Phong exponent s >= 0 (glossy factor only).
    samples : int
        S: S×S midpoints per texel.
    """
    n = check_resolution(n)
    glossy = reflections is not None
    if glossy and (shininess is None or not math.isfinite(shininess) or shininess < 0):
        raise InvalidInputError(f"Phong shininess={shininess!r}; accepted: finite, >= 0")
    dirs, weights = subsample_pattern(n, samples)
    ss = weights.shape[-1]
    dirs_t = np.ascontiguousarray(dirs.reshape(-1, 3).T.astype(np.float32))  # (3, M·S²)
    w = np.broadcast_to(weights, (6, *weights.shape)).reshape(-1).astype(np.float32)
    nrm = np.asarray(normals, np.float32).reshape(-1, 3)
    ref = np.asarray(reflections, np.float32).reshape(-1, 3) if glossy else None
    m = 6 * n * n
    out = np.empty((len(nrm), m), np.float32)
    step = max(1, CHUNK_SAMPLES // dirs_t.shape[1])
    for start in range(0, len(nrm), step):
        sl = slice(start, start + step)
        value = _dot(nrm[sl], dirs_t)
        np.maximum(value, 0.0, out=value)
        if glossy:
            lobe = _dot(ref[sl], dirs_t)
            np.maximum(lobe, 0.0, out=lobe)
            # sh.phong_lobe in place, in float32 (this chunk loop is the precompute's hot path):
            # zero behind the mirror plane at every s, s = 0 included (not 0^0 = 1).
            np.power(lobe, np.float32(shininess), out=lobe, where=lobe > 0.0)
            value *= lobe
            value *= np.float32((shininess + 1.0) / (2.0 * math.pi))
        else:
            value *= np.float32(1.0 / math.pi)
        value *= w
        out[sl] = value.reshape(len(value), m, ss).sum(axis=-1) if ss > 1 else value
    return out


def _dot(vectors: np.ndarray, dirs_t: np.ndarray) -> np.ndarray:
    """(P, R) float32 v·ω by three broadcast multiply-adds (faster than BLAS at inner size 3)."""
    out = vectors[:, 0:1] * dirs_t[0]
    out += vectors[:, 1:2] * dirs_t[1]
    out += vectors[:, 2:3] * dirs_t[2]
    return out


def project(normals: np.ndarray, *, n: int, keep: int, reflections: np.ndarray | None = None,
            shininess: float | None = None, samples: int = 1
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Haar coefficients of D or G per point, the ``keep`` largest magnitudes of each.

    Parameters
    ----------
    normals, reflections, shininess, samples, n
        As :func:`factor_texels`.
    keep : int
        Coefficients kept per point, 1..6N².

    Returns
    -------
    points, coeffs : ndarray, shape (nnz,), int64
        Point (0..P−1) and flat coefficient of each kept non-zero entry, by point then
        coefficient (ready for :class:`~prtbench.transport.wavelet.triple.SparseRows` keys).
    values : ndarray, shape (nnz,), float32
    """
    n = check_resolution(n)
    m = 6 * n * n
    if isinstance(keep, bool) or int(keep) != keep or not 1 <= keep <= m:
        raise InvalidInputError(f"brdf_keep={keep!r}; accepted: integers 1..{m} (6·N²)")
    keep = int(keep)
    normals = np.asarray(normals, np.float64).reshape(-1, 3)
    reflections = None if reflections is None else np.asarray(reflections).reshape(-1, 3)
    step = max(1, CHUNK_SAMPLES // (m * int(samples) ** 2))  # bounds the dense texels
    parts = []
    for start in range(0, len(normals), step):
        sl = slice(start, start + step)
        texels = factor_texels(normals[sl], n=n, reflections=None if reflections is None
                               else reflections[sl], shininess=shininess, samples=samples)
        coeffs = haar.forward(texels.reshape(-1, 6, n, n), dtype=np.float32).reshape(-1, m)
        if keep < m:
            # Sorted within each point, so (point, coefficient) keys come out increasing.
            idx = np.sort(np.argpartition(-np.abs(coeffs), keep - 1, axis=1)[:, :keep], axis=1)
            vals = np.take_along_axis(coeffs, idx, axis=1)
        else:
            idx, vals = np.broadcast_to(np.arange(m), coeffs.shape), coeffs
        rows = np.broadcast_to(np.arange(start, start + len(coeffs))[:, None], idx.shape)
        nonzero = vals != 0
        parts.append((rows[nonzero], idx[nonzero], vals[nonzero]))
    if not parts:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.float32)
    return (np.concatenate([q[0] for q in parts]).astype(np.int64),
            np.concatenate([q[1] for q in parts]).astype(np.int64),
            np.concatenate([q[2] for q in parts]))


def direction_bins(dirs: np.ndarray, t: int) -> np.ndarray:
    """Flat texel index (face·t² + row·t + column) of each direction on a 6×t×t cube, (P,)."""

    face, row, col, _, _ = directions_to_texels(dirs, t)
    return face * t * t + row * t + col


class BrdfTable:
    """Ng 2004's tabulated glossy factor: G in Haar for sampled normals × mirror directions.

    Normals and mirror directions are binned on a 6×t×t cube and G is projected (texel
    integrals, Haar, ``keep`` largest) once per (normal bin, mirror bin) at the bins' centre
    directions; only the normal bins that the object's (static) vertex normals fall in are
    tabulated, with every mirror bin. A frame looks up the nearest entry per vertex (O(kept)
    per vertex, no texel work), at the price of binning n and r to the table's resolution.

    Attributes
    ----------
    t : int
    indptr : ndarray, shape (B·6t² + 1,), int64
        Entry ``slot·6t² + mirror bin`` holds ``coeffs[indptr[e]:indptr[e+1]]``, ascending.
    coeffs : ndarray, shape (nnz,), int32
    values : ndarray, shape (nnz,), float32
    """

    def __init__(self, t: int, indptr: np.ndarray, coeffs: np.ndarray, values: np.ndarray):
        self.t, self.indptr, self.coeffs, self.values = int(t), indptr, coeffs, values

    @classmethod
    def build(cls, normals: np.ndarray, *, t: int, n: int, keep: int, shininess: float,
              samples: int = 1) -> tuple["BrdfTable", np.ndarray]:
        """The table for vertex ``normals`` (P, 3) and each vertex's slot (P,) int64 in it."""

        t = check_resolution(t, what="brdf_table")
        bins = direction_bins(normals, t)
        present, slots = np.unique(bins, return_inverse=True)
        centres = texel_directions(t).reshape(-1, 3)
        r_count = len(centres)
        table_n = np.repeat(centres[present], r_count, axis=0)
        table_r = np.tile(centres, (len(present), 1))
        points, coeffs, values = project(table_n, n=n, keep=keep, reflections=table_r,
                                         shininess=shininess, samples=samples)
        indptr = np.zeros(len(table_n) + 1, np.int64)
        np.cumsum(np.bincount(points, minlength=len(table_n)), out=indptr[1:])
        return cls(t, indptr, coeffs.astype(np.int32), values.astype(np.float32)), slots

    @property
    def nbytes(self) -> int:
        return int(self.indptr.nbytes + self.coeffs.nbytes + self.values.nbytes)

    def arrays(self, prefix: str) -> dict[str, np.ndarray]:
        return {f"{prefix}indptr": self.indptr, f"{prefix}coeffs": self.coeffs,
                f"{prefix}values": self.values, f"{prefix}t": np.array(self.t)}

    @classmethod
    def from_arrays(cls, arrays, prefix: str) -> "BrdfTable":
        return cls(int(arrays[f"{prefix}t"]), arrays[f"{prefix}indptr"],
                   arrays[f"{prefix}coeffs"], arrays[f"{prefix}values"])

    def gather(self, slots: np.ndarray, reflections: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Entries of each vertex's nearest (normal slot, mirror bin), as :func:`project`
        returns them."""
        entry = (np.asarray(slots, np.int64) * 6 * self.t * self.t
                 + direction_bins(reflections, self.t))
        starts = self.indptr[entry]
        counts = self.indptr[entry + 1] - starts
        total = int(counts.sum())
        before = np.cumsum(counts) - counts
        picked = np.repeat(starts - before, counts) + np.arange(total)
        points = np.repeat(np.arange(len(entry), dtype=np.int64), counts)
        return points, self.coeffs[picked].astype(np.int64), self.values[picked]
