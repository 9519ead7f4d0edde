"""What a lightmap texel holds and how it is stored: the light folded into per-texel
coefficients (:func:`fold`), the H-basis (:func:`hbasis_matrix`), and the 8-bit and half-float
storage forms (:func:`encode` and its numpy twin :func:`decode`, which ``lightmap.frag``
mirrors).

Encodings (coefficients per texel, each an RGB triple):

* ``diffuse`` (1): the irradiance E(n) at the texel's normal, E = Σ_k Â_l R_k Y_k(n) over the
  bake's bands: a non-directional lightmap (normal maps cannot change it);
* ``sh-l1`` (4), ``sh-l2`` (9): the SH of the incident radiance R, shaded per pixel as
  E(n') = Σ_{l} Â_l Σ_m R_lm Y_lm(n') at the pixel's (normal-mapped) normal n'
  (Ramamoorthi and Hanrahan 2001; SH lightmaps as Halo 3 and Frostbite ship them);
* ``hbasis4`` (4), ``hbasis6`` (6): the irradiance over the hemisphere about the texel's normal
  fitted in the H-basis (Habel and Wimmer 2010), evaluated at n' in the texel's tangent frame.

The H-basis here is the orthonormal basis of the upper hemisphere that Gram–Schmidt makes of
the monomials (1, y, z, x) and, for six functions, (xy, x² − y²): the span of Habel and
Wimmer's H4 and H6 (constant and linear functions, then the two m = ±2 quadratics), so the
least-squares fit, which is all the lightmap stores, is theirs. The tangent frame is the
branchless one of Duff et al. 2017 about the unmapped normal
(:func:`prtbench.transport.ray_pattern.tangent_frames` with angle 0), rebuilt per pixel.

Storage (one RGBA texel per coefficient, so one fetch per coefficient):

* ``float16``: RGB as half floats times one power of two per lightmap, 2^-e with the brightest
  coefficient in [2^14, 2^15) (a ``half_scale`` uniform, as engines scale their HDR lightmaps):
  any light's lightmap fits the half floats' range (never Inf, ±65504 at most) and keeps their
  11-bit relative precision, a light 10⁶ times brighter included (8 bytes per coefficient);
* ``rgbm``: coefficient 0 as RGBM (RGB / (M·range), M in alpha, ``range`` the lightmap's
  brightest value) and every further coefficient as its ratio to coefficient 0, per channel,
  in 8-bit unorm over ±bound_k (the lightmap's largest ratio), as Unity's probe volumes store
  L1 and L2 (4 bytes per coefficient);
* ``scaled8``: every coefficient and channel in 8-bit unorm with a per-lightmap scale and
  bias (Unreal's LightMapScale / LightMapAdd; 4 bytes per coefficient).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from prtbench.api.errors import InvalidInputError
from prtbench.transport.ray_pattern import ShRotation, tangent_frames
from prtbench.transport.sh import (
    band_norms,
    clamped_cosine_zonal,
    eval_sh,
    lm_of,
    tpfl_matrix,
)

#: Coefficients per texel of each encoding.
ENCODINGS = {"diffuse": 1, "sh-l1": 4, "sh-l2": 9, "hbasis4": 4, "hbasis6": 6}
#: SH bands of the SH encodings.
SH_BANDS = {"sh-l1": 2, "sh-l2": 3}
#: Bytes per stored coefficient (one RGBA texel) of each storage.
STORAGE_BYTES = {"float16": 8, "rgbm": 4, "scaled8": 4}
#: float16 storage scales the lightmap's brightest coefficient into [2^HALF_PEAK_EXPONENT − 1,
#: 2^HALF_PEAK_EXPONENT): a binade below the largest half float, far above the subnormals.
HALF_PEAK_EXPONENT = 15


def half_scale(peak: float) -> float:
    """The power of two 2^e by which float16 storage divides a lightmap whose largest |value|
    is ``peak`` (1 for a black or non-finite one)."""
    if not (np.isfinite(peak) and peak > 0.0):
        return 1.0
    return float(np.exp2(np.floor(np.log2(peak)) + 1 - HALF_PEAK_EXPONENT))


def cosine_convolution(bands: int) -> np.ndarray:
    """Â_l per coefficient (n²,): √(4π/(2l+1)) g_l, the clamped cosine's convolution."""
    l, _ = lm_of(bands)
    return (clamped_cosine_zonal(bands) / band_norms(bands))[l]


def local_frames(normals: np.ndarray) -> np.ndarray:
    """(N, 3, 3) tangent frames (rows t1, t2, n) about unit ``normals``, spun by angle 0."""
    n = np.asarray(normals, np.float64)
    n = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
    return tangent_frames(n, np.zeros(len(n)))


def _monomials(local: np.ndarray, count: int) -> np.ndarray:
    """(N, count) of (1, y, z, x, xy, x² − y²) at local directions (N, 3)."""
    x, y, z = local[:, 0], local[:, 1], local[:, 2]
    return np.stack([np.ones_like(x), y, z, x, x * y, x * x - y * y], axis=1)[:, :count]


