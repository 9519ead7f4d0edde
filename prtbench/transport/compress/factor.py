"""In-out factorization of the Phong BRDF (Kautz & McCool 1999; Wang et al. 2004, Sloan 2004).

The cosine-weighted BRDF of DESIGN.md §4 in a surface's local frame (normal +Z, tangent +X),

    ρ_c(ωi, ωo) = f_c(ωi, ωo) · max(n·ωi, 0),   f = kd/π + ks·(s+1)/(2π)·max(ωi·r, 0)^s,

is approximated by J separable terms ρ_c(ωi, ωo) ≈ Σ_j g_jc(ωo) h_j(ωi): an RGB outgoing factor
g_j and a scalar incoming factor h_j (one for all channels, so that each term needs one transfer
vector per vertex). We use the truncated singular value decomposition of the BRDF sampled on two
hemisphere grids (:class:`HemisphereGrid`: ωo rows × 3 channels against ωi columns), weighted by
the square roots of the cells' solid angles so that truncation is the L²-optimal rank-J
approximation of ρ over the hemisphere pair (Eckart–Young), which is what Wang et al. 2004 do
(the SVD of the sampled BRDF; Kautz & McCool's normalised decomposition uses the same SVD).

Every sampled row of ρ carries the factor cos θi, hence so does every h_j (it lies in the rows'
span): the tables store h̃_j = h_j / cos θi, which the cosine-weighted transfer rays need
(T^j_i = ∫ Y_i V h_j dω ≈ π/M Σ_r V_r Y_i(ω_r) h̃_j(ω_r)). A diffuse material (ks = 0) has
rank exactly 1 (g ∝ kd, h = cos θi). Both factors are tabulated on their grids and looked up
bilinearly (:func:`bilinear_lookup`, the GL lookup of a texture with φ repeating and θ clamped).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from prtbench.api.errors import InvalidInputError
from prtbench.transport.parallel import single_threaded_blas
from prtbench.transport.sh import phong_lobe

#: Singular values below this fraction of the largest count as zero (the numerical rank):
#: squared values come from an eigendecomposition of the Gram matrix, whose rounding (~1e-16
#: of the largest) sits far below 1e-12.
RANK_TOLERANCE = 1e-6
#: Dense SVD up to this many matrix entries, above it the eigendecomposition of the smaller Gram.
_DENSE_SVD_VALUES = 1 << 20


@dataclass(frozen=True)
class HemisphereGrid:
    """Cell centres of an equal-angle grid over the upper hemisphere, local frame (+Z normal).

    Row r holds θ = (r + ½)·(π/2)/rows, column c holds φ = (c + ½)·2π/cols: the texel centres of
    a rows × cols texture with s = φ/(2π) (repeating) and t = θ/(π/2) (clamped), which is how
    the shader reads the tables.
    """

    rows: int
    cols: int

    def __post_init__(self) -> None:
        if self.rows < 1 or self.cols < 1:
            raise InvalidInputError(f"hemisphere grid {self.rows} x {self.cols}; accepted: "
                                    "at least 1 x 1")

    @property
    def size(self) -> int:
        return self.rows * self.cols

    def angles(self) -> tuple[np.ndarray, np.ndarray]:
        """(θ (rows,), φ (cols,)) of the cell centres."""
        theta = (np.arange(self.rows) + 0.5) * (0.5 * np.pi / self.rows)
        phi = (np.arange(self.cols) + 0.5) * (2.0 * np.pi / self.cols)
        return theta, phi

    def directions(self) -> np.ndarray:
        """(rows·cols, 3) float64 unit directions, row-major (θ row, then φ column)."""
        theta, phi = self.angles()
        st, ct = np.sin(theta)[:, None], np.cos(theta)[:, None]
        return np.stack(np.broadcast_arrays(st * np.cos(phi), st * np.sin(phi), ct),
                        axis=-1).reshape(-1, 3)

    def solid_angles(self) -> np.ndarray:
        """(rows·cols,) exact solid angles of the cells (they sum to 2π)."""
        edges = np.arange(self.rows + 1) * (0.5 * np.pi / self.rows)
        band = np.cos(edges[:-1]) - np.cos(edges[1:])
        return np.repeat(band * (2.0 * np.pi / self.cols), self.cols)


def phong_cosine_matrix(kd, ks, shininess: float, *, out_grid: HemisphereGrid,
                        in_grid: HemisphereGrid) -> np.ndarray:
    """ρ_c(ωi, ωo) = f_c(ωi, ωo)·cos θi sampled at the grids' cell centres.

    Returns
    -------
    ndarray, shape (out_grid.size, 3, in_grid.size), float64
        Axis 0 the outgoing direction, axis 1 the channel, axis 2 the incoming direction.
    """
    wo, wi = out_grid.directions(), in_grid.directions()
    mirror = wo * np.array([-1.0, -1.0, 1.0])  # r = 2(n·ωo)n − ωo with n = +Z
    lobe = phong_lobe(mirror @ wi.T, float(shininess))
    cos_in = wi[:, 2]
    kd, ks = np.asarray(kd, np.float64), np.asarray(ks, np.float64)
    return ((kd[None, :, None] / np.pi) + ks[None, :, None] * lobe[:, None, :]) * cos_in


@dataclass(frozen=True)
class FactoredBrdf:
    """J separable terms of one material's cosine-weighted BRDF.

    Attributes
    ----------
    outgoing : ndarray, shape (J, 3, out.rows, out.cols)
        g_jc(ωo) on the outgoing grid (RGB).
    incoming : ndarray, shape (J, in.rows, in.cols)
        h̃_j(ωi) = h_j(ωi) / cos θi on the incoming grid.
    singular_values : ndarray, shape (R,)
        All weighted singular values σ (descending) up to the numerical rank R.
    out_grid, in_grid : HemisphereGrid
    """

    outgoing: np.ndarray
    incoming: np.ndarray
    singular_values: np.ndarray
    out_grid: HemisphereGrid
    in_grid: HemisphereGrid

    @property
    def terms(self) -> int:
        return int(self.outgoing.shape[0])

    @property
    def rank(self) -> int:
        return int(len(self.singular_values))

    def relative_error(self, terms: int | None = None) -> float:
        """‖ρ − ρ_J‖ / ‖ρ‖ in the solid-angle-weighted L² norm (from the singular values)."""
        j = self.terms if terms is None else int(terms)
        s2 = self.singular_values.astype(np.float64) ** 2
        return float(math.sqrt(s2[j:].sum() / s2.sum())) if s2.sum() > 0 else 0.0

    def reconstruct(self) -> np.ndarray:
        """Σ_j g_j(ωo) h_j(ωi) on the grids, shaped like :func:`phong_cosine_matrix`."""
        cos_in = self.in_grid.directions()[:, 2]
        g = self.outgoing.reshape(self.terms, 3, -1)
        h = self.incoming.reshape(self.terms, -1) * cos_in
        return np.einsum("jco,ji->oci", g, h)


@single_threaded_blas()
def _weighted_svd(a: np.ndarray, *, terms: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(σ up to the numerical rank, U (m, terms), V (n, terms)) of a dense (m, n) matrix.

    The Phong lobe's symmetry makes singular values come in equal pairs, whose singular
    vectors are any rotation within the pair: a J that cuts through a pair keeps whichever
    one LAPACK returns, and multi-threaded OpenBLAS returns a different one for a different
    thread count (a sweep worker holds BLAS to one thread, a serial run does not: 0.05 dB
    apart at J = 8 on plants). The factorisation therefore runs on one BLAS thread.
    """
    m, n = a.shape
    if a.size <= _DENSE_SVD_VALUES:
        u, s, vt = np.linalg.svd(a, full_matrices=False)
        v = vt.T
    else:  # the Gram matrix of the smaller side: an (m × m) eigenproblem instead of an SVD
        from scipy.linalg import eigh

        small = a if m <= n else a.T
        values, vectors = eigh(small @ small.T)
        order = np.argsort(values)[::-1]
        s = np.sqrt(np.clip(values[order], 0.0, None))
        left = vectors[:, order[:terms]]
        right = small.T @ left / np.where(s[:terms] > 0, s[:terms], 1.0)
        u, v = (left, right) if m <= n else (right, left)
    rank = int(np.sum(s > RANK_TOLERANCE * s[0])) if s.size and s[0] > 0 else 0
    return s[:rank], u[:, :terms], v[:, :terms]


