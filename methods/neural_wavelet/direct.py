"""The real-time direct light of neural-wavelet: ray-traced, importance-sampled, denoised.

The paper computes direct light apart from its learnt indirect light, "with real-time ray
tracing in OptiX, importance sampling of the environment map and Monte Carlo denoising"
(Raghavan et al. 2023, §1 and §5). This is that term on our stack: from the G-buffer's
front-facing pixels (position, normal, kd, ks, Phong exponent), per pixel

    B(p, ωo) = ∫ L(ω) V(p, ω) max(n·ω, 0) f(ω, ωo) dω                      (DESIGN.md §4)

estimated with ``light_samples`` directions from the environment
(:class:`prtbench.transport.env_sampling.EnvironmentSampler`) and ``brdf_samples`` from the
BRDF (cosine lobe for kd, the Phong lobe about r for ks, mixed by their luminances), combined
by the balance heuristic (Veach 1997: each sample weighs f L cos / (n_l p_l + n_b p_b)), with
binary visibility V traced by Embree shadow rays (:class:`prtbench.transport.raytrace.Tracer`,
the same rays and offsets as every precompute). The estimate is unbiased; its noise is then
filtered by :func:`denoise` (edge-avoiding à-trous wavelets, Dammertz et al. 2010, with the
variance-guided luminance weight of SVGF, Schied et al. 2017): the paper's denoiser is
OptiX's; this one runs on a CPU and on any GL device.

Per light change: the sampler's tables (one pass over the map). Per frame: the samples, the
shadow rays, the shading and the filter -- all inside the frame.
"""

from __future__ import annotations

import math

import numpy as np

from prtbench.render.ops import TRANSCENDENTAL_MADDS as TRANSCENDENTAL
from prtbench.transport.env_sampling import EnvironmentSampler
from prtbench.transport.lights import LUMINANCE_WEIGHTS
from prtbench.transport.raytrace import Tracer, offset_origins

#: Embree's BVH is not visible from Python: resident bytes per triangle are estimated from its
#: BVH4 layout (about one 128-byte node per 4 triangles, Triangle4 leaves of 48 bytes per
#: triangle, plus the float32 vertex and int32 index buffers it shares).
BVH_BYTES_PER_TRIANGLE = 96
#: À-trous passes (step 1, 2, 4, ...) and edge-stopping widths.
DENOISE_PASSES = 3
SIGMA_NORMAL = 64.0      # exponent of max(n_p·n_q, 0) (SVGF's σ_n)
SIGMA_DEPTH = 1.0        # in units of the local depth change per pixel (SVGF's σ_z)
SIGMA_LUMINANCE = 4.0    # in units of the luminance's standard deviation (SVGF's σ_l)
_KERNEL = np.array([1.0, 4.0, 6.0, 4.0, 1.0]) / 16.0  # B3 spline


def direct_counts(*, samples: int, triangles: int, light_cells: int, denoised: bool
                  ) -> dict[str, float]:
    """Operations of the direct term per covered pixel (``op_counts``' model).

    Per sample (``2 · samples``: light and BRDF draws): drawing the direction (a binary search
    of the light's CDF over ``light_cells`` or the lobe's inversion, with their sin, cos, pow),
    both densities, the BRDF, the light's bilinear lookup (4 fetches) and one Embree shadow ray
    -- a BVH4 walk of about 2·log₄(triangles) + 2 nodes (4 box tests of 6 madds, a 64-byte
    node each) and 4 triangle tests (20 madds, 48 bytes). The denoiser: 3 passes of 25 taps of
    about 30 madds (weights and accumulation).
    """
    depth = 2.0 * math.log(max(triangles, 2), 4) + 2.0
    per_sample = {"madds": 60.0 + 8.0 * TRANSCENDENTAL + math.log2(max(light_cells, 2))
                  + depth * 24.0 + 4 * 20.0,
                  "fetches": 4.0 + math.log2(max(light_cells, 2)) + depth + 4.0,
                  "bytes": 64.0 * depth + 4 * 48.0}
    out = {k: v * 2 * samples for k, v in per_sample.items()}
    if denoised:
        out["madds"] += DENOISE_PASSES * 25 * 30.0
        out["fetches"] += DENOISE_PASSES * 25 * 3.0
    return out