@lru_cache(maxsize=4)
def _hemisphere_quadrature() -> tuple[np.ndarray, np.ndarray]:
    """Directions (Q, 3) and weights (Q,) exact on the upper hemisphere for polynomials of
    degree ≤ 31 (Gauss–Legendre in cos θ ∈ [0, 1], 64 equal steps in φ)."""
    z, wz = np.polynomial.legendre.leggauss(32)
    z, wz = 0.5 * (z + 1.0), 0.5 * wz
    phi = (np.arange(64) + 0.5) * (2 * np.pi / 64)
    zz, pp = np.meshgrid(z, phi, indexing="ij")
    r = np.sqrt(1.0 - zz * zz)
    dirs = np.stack([r * np.cos(pp), r * np.sin(pp), zz], axis=-1).reshape(-1, 3)
    weights = np.repeat(wz, len(phi)) * (2 * np.pi / 64)
    return dirs, weights


@lru_cache(maxsize=4)
def hbasis_matrix(count: int) -> np.ndarray:
    """(count, count) C with H_k(ω) = Σ_j C_kj m_j(ω), orthonormal over the upper hemisphere.

    Gram–Schmidt (a Cholesky factor of the monomials' Gram matrix), in the monomials' order.
    """
    dirs, weights = _hemisphere_quadrature()
    m = _monomials(dirs, count)
    gram = (m * weights[:, None]).T @ m
    lower = np.linalg.cholesky(gram)
    out = np.linalg.inv(lower)
    out.flags.writeable = False
    return out


def hbasis(local: np.ndarray, count: int) -> np.ndarray:
    """H_k at local directions (N, 3): (N, count)."""
    return _monomials(np.asarray(local, np.float64), count) @ hbasis_matrix(count).T


@lru_cache(maxsize=16)
def hbasis_projection(count: int, bands: int) -> np.ndarray:
    """(count, n²) P_kj = ∫_{z>0} H_k(ω) Y_j(ω) dω: local SH coefficients → H-basis ones."""
    dirs, weights = _hemisphere_quadrature()
    out = (hbasis(dirs, count) * weights[:, None]).T @ eval_sh(dirs, bands)
    out.flags.writeable = False
    return out


def fold(visibility: np.ndarray, normals: np.ndarray, light_sh: np.ndarray, *,
         encoding: str, bake_bands: int) -> np.ndarray:
    """The lightmap coefficients of texels with visibility SH ``visibility`` under a light.

    Parameters
    ----------
    visibility : ndarray, shape (F, b²)
        Sphere visibility SH of each texel at the bake's ``b`` bands (below-horizon
        directions unoccluded, :func:`methods.common.sphere_rays.trace_sphere`).
    normals : ndarray, shape (F, 3)
        The texels' (unmapped) normals.
    light_sh : ndarray, shape (b², 3)
    encoding : str
        One of :data:`ENCODINGS`.
    bake_bands : int

    Returns
    -------
    ndarray, shape (F, K, 3), float64
        K = ``ENCODINGS[encoding]`` RGB coefficients per texel.
    """
    v = np.asarray(visibility, np.float64)
    matrix = tpfl_matrix(np.asarray(light_sh, np.float64)[: bake_bands**2], bake_bands)
    if encoding in SH_BANDS:  # R_k = Σ_ij Γ_ijk V_i L_j, truncated to the encoding's bands
        return np.einsum("fi,ikc->fkc", v, matrix[:, : SH_BANDS[encoding] ** 2])
    irradiance = np.einsum("fi,ikc->fkc", v, matrix) * cosine_convolution(bake_bands)[:, None]
    if encoding == "diffuse":  # E(n) = Σ_k Â_l R_k Y_k(n)
        y = eval_sh(np.asarray(normals, np.float64), bake_bands)
        return np.einsum("fk,fkc->fc", y, irradiance)[:, None, :]
    count = ENCODINGS[encoding]
    frames = local_frames(normals)
    rotate = ShRotation.for_bands(bake_bands)
    # g(ω_local) = E(Wω_local) with W = framesᵀ: ShRotation turns f into f(Rᵀω), so R = frames.
    local = np.stack([rotate(irradiance[..., c], frames) for c in range(3)], axis=-1)
    return np.einsum("kj,fjc->fkc", hbasis_projection(count, bake_bands), local)


@lru_cache(maxsize=8)
def ratio_limits(encoding: str) -> np.ndarray:
    """(K − 1,) largest |c_k / c_0| of a non-negative function in ``encoding``'s basis.

    |c_k| = |∫ f B_k| ≤ max|B_k| ∫ f and c_0 = B_0 ∫ f for a constant B_0, so the ratio is at
    most max|B_k| / B_0: √3 for SH l = 1 and √5 for the l = 2 zonal function. The maxima are
    taken over 40 000 directions (a Fibonacci sphere), a fraction of a percent under the true
    ones at most: such ratios are clipped to them.
    """
    count = ENCODINGS[encoding]
    j = np.arange(40000) + 0.5
    z = 1.0 - 2.0 * j / len(j)
    r, phi = np.sqrt(1.0 - z * z), np.pi * (1.0 + 5.0**0.5) * j
    dirs = np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)
    if encoding in SH_BANDS:
        values = eval_sh(dirs, SH_BANDS[encoding])
    else:
        values = hbasis(dirs[dirs[:, 2] >= 0.0], count) if count > 1 else np.ones((1, 1))
    return np.abs(values[:, 1:]).max(axis=0) / np.abs(values[0, 0])