def factor_brdf(kd, ks, shininess: float, *, terms: int, out_grid: HemisphereGrid,
                in_grid: HemisphereGrid, name: str = "material", at_most: bool = False
                ) -> FactoredBrdf:
    """The J = ``terms`` best separable terms of the material's cosine-weighted BRDF.

    Parameters
    ----------
    kd, ks : RGB in [0, 1]
    shininess : float
        Phong exponent s ≥ 0.
    terms : int
        J, from 1 to the numerical rank of the sampled BRDF.
    out_grid, in_grid : HemisphereGrid
    name : str
        For the error message.
    at_most : bool
        Keep min(``terms``, rank) terms instead of refusing ``terms`` above the rank.

    Raises
    ------
    InvalidInputError
        ``terms`` above the rank (a diffuse material has rank 1), unless ``at_most``.
    """
    rho = phong_cosine_matrix(kd, ks, shininess, out_grid=out_grid, in_grid=in_grid)
    w_out = np.sqrt(out_grid.solid_angles())
    w_in = np.sqrt(in_grid.solid_angles())
    weighted = (rho * w_out[:, None, None] * w_in[None, None, :]).reshape(-1, in_grid.size)
    if int(terms) != terms or terms < 1:
        raise InvalidInputError(f"terms={terms!r}; accepted: integers >= 1")
    s, u, v = _weighted_svd(weighted, terms=int(terms))
    if at_most:
        terms = min(int(terms), len(s))
        u, v = u[:, :terms], v[:, :terms]
    elif terms > len(s):
        raise InvalidInputError(
            f"terms={terms} for material '{name}' (ks={tuple(float(c) for c in ks)}, "
            f"s={float(shininess):g}), whose sampled BRDF has rank {len(s)}; accepted: terms "
            f"1 to {len(s)}" + (" (a diffuse material is one term)" if len(s) == 1 else ""))
    # g_j = σ_j u_j / √w_out, h_j = v_j / √w_in; h̃_j = h_j / cos θi. The sign of each pair is
    # fixed (positive mean of h̃) so refits give the same tables.
    cos_in = in_grid.directions()[:, 2]
    h = v / w_in[:, None] / cos_in[:, None]  # (n_in, J)
    g = (u * s[:terms]).reshape(out_grid.size, 3, terms) / w_out[:, None, None]
    sign = np.where(h.sum(axis=0) < 0, -1.0, 1.0)
    h, g = h * sign, g * sign
    outgoing = np.transpose(g, (2, 1, 0)).reshape(terms, 3, out_grid.rows, out_grid.cols)
    incoming = h.T.reshape(terms, in_grid.rows, in_grid.cols)
    return FactoredBrdf(outgoing, incoming, s, out_grid, in_grid)


