"""The cheap measurements behind ``prtbench analyze`` (DESIGN.md §15).

Each function measures one thing a scene or light may or may not require, and returns plain
numbers (floats, lists, dicts) that :mod:`prtbench.tradeoff.analyze` turns into decisions.

Errors are relative L2 errors throughout: for a function f and its approximation f̃,
‖f − f̃‖ / ‖f‖. By Parseval, the error of truncating an SH expansion to n bands is
√(1 − E_n / E), with E_n the energy (sum of squared coefficients) of bands l < n and E the
total energy; lights are reduced to Rec. 709 luminance first.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from prtbench.render.reference import render_reference
from prtbench.transport import sh
from prtbench.transport.lights import LUMINANCE_WEIGHTS
from prtbench.transport.ray_pattern import RayPattern, tangent_frames
from prtbench.transport.raytrace import Tracer, offset_origins
from prtbench.transport.transfer import compute_transfer

if TYPE_CHECKING:
    from prtbench.scene.model import Scene
    from prtbench.transport.lights import EnvironmentLight

#: Bands measured for lights (the most any SH method here stores).
MAX_LIGHT_BANDS = 16

#: Bands measured for Phong lobes (lobe coefficients are exact and cheap to any band).
MAX_LOBE_BANDS = 64

#: Target errors every band count is also reported for.
REPORTED_TARGETS = (0.01, 0.05, 0.10)


def fibonacci_sphere(n: int) -> np.ndarray:
    """``n`` near-uniform unit directions (a spherical Fibonacci lattice), (n, 3) float64."""
    j = np.arange(n, dtype=np.float64) + 0.5
    z = 1.0 - 2.0 * j / n
    r = np.sqrt(np.maximum(1.0 - z * z, 0.0))
    phi = j * math.pi * (3.0 - math.sqrt(5.0))
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def bands_for(errors: list[float] | np.ndarray, target: float) -> int:
    """Fewest bands n (errors[n − 1] is the n-band error) with error <= ``target``.

    Returns ``len(errors) + 1`` when even the most bands measured miss the target (read: "more
    than the SH methods here can store").
    """
    for n, err in enumerate(errors, start=1):
        if err <= target:
            return n
    return len(errors) + 1


def bands_table(errors: list[float] | np.ndarray) -> dict[str, int]:
    """``{"1%": n, "5%": n, "10%": n}``: :func:`bands_for` at each of ``REPORTED_TARGETS``."""
    return {f"{round(t * 100)}%": bands_for(errors, t) for t in REPORTED_TARGETS}


# --- lighting frequency ------------------------------------------------------------------------

def _luminance_sh(light: "EnvironmentLight", bands: int) -> np.ndarray:
    """(bands²,) SH coefficients of the light's luminance (the light's own cached projection)."""
    return light.sh(bands) @ LUMINANCE_WEIGHTS


def _filtered_direct(light: "EnvironmentLight", axes: np.ndarray, lobe) -> np.ndarray:
    """∫ L_lum(ω) lobe(a·ω) dω at each axis a, by the map's own texel quadrature, (A,)."""
    dirs = light.texel_directions().reshape(-1, 3)
    weight = (light.luminance() * light.texel_solid_angles()).reshape(-1)
    keep = weight > 0
    dirs, weight = dirs[keep], weight[keep]
    out = np.zeros(len(axes))
    step = max(1, (1 << 22) // max(len(dirs), 1))  # bound the (A, texels) temporary to ~32 MB
    for start in range(0, len(axes), step):
        cos = axes[start:start + step] @ dirs.T
        out[start:start + step] = lobe(cos) @ weight
    return out


def _filtered_errors(light: "EnvironmentLight", zonal: np.ndarray, lobe, axes: np.ndarray,
                     ) -> np.ndarray:
    """Relative L2 error over ``axes`` of the n-band SH filtered light, n = 1..len(zonal)."""
    bands = len(zonal)
    truth = _filtered_direct(light, axes, lobe)
    coeffs = _luminance_sh(light, bands)
    y = sh.eval_sh(axes, bands)
    ls, _ = sh.lm_of(bands)
    kernel = np.sqrt(4.0 * np.pi / (2 * ls + 1)) * zonal[ls]
    terms = y * (kernel * coeffs)  # (A, n²): each coefficient's contribution at each axis
    norm = float(np.sqrt(np.mean(truth**2)))
    errors = []
    for n in range(1, bands + 1):
        approx = terms[:, : n * n].sum(axis=1)
        errors.append(float(np.sqrt(np.mean((approx - truth) ** 2))) / max(norm, 1e-300))
    return np.array(errors)


def light_frequency(light: "EnvironmentLight", *, max_bands: int = MAX_LIGHT_BANDS,
                    n_normals: int = 256) -> dict[str, Any]:
    """How many SH bands the light and the irradiance it produces need.

    Radiance: energy fraction E_n / E of bands l < n, with E = ∫ L_lum² dω measured on the
    lat-long map with the texels' solid angles (so a constant light has fraction 1 at n = 1),
    and the truncation error √(1 − E_n/E). Irradiance: E(n̂) = ∫ L_lum max(n̂·ω, 0) dω at
    ``n_normals`` Fibonacci normals by direct texel integration, against the n-band SH
    reconstruction Σ_l √(4π/(2l+1)) ĉ_l Σ_m L_lm Y_lm(n̂) (ĉ_l: clamped-cosine zonal
    coefficients, which damp high bands); relative RMS error over the normals.

    Returns
    -------
    dict with ``radiance_energy_fraction``, ``radiance_error``, ``irradiance_energy_fraction``
    (of the ``max_bands``-band irradiance, SH domain), ``irradiance_error`` (lists of
    ``max_bands`` floats, index n − 1) and ``radiance_bands``, ``irradiance_bands`` (bands for
    each of ``REPORTED_TARGETS``).
    """
    coeffs = _luminance_sh(light, max_bands)
    ls, _ = sh.lm_of(max_bands)
    per_band = np.bincount(ls, weights=coeffs**2, minlength=max_bands)
    total = float(np.sum(light.luminance() ** 2 * light.texel_solid_angles()))
    fraction = np.minimum(np.cumsum(per_band) / max(total, 1e-300), 1.0)
    radiance_error = np.sqrt(np.maximum(1.0 - fraction, 0.0))
    # Irradiance energy per band: the clamped cosine scales band l by √(4π/(2l+1)) ĉ_l.
    cosine = sh.clamped_cosine_zonal(max_bands)
    irr_band = per_band * (4.0 * np.pi / (2 * np.arange(max_bands) + 1)) * cosine**2
    irradiance_fraction = np.cumsum(irr_band) / max(float(irr_band.sum()), 1e-300)
    normals = fibonacci_sphere(n_normals)
    irradiance_error = _filtered_errors(light, sh.clamped_cosine_zonal(max_bands),
                                        lambda c: np.maximum(c, 0.0), normals)
    return {
        "radiance_energy_fraction": fraction.tolist(),
        "radiance_error": radiance_error.tolist(),
        "irradiance_energy_fraction": irradiance_fraction.tolist(),
        "irradiance_error": irradiance_error.tolist(),
        "radiance_bands": bands_table(radiance_error),
        "irradiance_bands": bands_table(irradiance_error),
        "irradiance_normals": int(n_normals),
    }


def phong_filtered_errors(light: "EnvironmentLight", shininess: float, *,
                          max_bands: int = MAX_LIGHT_BANDS, n_axes: int = 256) -> list[float]:
    """Relative error of the n-band light convolved with the Phong lobe of exponent ``shininess``.

    The glossy part of shading is the light filtered by the lobe (s+1)/(2π)·max(r·ω, 0)^s about
    the reflection vector r; this measures it at ``n_axes`` Fibonacci axes, direct integration
    against the SH convolution with :func:`prtbench.transport.sh.phong_zonal`.
    """
    s = float(shininess)
    # μ^s only where it exceeds 1e-9 of its peak: the power is the costly part, and the rest of
    # the sphere contributes nothing measurable.
    cut = 1e-9 ** (1.0 / s) if s > 0 else 0.0
    scale = (s + 1.0) / (2.0 * np.pi)

    def lobe(cos: np.ndarray) -> np.ndarray:
        out = np.zeros_like(cos)
        inside = cos > cut
        out[inside] = scale * cos[inside] ** s
        return out

    return _filtered_errors(light, sh.phong_zonal(s, max_bands), lobe,
                            fibonacci_sphere(n_axes)).tolist()


# --- glossiness --------------------------------------------------------------------------------

def _max_of(value: Any) -> float:
    """Largest value of an RGB tuple, a scalar, or a Texture's image."""
    image = getattr(value, "image", None)
    return float(np.max(image)) if image is not None else float(np.max(value))


def glossiness(scene: "Scene") -> dict[str, Any]:
    """Largest specular albedo ks and Phong exponent s among the scene's glossy materials.

    ``max_shininess`` is taken over materials with ks > 0 only (the exponent of a diffuse
    material is never used); 0 when none is glossy.
    """
    glossy = [o for o in scene.objects if o.material.is_glossy and _max_of(o.material.ks) > 0]
    return {
        "max_ks": max((_max_of(o.material.ks) for o in glossy), default=0.0),
        "max_shininess": max((_max_of(o.material.shininess) for o in glossy), default=0.0),
        "glossy_objects": [o.name for o in glossy],
    }


def lobe_errors(shininess: float, *, max_bands: int = MAX_LOBE_BANDS) -> list[float]:
    """Relative L2 error of the Phong lobe truncated to n bands, n = 1..``max_bands``.

    Energy of bands l < n is Σ g_l² with g_l from :func:`prtbench.transport.sh.phong_zonal` (the exact
    moment recurrence); the total is the lobe's exact L2 norm, ∫ ((s+1)/(2π))² max(μ,0)^{2s} dω
    = (s+1)² / (2π(2s+1)), so the error is √(1 − Σ_{l<n} g_l² / total).
    """
    s = float(shininess)
    g = sh.phong_zonal(s, max_bands)
    total = (s + 1.0) ** 2 / (2.0 * np.pi * (2.0 * s + 1.0))
    return np.sqrt(np.maximum(1.0 - np.cumsum(g**2) / total, 0.0)).tolist()


# --- surface samples ---------------------------------------------------------------------------

def surface_samples(scene: "Scene", n_points: int, *, seed: int = 0
                    ) -> dict[str, np.ndarray]:
    """Area-uniform random points on the scene's triangles.

    Returns
    -------
    dict with ``face`` (N,) int64 index into ``Scene.merged()`` faces, ``bary`` (N, 3) float64
    barycentric weights of the face's three vertices, ``points`` (N, 3), ``face_normals`` (N, 3)
    geometric unit normals, ``normals`` (N, 3) interpolated unit shading normals, and ``area``
    (float) the total surface area.
    """
    positions, normals, faces, _ = scene.merged()
    p = positions.astype(np.float64)
    a, b, c = p[faces[:, 0]], p[faces[:, 1]], p[faces[:, 2]]
    cross = np.cross(b - a, c - a)
    area = 0.5 * np.linalg.norm(cross, axis=1)
    rng = np.random.default_rng([int(seed), 0x414E4C5A])  # stream tag: "ANLZ"
    face = rng.choice(len(faces), size=int(n_points), p=area / area.sum())
    r1, r2 = rng.random(n_points), rng.random(n_points)
    s1 = np.sqrt(r1)
    bary = np.stack([1.0 - s1, s1 * (1.0 - r2), s1 * r2], axis=1)  # uniform in the triangle
    points = np.einsum("nk,nkd->nd", bary, p[faces[face]])
    fn = cross[face] / np.maximum(np.linalg.norm(cross[face], axis=1, keepdims=True), 1e-300)
    sn = np.einsum("nk,nkd->nd", bary, normals.astype(np.float64)[faces[face]])
    sn /= np.maximum(np.linalg.norm(sn, axis=1, keepdims=True), 1e-300)
    return {"face": face.astype(np.int64), "bary": bary, "points": points, "face_normals": fn,
            "normals": sn, "area": float(area.sum())}


# --- visibility --------------------------------------------------------------------------------

def occluded_fraction(tracer: Tracer, points: np.ndarray, normals: np.ndarray, *,
                      rays_per_point: int = 256, seed: int = 0) -> np.ndarray:
    """Fraction of cosine-weighted hemisphere rays about ``normals`` that hit geometry, (N,).

    Rays are stratified (a shifted Fibonacci lattice through Malley's method, spun per point,
    as in :mod:`prtbench.transport.transfer`) and leave from origins offset along the normal.
    """
    n = len(points)
    pattern = RayPattern(n, rays_per_point, seed)
    unit = normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-300)
    dirs = pattern.world_directions(tangent_frames(unit, pattern.angle_of_point), slice(0, n))
    origins = offset_origins(points, unit, diagonal=tracer.diagonal)
    hit = tracer.occluded(np.repeat(origins, rays_per_point, axis=0), dirs.reshape(-1, 3))
    return hit.reshape(n, rays_per_point).mean(axis=1)


