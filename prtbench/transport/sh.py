"""Real spherical harmonics and the SH algebra every PRT method shares.

Convention (DESIGN.md §5)
-------------------------
Real, orthonormal SH **without** the Condon–Shortley phase, polar axis +Z of the world frame
(θ from +Z, φ = atan2(y, x)), flat index ``i = l(l+1) + m``; ``n`` bands means ``n²``
coefficients (l = 0 … n−1)::

    Y_lm = √2 K_l^m P_l^m(cos θ) cos(mφ)        m > 0
    Y_l0 = K_l^0 P_l^0(cos θ)
    Y_lm = √2 K_l^|m| P_l^|m|(cos θ) sin(|m|φ)  m < 0

with K_l^m = √((2l+1)/(4π) · (l−m)!/(l+m)!) and P_l^m the associated Legendre functions without
the (−1)^m factor. Evaluation uses the normalised-Legendre recurrence with sin^m θ·cos/sin(mφ)
taken as Re/Im of (x + iy)^m, so it is stable to high bands (no factorials, no atan2) in float64.

Coefficient layout: a sampled function's coefficients are ``(n²,)`` or ``(n², C)`` (coefficients
first, e.g. RGB lights); per-point transfer vectors are ``(N, n²)`` (coefficients last).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from prtbench.api.cache import cached_arrays
from prtbench.api.errors import InvalidInputError

MAX_DENSE_TRIPLE_BANDS = 8


def n_coeffs(bands: int) -> int:
    """Number of coefficients of ``bands`` bands (``bands**2``)."""
    return bands * bands


def index(l: int, m: int) -> int:
    """Flat index of (l, m): ``l(l+1) + m``."""
    return l * (l + 1) + m


def lm_of(bands: int) -> tuple[np.ndarray, np.ndarray]:
    """Band l and order m of each flat index, each (bands²,) int."""
    ls = np.concatenate([np.full(2 * l + 1, l) for l in range(bands)]) if bands else np.zeros(0, int)
    ms = np.concatenate([np.arange(-l, l + 1) for l in range(bands)]) if bands else np.zeros(0, int)
    return ls.astype(int), ms.astype(int)


def _check_bands(bands: int, *, low: int = 1, high: int = 64) -> int:
    if int(bands) != bands or not (low <= bands <= high):
        raise InvalidInputError(f"sh bands={bands!r}; accepted: integers {low}..{high}")
    return int(bands)


#: Directions per block of :func:`eval_sh` (its coefficient-major scratch: 8·n²·this bytes).
_EVAL_BLOCK = 1 << 14


def eval_sh(dirs: np.ndarray, bands: int) -> np.ndarray:
    """Evaluate all real SH of ``bands`` bands at unit directions.

    Parameters
    ----------
    dirs : ndarray, shape (N, 3)
        Unit directions (normalised here in float64).
    bands : int
        Number of bands n.

    Returns
    -------
    ndarray, shape (N, n²), float64, C-contiguous
    """
    bands = _check_bands(bands)
    d = np.asarray(dirs, dtype=np.float64).reshape(-1, 3)
    out = np.empty((len(d), bands * bands))
    # Evaluated coefficient-major in blocks (bounded scratch), transposed into place.
    for start in range(0, len(d), _EVAL_BLOCK):
        block = slice(start, start + _EVAL_BLOCK)
        out[block] = eval_sh_coefficient_major(d[block], bands).T
    return out


def eval_sh_coefficient_major(dirs: np.ndarray, bands: int) -> np.ndarray:
    """:func:`eval_sh` laid out coefficient-major: row i holds Y_i at every direction.

    The recurrences run on whole rows (one band's orders m at once, N values each), so the
    work is O(n) numpy operations on contiguous memory rather than O(n²) on strided columns
    (2–3× faster at 6–16 bands); every value is computed by the same floating-point
    operations in the same order as a per-(l, m) loop, hence the same bits.

    Parameters
    ----------
    dirs : ndarray, shape (N, 3)
        Unit directions (normalised here in float64).
    bands : int

    Returns
    -------
    ndarray, shape (n², N), float64, C-contiguous
    """
    bands = _check_bands(bands)
    d = np.asarray(dirs, dtype=np.float64).reshape(-1, 3).T
    # |d| as np.linalg.norm forms it, ((x² + y²) + z²)^½, then x/|d| …: the same bits.
    length = np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    x, y, z = d[0] / length, d[1] / length, d[2] / length
    n = len(x)
    out = np.empty((bands * bands, n))
    # Row m of (re, im) is (x + iy)^m = sin^m θ · e^{imφ}: its parts carry the φ dependence.
    re, im = np.empty((bands, n)), np.empty((bands, n))
    re[0], im[0] = 1.0, 0.0
    for m in range(1, bands):
        re[m] = re[m - 1] * x - im[m - 1] * y
        im[m] = re[m - 1] * y + im[m - 1] * x
    # Normalised P_m^m without sin^m θ: a constant per m.
    qmm = [math.sqrt(1.0 / (4.0 * math.pi))]
    for m in range(1, bands):
        qmm.append(qmm[-1] * math.sqrt((2 * m + 1) / (2 * m)))
    sqrt2 = math.sqrt(2.0)
    q_prev2 = q_prev = None  # P_l^m normalised, without sin^m θ: rows m = 0 … l of l−2, l−1
    for l in range(bands):
        q = np.empty((l + 1, n))
        if l >= 2:  # m = 0 … l−2: the three-term recurrence in l
            ms = np.arange(l - 1)
            a = np.sqrt((4 * l * l - 1) / (l * l - ms * ms))[:, None]
            b = np.sqrt(((l - 1) ** 2 - ms * ms) / (4 * (l - 1) ** 2 - 1))[:, None]
            low = q[:l - 1]
            np.multiply(z, q_prev[:l - 1], out=low)
            low -= b * q_prev2[:l - 1]
            np.multiply(a, low, out=low)
        if l >= 1:  # m = l − 1
            np.multiply(math.sqrt(2 * l + 1) * z, qmm[l - 1], out=q[l - 1])
        q[l] = qmm[l]
        centre = l * l + l
        out[centre] = q[0]
        if l:
            # m = 1 … l are rows centre+1 … centre+l; −m are centre−1 down to l².
            scaled = sqrt2 * q[1:]
            np.multiply(scaled, re[1:l + 1], out=out[centre + 1:centre + l + 1])
            np.multiply(scaled, im[1:l + 1], out=out[centre - 1:l * l - 1:-1])
        q_prev2, q_prev = q_prev, q
    return out


def project(values: np.ndarray, dirs: np.ndarray, weights: np.ndarray, bands: int) -> np.ndarray:
    """SH coefficients of a sampled spherical function, ``Σ_p w_p f(ω_p) Y_i(ω_p)``.

    Parameters
    ----------
    values : ndarray, shape (N,) or (N, C)
        Function values at the sample directions.
    dirs : ndarray, shape (N, 3)
        Unit sample directions.
    weights : ndarray, shape (N,)
        Quadrature weights (solid angles; they sum to 4π for a full-sphere rule).
    bands : int

    Returns
    -------
    ndarray, shape (n²,) or (n², C), float64
    """
    values = np.asarray(values, dtype=np.float64)
    y = eval_sh(dirs, bands) * np.asarray(weights, dtype=np.float64).reshape(-1, 1)
    return y.T @ values


def _legendre_moments(s: float, bands: int) -> np.ndarray:
    """I_l(s) = ∫_0^1 μ^s P_l(μ) dμ for l < bands, exact for any real s >= 0.

    Uses I_0 = 1/(s+1), I_1 = 1/(s+2), I_l = (s − l + 2)/(s + l + 1) · I_{l−2}, which follows
    from Bonnet's recurrence and integration by parts: a product of ratios, so it neither
    overflows nor cancels, unlike expanding P_l or quadrature of a steep μ^s.
    """
    out = np.zeros(bands)
    out[0] = 1.0 / (s + 1.0)
    if bands > 1:
        out[1] = 1.0 / (s + 2.0)
    for l in range(2, bands):
        out[l] = (s - l + 2.0) / (s + l + 1.0) * out[l - 2]
    return out


def band_norms(bands: int) -> np.ndarray:
    """N_l = √((2l+1)/(4π)) for l < bands."""
    l = np.arange(bands)
    return np.sqrt((2 * l + 1) / (4 * np.pi))


def clamped_cosine_zonal(bands: int) -> np.ndarray:
    """Zonal coefficients g_l = 2π ∫ max(μ, 0) N_l P_l(μ) dμ of the clamped cosine, (bands,).

    g_0 = √π/2, g_1 = √(π/3), g_2 = √(5π)/8, odd l > 1 vanish.
    """
    bands = _check_bands(bands)
    return 2.0 * np.pi * band_norms(bands) * _legendre_moments(1.0, bands)


def phong_lobe(cos_alpha, s) -> np.ndarray:
    """The normalised Phong lobe (s+1)/(2π)·max(cos α, 0)^s whose zonal coefficients
    :func:`phong_zonal` gives, broadcast over ``cos_alpha`` and ``s``, in their float precision
    (float32 inputs stay float32: per-pixel transport evaluates it on large chunks).

    Zero where cos α <= 0 at every s, s = 0 included: the s = 0 lobe is the hemisphere about the
    mirror direction (as the reference's ``prtphong``), not the full sphere that 0^0 = 1 gives.
    """
    cos_alpha, s = np.asarray(cos_alpha), np.asarray(s)
    dtype = np.result_type(cos_alpha.dtype, s.dtype, np.float32)
    cos_alpha, s = cos_alpha.astype(dtype, copy=False), s.astype(dtype, copy=False)
    inside = cos_alpha > 0.0
    with np.errstate(divide="ignore"):
        power = np.power(np.where(inside, cos_alpha, 1.0), s)
    return np.where(inside, (s + 1.0) / (2.0 * np.pi) * power, 0.0)


def phong_zonal(s: float, bands: int) -> np.ndarray:
    """Zonal coefficients of the normalised Phong lobe (s+1)/(2π)·max(μ, 0)^s, (bands,).

    Exact for any real s in [0, 1e4] (see :func:`_legendre_moments`); g_0 = N_0 for every s.
    """
    bands = _check_bands(bands)
    s = float(s)
    if not (0.0 <= s <= 1e4) or not math.isfinite(s):
        raise InvalidInputError(f"Phong exponent s={s!r}; accepted: [0, 10000]")
    return band_norms(bands) * (s + 1.0) * _legendre_moments(s, bands)


def zonal_convolve(coeffs: np.ndarray, zonal: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Convolve SH functions with a zonal lobe and evaluate along ``axis``.

    (g ⋆ H)(a) = Σ_l √(4π/(2l+1)) g_l Σ_m H_lm Y_lm(a).

    Parameters
    ----------
    coeffs : ndarray, shape (..., n²)
        SH coefficients, coefficients on the last axis.
    zonal : ndarray, shape (n,)
        Zonal coefficients g_l of the lobe (e.g. :func:`phong_zonal`).
    axis : ndarray, shape (..., 3)
        Lobe axes (broadcast against ``coeffs[..., 0]``).

    Returns
    -------
    ndarray, shape (...)
    """
    coeffs = np.asarray(coeffs, dtype=np.float64)
    n = len(zonal)
    if coeffs.shape[-1] != n * n:
        raise InvalidInputError(
            f"zonal_convolve: {coeffs.shape[-1]} coefficients do not match {n} zonal bands")
    axis = np.asarray(axis, dtype=np.float64)
    lead = np.broadcast_shapes(coeffs.shape[:-1], axis.shape[:-1])
    y = eval_sh(np.broadcast_to(axis, lead + (3,)).reshape(-1, 3), n).reshape(lead + (n * n,))
    ls, _ = lm_of(n)
    kernel = np.sqrt(4 * np.pi / (2 * ls + 1)) * np.asarray(zonal, dtype=np.float64)[ls]
    return np.sum(np.broadcast_to(coeffs, lead + (n * n,)) * kernel * y, axis=-1)


def sphere_quadrature(degree: int) -> tuple[np.ndarray, np.ndarray]:
    """A product Gauss–Legendre × uniform-φ rule exact for polynomials of ``degree`` on S².

    Returns
    -------
    dirs : ndarray, shape (N, 3)
    weights : ndarray, shape (N,), summing to 4π
    """
    n_mu = degree // 2 + 1
    n_phi = degree + 1
    mu, w_mu = np.polynomial.legendre.leggauss(n_mu)
    phi = (np.arange(n_phi) + 0.5) * 2 * np.pi / n_phi
    mu_g, phi_g = np.meshgrid(mu, phi, indexing="ij")
    sin_t = np.sqrt(1 - mu_g**2)
    dirs = np.stack([sin_t * np.cos(phi_g), sin_t * np.sin(phi_g), mu_g], axis=-1).reshape(-1, 3)
    weights = np.repeat(w_mu * 2 * np.pi / n_phi, n_phi)
    return dirs, weights


@lru_cache(maxsize=8)
def _triple_dense(bands: int) -> np.ndarray:
    # The product of three SH of band <= n-1 is a polynomial of degree <= 3(n-1): the rule is exact.
    dirs, weights = sphere_quadrature(3 * (bands - 1))
    y = eval_sh(dirs, bands)
    gamma = np.einsum("p,pi,pj,pk->ijk", weights, y, y, y, optimize=True)
    gamma[np.abs(gamma) < 1e-13] = 0.0
    gamma.setflags(write=False)
    return gamma


def triple_product_tensor(bands: int) -> np.ndarray:
    """Exact Γ_ijk = ∫ Y_i Y_j Y_k dω, dense float64 (n², n², n²), for bands <= 8.

    Γ_0jk = δ_jk/√(4π); Γ vanishes unless l1+l2+l3 is even and the l's satisfy the triangle
    inequality.
    """
    bands = _check_bands(bands, high=MAX_DENSE_TRIPLE_BANDS)
    return _triple_dense(bands)


def triple_product_sparse(bands: int) -> tuple[np.ndarray, np.ndarray]:
    """Non-zero entries of Γ, cached on disk.

    Returns
    -------
    ijk : ndarray, shape (K, 3), int32
    values : ndarray, shape (K,), float64
    """
    bands = _check_bands(bands, high=MAX_DENSE_TRIPLE_BANDS)

    def compute() -> dict[str, np.ndarray]:
        gamma = _triple_dense(bands)
        ijk = np.argwhere(gamma != 0).astype(np.int32)
        return {"ijk": ijk, "values": gamma[tuple(ijk.T)]}

    arrays = cached_arrays("sh-triple", f"gamma-v1-b{bands}", compute)
    return arrays["ijk"], arrays["values"]


def triple_product(transfer: np.ndarray, light: np.ndarray, bands: int) -> np.ndarray:
    """H_k = Σ_ij Γ_ijk T_i L_j: the transferred incident radiance (TP).

    Parameters
    ----------
    transfer : ndarray, shape (N, n²)
    light : ndarray, shape (n²,) or (n², C)

    Returns
    -------
    ndarray, shape (N, n²) or (N, n², C)
    """
    return np.einsum("ni,ik...->nk...", np.asarray(transfer, np.float64), tpfl_matrix(light, bands))


def tpfl_matrix(light_coeffs: np.ndarray, bands: int) -> np.ndarray:
    """Fixed-light triple-product matrix M_ik = Σ_j Γ_ijk L_j.

    Parameters
    ----------
    light_coeffs : ndarray, shape (n²,) or (n², C)

    Returns
    -------
    ndarray, shape (n², n²) or (n², n², C); H_k = Σ_i T_i M_ik.
    """
    gamma = triple_product_tensor(bands)
    light = np.asarray(light_coeffs, dtype=np.float64)
    if light.shape[0] != bands * bands:
        raise InvalidInputError(
            f"tpfl_matrix: light has {light.shape[0]} coefficients, expected {bands * bands}")
    return np.einsum("ijk,j...->ik...", gamma, light)


def window(bands: int, *, kind: str = "none", width: float | None = None) -> np.ndarray:
    """Per-band de-ringing window (Sloan, "Stupid SH Tricks"), (bands,).

    ``kind`` is ``"none"`` (all ones), ``"hanning"`` ((1 + cos(πl/w))/2 for l <= w) or
    ``"lanczos"`` (sinc(l/w)); ``width`` defaults to ``bands``.
    """
    w = float(width if width is not None else bands)
    l = np.arange(bands, dtype=np.float64)
    if kind == "none":
        return np.ones(bands)
    if kind == "hanning":
        return np.where(l <= w, 0.5 * (1 + np.cos(np.pi * l / w)), 0.0)
    if kind == "lanczos":
        return np.sinc(l / w)
    raise InvalidInputError(f"unknown SH window '{kind}'; known: none, hanning, lanczos")