def local_angles_to_texture(directions: np.ndarray, grid: HemisphereGrid
                            ) -> tuple[np.ndarray, np.ndarray]:
    """Continuous texel coordinates (row, col) of local directions (M, 3) on ``grid``.

    θ beyond the horizon is clamped to it (the last row), as GL clamps t.
    """
    d = np.asarray(directions, np.float64)
    theta = np.arccos(np.clip(d[:, 2], -1.0, 1.0))
    phi = np.mod(np.arctan2(d[:, 1], d[:, 0]), 2.0 * np.pi)
    row = np.minimum(theta, 0.5 * np.pi) / (0.5 * np.pi) * grid.rows - 0.5
    col = phi / (2.0 * np.pi) * grid.cols - 0.5
    return row, col


def bilinear_lookup(table: np.ndarray, directions: np.ndarray, grid: HemisphereGrid
                    ) -> np.ndarray:
    """Bilinear lookup of tables (..., rows, cols) at local directions (M, 3): (M, ...).

    φ wraps around (GL REPEAT), θ clamps to the first and last rows (CLAMP_TO_EDGE).
    """
    row, col = local_angles_to_texture(directions, grid)
    row = np.clip(row, 0.0, grid.rows - 1.0)
    r0 = np.floor(row).astype(np.int64)
    r1 = np.minimum(r0 + 1, grid.rows - 1)
    fr = row - r0
    c0f = np.floor(col)
    fc = col - c0f
    c0 = np.mod(c0f.astype(np.int64), grid.cols)
    c1 = np.mod(c0 + 1, grid.cols)
    t = np.moveaxis(np.asarray(table), (-2, -1), (0, 1))  # (rows, cols, ...)
    extra = (slice(None),) + (None,) * (t.ndim - 2)
    fr, fc = fr[extra], fc[extra]
    return ((1 - fr) * ((1 - fc) * t[r0, c0] + fc * t[r0, c1])
            + fr * ((1 - fc) * t[r1, c0] + fc * t[r1, c1]))