def occlusion(scene: "Scene", *, n_points: int = 4096, rays_per_point: int = 256, seed: int = 0,
              tracer: Tracer | None = None) -> dict[str, Any]:
    """Occluded fraction of the cosine-weighted hemisphere at area-uniform surface points.

    The hemisphere is that of the geometric (face) normal, so a convex object alone measures 0
    exactly (its own faces cannot block rays leaving their plane). Rays are cosine-weighted
    (what diffuse shading weighs), stratified as in :mod:`prtbench.transport.transfer`.

    Returns
    -------
    dict with ``mean``, ``std``, ``p50``, ``p90``, ``p99``, ``max`` of the per-point fraction,
    ``shadowed_area_fraction`` (share of the surface with occlusion > 5 %), and ``per_object``
    means (by object name).
    """
    tracer = tracer or Tracer.from_scene(scene)
    samples = surface_samples(scene, n_points, seed=seed)
    frac = occluded_fraction(tracer, samples["points"], samples["face_normals"],
                             rays_per_point=rays_per_point, seed=seed)
    objects = tracer.object_of_face[samples["face"]]
    per_object = {o.name: float(frac[objects == i].mean())
                  for i, o in enumerate(scene.objects) if np.any(objects == i)}
    return {
        "mean": float(frac.mean()), "std": float(frac.std()),
        "p50": float(np.quantile(frac, 0.5)), "p90": float(np.quantile(frac, 0.9)),
        "p99": float(np.quantile(frac, 0.99)), "max": float(frac.max()),
        "shadowed_area_fraction": float(np.mean(frac > 0.05)),
        "per_object": per_object, "points": int(n_points), "rays_per_point": int(rays_per_point),
        "weighting": "cosine (geometric normal)",
    }