def encode(coeffs: np.ndarray, storage: str, *, encoding: str, light: str = "",
           ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Stored texels and the uniforms that decode them.

    Parameters
    ----------
    coeffs : ndarray, shape (..., K, 3)
    storage : {"float16", "rgbm", "scaled8"}
    encoding : str
        The coefficients' basis (:data:`ENCODINGS`), which bounds RGBM's ratios.
    light : str
        The baked light's name, for the error message.

    Raises
    ------
    InvalidInputError
        For coefficients that are not finite (a light with Inf or NaN radiance).

    Returns
    -------
    texels : ndarray, shape (..., K, 4), float16 or uint8
    uniforms : dict
        ``half_scale`` (float16's power of two), ``rgbm_range`` (float), ``ratio_bound`` (K,),
        ``scale`` and ``bias`` (K, 3).
    """
    c = np.asarray(coeffs, np.float64)
    k = c.shape[-2]
    flat = c.reshape(-1, k, 3)
    if not np.all(np.isfinite(flat)):
        raise InvalidInputError(f"light '{light}' gives non-finite lightmap coefficients; "
                                "accepted: a light whose radiance is finite everywhere")
    uniforms = {"half_scale": np.float64(1.0), "rgbm_range": np.float64(1.0),
                "ratio_bound": np.ones(k), "scale": np.ones((k, 3)), "bias": np.zeros((k, 3))}
    out = np.zeros(flat.shape[:-1] + (4,), np.float64)
    if storage == "float16":
        scale = half_scale(float(np.abs(flat).max()) if flat.size else 0.0)
        out[..., :3] = flat / scale  # exact: a power of two
        uniforms["half_scale"] = np.float64(scale)
        return out.astype(np.float16).reshape(c.shape[:-1] + (4,)), uniforms
    if storage == "scaled8":
        low, high = flat.min(axis=0), flat.max(axis=0)  # (K, 3) over the lightmap's texels
        scale = np.where(high > low, high - low, 1.0)
        out[..., :3] = (flat - low) / scale
        uniforms.update(scale=scale, bias=low)
    else:  # rgbm: coefficient 0 as RGBM, the others as ratios to it
        base = np.maximum(flat[:, 0], 0.0)
        peak = float(base.max()) if base.size else 0.0
        rgbm_range = peak if peak > 0.0 else 1.0
        m = np.clip(np.ceil(base.max(axis=1) / rgbm_range * 255.0) / 255.0, 1.0 / 255.0, 1.0)
        out[:, 0, :3] = base / (m * rgbm_range)[:, None]
        out[:, 0, 3] = m
        safe = np.where(base > 1e-12 * max(rgbm_range, 1e-30), base, np.inf)
        ratio = flat[:, 1:] / safe[:, None, :]  # 0 where coefficient 0 is black
        # The lightmap's largest ratio, but never past what a non-negative function allows
        # (ratio_limits): a few near-black texels must not coarsen every other texel's steps.
        bound = np.abs(ratio).max(axis=(0, 2)) if len(ratio) else np.zeros(k - 1)
        bound = np.minimum(bound, ratio_limits(encoding))
        bound = np.where(bound > 0.0, bound, 1.0)
        out[:, 1:, :3] = 0.5 + ratio / (2.0 * bound[:, None])
        uniforms.update(rgbm_range=np.float64(rgbm_range),
                        ratio_bound=np.concatenate([[1.0], bound]))
    texels = np.rint(np.clip(out, 0.0, 1.0) * 255.0).astype(np.uint8)
    return texels.reshape(c.shape[:-1] + (4,)), uniforms


def decode(texels: np.ndarray, storage: str, uniforms: dict[str, np.ndarray]) -> np.ndarray:
    """The numpy twin of ``decode_coefficient`` in ``lightmap.frag``: (..., K, 4) → (..., K, 3)."""
    t = np.asarray(texels)
    if storage == "float16":
        return t[..., :3].astype(np.float64) * float(uniforms.get("half_scale", 1.0))
    t = t.astype(np.float64) / 255.0
    if storage == "scaled8":
        return t[..., :3] * uniforms["scale"] + uniforms["bias"]
    base = t[..., 0, :3] * t[..., 0, 3:4] * float(uniforms["rgbm_range"])
    bound = np.asarray(uniforms["ratio_bound"])[1:, None]
    rest = (t[..., 1:, :3] - 0.5) * 2.0 * bound * base[..., None, :]
    return np.concatenate([base[..., None, :], rest], axis=-2)