def reflect(wo: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """r = 2 (n·ωo) n − ωo, (..., 3)."""
    return 2.0 * np.sum(normal * wo, axis=-1, keepdims=True) * normal - wo


def _frame(axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing ``axis`` (..., 3) to an orthonormal frame (Duff et al.)."""
    x, y, z = axis[..., 0], axis[..., 1], axis[..., 2]
    sign = np.where(z >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + z)
    b = x * y * a
    t = np.stack([1.0 + sign * x * x * a, sign * b, -sign * x], axis=-1)
    s = np.stack([b, sign + y * y * a, -y], axis=-1)
    return t, s


def _around(axis: np.ndarray, cos_a: np.ndarray, phi: np.ndarray) -> np.ndarray:
    t, s = _frame(axis)
    sin_a = np.sqrt(np.maximum(1.0 - cos_a * cos_a, 0.0))[..., None]
    return (t * (sin_a * np.cos(phi)[..., None]) + s * (sin_a * np.sin(phi)[..., None])
            + axis * cos_a[..., None])


class DirectLight:
    """Per-pixel direct light of the G-buffer's rows by importance-sampled shadow rays.

    Parameters
    ----------
    scene : Scene
        Its merged triangles become the Embree scene (built once, with the renderer).
    light_samples, brdf_samples : int
        Directions per pixel drawn from the light and from the BRDF.
    seed : int
        Seed of the per-frame random numbers (the same every frame: a still camera under a
        still light shows a still image).
    """

    def __init__(self, scene, *, light_samples: int, brdf_samples: int, seed: int):
        self.tracer = Tracer.from_scene(scene)
        self.diagonal = float(scene.diagonal())
        self.light_samples, self.brdf_samples = int(light_samples), int(brdf_samples)
        self.seed = int(seed)
        self.sampler: EnvironmentSampler | None = None
        self._light_key: str | None = None
        self.bvh_bytes = BVH_BYTES_PER_TRIANGLE * int(scene.n_triangles)

    def set_light(self, light, *, force: bool = False) -> EnvironmentSampler:
        """The sampler of ``light``, built when the light changes (per-light work)."""
        key = light.content_hash()
        if force or self.sampler is None or key != self._light_key:
            self.sampler, self._light_key = EnvironmentSampler(light), key
        return self.sampler

    def radiance(self, rows: dict, light) -> tuple[np.ndarray, np.ndarray]:
        """Direct radiance of the G-buffer's rows and the variance of its luminance.

        Parameters
        ----------
        rows : dict
            :func:`methods.neural_wavelet.gbuffer.pixel_rows`: ``positions``, ``normals``,
            ``wo``, ``kd``, ``ks`` (P, 3), ``shininess`` (P,).
        light : EnvironmentLight

        Returns
        -------
        radiance : ndarray, shape (P, 3), float32
        variance : ndarray, shape (P,), float32
            Variance of the estimate's luminance (the sample variance over its samples / n).
        """
        sampler = self.set_light(light)
        n = np.asarray(rows["normals"], np.float64)
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
        wo = np.asarray(rows["wo"], np.float64)
        kd, ks = np.asarray(rows["kd"], np.float64), np.asarray(rows["ks"], np.float64)
        s = np.asarray(rows["shininess"], np.float64)
        r = reflect(wo, n)
        r /= np.maximum(np.linalg.norm(r, axis=1, keepdims=True), 1e-12)
        p_count, nl, nb = len(n), self.light_samples, self.brdf_samples
        if p_count == 0:
            return np.zeros((0, 3), np.float32), np.zeros(0, np.float32)
        rng = np.random.default_rng(self.seed)
        wd, ws = kd @ LUMINANCE_WEIGHTS, ks @ LUMINANCE_WEIGHTS
        q_diffuse = np.where(wd + ws > 0, wd / np.maximum(wd + ws, 1e-30), 1.0)

        def brdf_pdf(dirs):
            cos_n = np.maximum(np.einsum("pc,psc->ps", n, dirs), 0.0)
            cos_r = np.maximum(np.einsum("pc,psc->ps", r, dirs), 0.0)
            lobe = (s[:, None] + 1.0) / (2.0 * np.pi) * cos_r ** s[:, None]
            return q_diffuse[:, None] * cos_n / np.pi + (1.0 - q_diffuse[:, None]) * lobe

        # Light samples and BRDF samples, (P, nl + nb, 3), with both densities.
        light_dirs, light_pdf = sampler.sample(rng.random((p_count, nl, 3)))
        xi = rng.random((p_count, nb, 3))
        diffuse = xi[..., 0] < q_diffuse[:, None]
        cos_d = np.sqrt(xi[..., 1])  # cosine-weighted about n
        cos_s = xi[..., 1] ** (1.0 / (s[:, None] + 1.0))  # Phong lobe about r
        axis = np.where(diffuse[..., None], n[:, None], r[:, None])
        brdf_dirs = _around(axis, np.where(diffuse, cos_d, cos_s), 2.0 * np.pi * xi[..., 2])
        dirs = np.concatenate([light_dirs, brdf_dirs], axis=1)
        p_light = np.concatenate([light_pdf, sampler.pdf(brdf_dirs)], axis=1)
        p_brdf = brdf_pdf(dirs)
        cos_n = np.einsum("pc,psc->ps", n, dirs)
        cos_r = np.maximum(np.einsum("pc,psc->ps", r, dirs), 0.0)
        f_diffuse = kd[:, None] / np.pi
        f_lobe = ks[:, None] * ((s[:, None] + 1.0) / (2.0 * np.pi) * cos_r ** s[:, None])[..., None]
        denom = nl * p_light + nb * p_brdf
        weight = np.where((cos_n > 0) & (denom > 0), cos_n / np.maximum(denom, 1e-300), 0.0)
        # Only samples that can carry light are traced.
        live = weight > 0
        radiance = np.zeros(dirs.shape, np.float64)
        if live.any():
            origins = offset_origins(np.repeat(rows["positions"], nl + nb, axis=0)
                                     .reshape(p_count, nl + nb, 3)[live],
                                     np.repeat(n, nl + nb, axis=0).reshape(p_count, nl + nb,
                                                                           3)[live],
                                     diagonal=self.diagonal)
            visible = ~self.tracer.occluded(origins, dirs[live])
            lit = light.radiance(dirs[live][visible])
            idx = np.flatnonzero(live.reshape(-1))[visible]
            flat = radiance.reshape(-1, 3)
            flat[idx] = lit
        contrib = radiance * (f_diffuse + f_lobe) * weight[..., None]  # (P, S, 3)
        total = contrib.sum(axis=1)
        # Each technique's samples are n i.i.d. draws; the variance of the sum is estimated
        # from the spread of (n_total · contribution) around the mean, divided by the count.
        lum = (contrib @ LUMINANCE_WEIGHTS) * (nl + nb)
        variance = lum.var(axis=1, ddof=1) / (nl + nb) if nl + nb > 1 else np.zeros(p_count)
        return total.astype(np.float32), variance.astype(np.float32)


def denoise(image: np.ndarray, variance: np.ndarray, *, covered: np.ndarray,
            normals: np.ndarray, depth: np.ndarray, passes: int = DENOISE_PASSES
            ) -> np.ndarray:
    """Edge-avoiding à-trous filter of a noisy image (Dammertz et al. 2010; SVGF weights).

    Parameters
    ----------
    image : ndarray, shape (H, W, 3)
        Noisy radiance; only ``covered`` pixels are read or written.
    variance : ndarray, shape (H, W)
        Variance of each pixel's luminance (filtered along, as SVGF does).
    covered : ndarray, shape (H, W), bool
    normals : ndarray, shape (H, W, 3)
        Unit normals (the edge-stopping on geometry).
    depth : ndarray, shape (H, W)
        Distance from the camera.
    passes : int
        À-trous passes with steps 1, 2, 4, ...

    Returns
    -------
    ndarray, shape (H, W, 3), float32
    """
    h, w = covered.shape
    color = np.where(covered[..., None], image, 0.0).astype(np.float64)
    var = np.where(covered, variance, 0.0).astype(np.float64)
    # Local depth change per pixel: how far neighbours on one surface may differ in depth.
    gy, gx = np.gradient(np.where(covered, depth, 0.0))
    slope = np.maximum(np.abs(gx) + np.abs(gy), 1e-6 * max(float(depth[covered].max(initial=1.0)), 1e-6))
    for level in range(passes):
        step = 1 << level
        lum = color @ LUMINANCE_WEIGHTS
        sigma_l = SIGMA_LUMINANCE * np.sqrt(np.maximum(var, 0.0)) + 1e-10
        acc = np.zeros_like(color)
        acc_var = np.zeros_like(var)
        total = np.zeros_like(var)
        for dy in range(-2, 3):
            for dx in range(-2, 3):
                oy, ox = dy * step, dx * step
                ys = slice(max(0, -oy), min(h, h - oy))
                xs = slice(max(0, -ox), min(w, w - ox))
                yq = slice(max(0, oy), min(h, h + oy))
                xq = slice(max(0, ox), min(w, w + ox))
                both = covered[ys, xs] & covered[yq, xq]
                k = _KERNEL[dy + 2] * _KERNEL[dx + 2]
                w_n = np.maximum(np.sum(normals[ys, xs] * normals[yq, xq], axis=-1), 0.0) \
                    ** SIGMA_NORMAL
                w_z = np.exp(-np.abs(depth[ys, xs] - depth[yq, xq])
                             / (SIGMA_DEPTH * slope[ys, xs] * max(abs(oy), abs(ox), 1) + 1e-12))
                # Symmetric in p and q (both variances): a one-sided weight lets dark,
                # low-variance pixels reject bright neighbours and the image loses light.
                w_l = np.exp(-np.abs(lum[ys, xs] - lum[yq, xq])
                             / np.hypot(sigma_l[ys, xs], sigma_l[yq, xq]))
                wgt = np.where(both, k * w_n * w_z * w_l, 0.0)
                acc[ys, xs] += wgt[..., None] * color[yq, xq]
                acc_var[ys, xs] += wgt * wgt * var[yq, xq]
                total[ys, xs] += wgt
        ok = covered & (total > 0)
        color = np.where(ok[..., None], acc / np.maximum(total, 1e-300)[..., None], color)
        var = np.where(ok, acc_var / np.maximum(total * total, 1e-300), var)
    return color.astype(np.float32)