# --- shadow detail versus tessellation ---------------------------------------------------------

def tessellation_error(scene: "Scene", light: "EnvironmentLight", *, bands: int = 6,
                       n_points: int = 1024, rays_per_point: int = 1024, seed: int = 0,
                       tracer: Tracer | None = None, progress: bool = False) -> dict[str, Any]:
    """Error of interpolating per-vertex transfer inside triangles, against direct transfer there.

    Transfer (:func:`prtbench.transport.transfer.compute_transfer`, ``bands`` bands) is computed at the
    vertices of the triangles under ``n_points`` area-uniform points and at the points themselves
    (interpolated shading normals, as a renderer uses); the vertex transfer is interpolated with
    the points' barycentric weights. Errors are relative RMS over the points, which sampling by
    area weights by area: ``transfer_error`` on the whole transfer vector (light-independent) and
    ``shading_error`` on the irradiance Σ_i T_i L_i under ``light`` (luminance), the decision's
    number (also ``per_object_shading_error``, for objects with >= 8 points). ``noise`` is the
    Monte-Carlo part: the same relative RMS between two independently
    seeded estimates of the interior transfer, divided by √2.
    """
    tracer = tracer or Tracer.from_scene(scene)
    samples = surface_samples(scene, n_points, seed=seed)
    positions, normals, faces, _ = scene.merged()
    tri = faces[samples["face"]]                     # (N, 3) vertex ids
    verts, inverse = np.unique(tri.reshape(-1), return_inverse=True)
    inverse = inverse.reshape(tri.shape)
    common = dict(bands=bands, rays_per_point=rays_per_point, progress=progress, use_cache=False,
                  tracer=tracer)
    t_vert = compute_transfer(scene, positions[verts], normals[verts], seed=seed, **common)
    t_in = compute_transfer(scene, samples["points"], samples["normals"], seed=seed + 1, **common)
    t_in2 = compute_transfer(scene, samples["points"], samples["normals"], seed=seed + 2, **common)
    t_vert, t_in, t_in2 = (t.astype(np.float64) for t in (t_vert, t_in, t_in2))
    t_interp = np.einsum("nk,nkc->nc", samples["bary"], t_vert[inverse])
    lum = _luminance_sh(light, bands)

    def rel(a: np.ndarray, b: np.ndarray) -> float:
        return float(np.sqrt(np.mean((a - b) ** 2)) / max(np.sqrt(np.mean(b**2)), 1e-300))

    objects = scene.merged()[3][samples["face"]]
    per_object = {o.name: rel(t_interp[objects == i] @ lum, t_in[objects == i] @ lum)
                  for i, o in enumerate(scene.objects) if np.count_nonzero(objects == i) >= 8}
    return {
        "transfer_error": rel(t_interp, t_in),
        "shading_error": rel(t_interp @ lum, t_in @ lum),
        "transfer_noise": rel(t_in2, t_in) / math.sqrt(2.0),
        "shading_noise": rel(t_in2 @ lum, t_in @ lum) / math.sqrt(2.0),
        "per_object_shading_error": per_object,
        "bands": int(bands), "points": int(n_points), "vertices": int(len(verts)),
        "rays_per_point": int(rays_per_point), "scene_vertices": int(scene.n_vertices),
    }


# --- interreflection ---------------------------------------------------------------------------

def interreflection(scene: "Scene", light: "EnvironmentLight", *, width: int = 128,
                    height: int = 96, spp: int = 32, view_index: int = 0) -> dict[str, Any]:
    """Indirect share of a one-bounce path-traced render relative to direct only.

    Renders one trajectory view with :func:`prtbench.render.reference.render_reference` at bounces 0
    and 1 and compares total linear luminance. The background is 0 in both (``hide_emitters``),
    so the ratio of sums equals the ratio of means over covered pixels. A scene without views
    gives ``indirect_fraction`` None and a ``why``.
    """

    if len(scene.trajectory) == 0:
        return {"indirect_fraction": None, "why": "scene has no views"}
    view = scene.trajectory.views[view_index]
    refs = [render_reference(scene, light, view, width=width, height=height, spp=spp, bounces=b)
            for b in (0, 1)]
    lum = [np.asarray(r.image, dtype=np.float64) @ LUMINANCE_WEIGHTS for r in refs]
    covered = (lum[0] > 0) | (lum[1] > 0)
    n = max(int(covered.sum()), 1)
    direct, total = (float(image[covered].sum()) / n for image in lum)
    # Standard error of the ratio from the references' own per-pixel noise estimates.
    stderr = (math.hypot(refs[0].noise_rmse, refs[1].noise_rmse) / math.sqrt(n)
              / max(direct, 1e-300))
    return {
        "indirect_fraction": (total - direct) / max(direct, 1e-300),
        "indirect_stderr": float(stderr),
        "direct_mean": direct, "one_bounce_mean": total, "covered_pixels": int(covered.sum()),
        "width": int(width), "height": int(height), "spp": int(spp), "view": int(view_index),
    }
