"""Ray-traced shading with embree: direct light at points and the indirect-light bake.

The indirect bake is a small path tracer over the lightmap texels, with the radiance model of
DESIGN.md §4 restricted to diffuse surfaces (f = kd/π, one-sided by the shading normal, as
Mitsuba's ``diffuse``). For a texel x with albedo kd_x it estimates

    L_ind(x) = kd_x · E_ω[ L_o(h(x, ω)) ],   ω cosine-distributed about n_x (pdf cos/π),

where L_o(h) = kd_h/π · E_direct(h) + (further bounces) is the radiance leaving the first hit h
towards x: zero when the ray escapes (light reaching x straight from the sky is *direct*) or
hits the back of a surface. E_direct is next-event estimation with shadow rays: exact for
point, spot and directional lights (one ray each), and importance-sampled for environment maps
(:class:`EnvironmentSampler`, texels chosen by luminance × solid angle, uniform in solid angle
inside the texel, so the estimate is unbiased for Mitsuba's bilinear ``envmap``). ``bounces``
= k follows paths up to k surface interactions after x, which is Mitsuba's ``path`` integrator
with ``max_depth = k + 2`` minus its ``max_depth = 2`` image (the test checks this).

First-bounce directions are the stratified, per-texel rotated patterns of
:class:`prtbench.transport.ray_pattern.RayPattern`; later bounces use independent cosine samples.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from methods.data_driven.lights import (
    DirectionalLight,
    PointLight,
    SpotLight,
    analytic_lights,
    is_environment,
)
from prtbench.api.errors import InvalidInputError
from prtbench.transport.ray_pattern import RayPattern, cosine_hemisphere, tangent_frames
from prtbench.transport.raytrace import Tracer, offset_origins

#: Rays per embree batch in the bake (bounds temporary memory to ~100 MB).
CHUNK_RAYS = 1 << 18

LUMINANCE = np.array([0.212671, 0.715160, 0.072169])


class EnvironmentSampler:
    """Importance sampling of an environment map's lat-long cells (for next-event estimation).

    Cell (j, i) spans u ∈ [i, i+1]/W and θ over the half-rows around sample row j; it is picked
    with probability ∝ (max luminance of its 3×3 samples + floor) × Ω_cell and sampled uniformly
    in solid angle, so pdf(ω) = p_cell / Ω_cell exactly.
    """

    def __init__(self, light: Any):
        self.light = light
        h, w = light.height, light.width
        edges = np.clip((np.arange(h + 1) - 0.5) / (h - 1), 0.0, 1.0) * np.pi
        self.cos0, self.cos1 = np.cos(edges[:-1]), np.cos(edges[1:])
        cell_omega = (self.cos0 - self.cos1)[:, None] * (2.0 * np.pi / w) * np.ones((1, w))
        from scipy.ndimage import maximum_filter

        lum = np.maximum(light.image.astype(np.float64) @ LUMINANCE, 0.0)
        # The bilinear radiance inside a cell mixes the neighbouring samples: weighting cells by
        # their neighbourhood's maximum keeps L/pdf bounded next to a small bright sun (cells
        # weighted by their own sample alone gave fireflies there).
        lum = maximum_filter(lum, size=3, mode=("nearest", "wrap"))
        lum = lum + 1e-3 * max(float(lum.mean()), 1e-12)  # every cell that can shine is sampled
        weight = (lum * cell_omega).ravel()
        self.pmf = weight / weight.sum()
        self.cdf = np.cumsum(self.pmf)
        self.cell_omega = cell_omega.ravel()
        self.w = w

    def sample(self, rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
        """``n`` directions (n, 3) and their solid-angle densities (n,)."""
        cell = np.minimum(np.searchsorted(self.cdf, rng.random(n) * self.cdf[-1], side="right"),
                          len(self.cdf) - 1)
        j, i = np.divmod(cell, self.w)
        u = (i + rng.random(n)) / self.w
        cos_t = self.cos0[j] + (self.cos1[j] - self.cos0[j]) * rng.random(n)
        sin_t = np.sqrt(np.maximum(1.0 - cos_t * cos_t, 0.0))
        phi = 2.0 * np.pi * u
        dirs = np.stack([np.sin(phi) * sin_t, cos_t, -np.cos(phi) * sin_t], axis=1)
        return dirs, self.pmf[cell] / self.cell_omega[cell]


def _shading_normal(tracer: Tracer, face: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    tri = tracer.faces[face]
    n = tracer.normals.astype(np.float64)
    w0 = (1.0 - u - v)[:, None]
    out = w0 * n[tri[:, 0]] + u[:, None] * n[tri[:, 1]] + v[:, None] * n[tri[:, 2]]
    length = np.linalg.norm(out, axis=1, keepdims=True)
    return out / np.maximum(length, 1e-12)


def analytic_irradiance(tracer: Tracer, points: np.ndarray, normals: np.ndarray,
                        lights: list, *, diagonal: float) -> np.ndarray:
    """Shadowed irradiance E = Σ_l E_l V max(n·l, 0) from analytic lights, (N, 3) float64.

    Parameters
    ----------
    tracer : Tracer
    points, normals : ndarray, shape (N, 3)
        Surface points and unit shading normals.
    lights : list of PointLight, SpotLight, DirectionalLight
    diagonal : float
        Scene diagonal (shadow-ray origin offset).
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    out = np.zeros((len(p), 3))
    if len(p) == 0:
        return out
    origins = offset_origins(p, n, diagonal=diagonal)
    for light in lights:
        if isinstance(light, DirectionalLight):
            to_light = np.broadcast_to(np.asarray(light.to_light), p.shape)
            power = np.broadcast_to(np.asarray(light.irradiance), p.shape)
            tfar = np.full(len(p), np.inf)
        elif isinstance(light, (PointLight, SpotLight)):
            d = np.asarray(light.position) - p
            dist = np.linalg.norm(d, axis=1)
            to_light = d / np.maximum(dist, 1e-12)[:, None]
            power = np.asarray(light.intensity)[None, :] / np.maximum(dist * dist, 1e-12)[:, None]
            if isinstance(light, SpotLight):
                power = power * light.falloff(-to_light)[:, None]
            tfar = dist - 2e-4 * diagonal
        else:
            raise InvalidInputError(f"light of type {type(light).__name__}; accepted: point, "
                                    "spot, directional")
        cos = np.einsum("ij,ij->i", n, to_light)
        active = (cos > 0) & (power.max(axis=1) > 0)
        if not active.any():
            continue
        idx = np.flatnonzero(active)
        blocked = tracer.occluded(origins[idx], to_light[idx], tfar=tfar[idx])
        lit = idx[~blocked]
        out[lit] += power[lit] * cos[lit, None]
    return out


def environment_irradiance(tracer: Tracer, sampler: EnvironmentSampler, points: np.ndarray,
                           normals: np.ndarray, *, samples: int, rng: np.random.Generator,
                           diagonal: float) -> np.ndarray:
    """Shadowed irradiance from an environment map by next-event estimation, (N, 3)."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    out = np.zeros((len(p), 3))
    if len(p) == 0 or samples < 1:
        return out
    origins = offset_origins(p, n, diagonal=diagonal)
    for _ in range(int(samples)):
        dirs, pdf = sampler.sample(rng, len(p))
        cos = np.einsum("ij,ij->i", n, dirs)
        idx = np.flatnonzero(cos > 0)
        if len(idx) == 0:
            continue
        blocked = tracer.occluded(origins[idx], dirs[idx])
        lit = idx[~blocked]
        out[lit] += sampler.light.radiance(dirs[lit]) * (cos[lit] / pdf[lit])[:, None]
    return out / samples


class DirectLight:
    """Next-event estimation of direct irradiance for any light (used at path vertices)."""

    def __init__(self, tracer: Tracer, light: Any, *, env_samples: int):
        self.tracer = tracer
        self.diagonal = tracer.diagonal
        self.env_samples = int(env_samples)
        if is_environment(light):
            self.sampler = EnvironmentSampler(light)
            self.lights = None
        else:
            self.sampler = None
            self.lights = analytic_lights(light, env_lights=1)

    def irradiance(self, points: np.ndarray, normals: np.ndarray,
                   rng: np.random.Generator) -> np.ndarray:
        if self.sampler is not None:
            return environment_irradiance(self.tracer, self.sampler, points, normals,
                                          samples=self.env_samples, rng=rng,
                                          diagonal=self.diagonal)
        return analytic_irradiance(self.tracer, points, normals, self.lights,
                                   diagonal=self.diagonal)


def _cosine_directions(normals: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    local = cosine_hemisphere(rng.random((len(normals), 2)))
    frames = tangent_frames(normals, rng.random(len(normals)) * 2.0 * np.pi)
    return np.einsum("nk,nkj->nj", local, frames)


def object_albedo(scene: Any, tracer: Tracer) -> np.ndarray:
    """(F, 3) diffuse albedo of every merged face."""
    kd = np.array([o.material.kd for o in scene.objects], dtype=np.float64)
    return kd[tracer.object_of_face]


def bake_indirect(tracer: Tracer, face_albedo: np.ndarray, points: np.ndarray,
                  normals: np.ndarray, albedo: np.ndarray, light: Any, *, bounces: int = 1,
                  paths: int = 64, env_samples: int = 4, seed: int = 0) -> np.ndarray:
    """Indirect outgoing radiance at surface points (the lightmap texels), (T, 3) float64.

    Parameters
    ----------
    tracer : Tracer
        From :meth:`Tracer.from_scene` (needs ``normals`` and ``object_of_face``).
    face_albedo : ndarray, shape (F, 3)
        Albedo of each merged face (:func:`object_albedo`).
    points, normals, albedo : ndarray, shape (T, 3)
        Texel surface points, unit shading normals, albedo.
    light : EnvironmentLight or analytic light(s)
    bounces : int
        Surface interactions after the texel (1 = one indirect bounce).
    paths : int
        Paths per texel.
    env_samples : int
        Shadow rays per path vertex for environment maps.
    seed : int
    """

    if bounces < 1 or paths < 1:
        raise InvalidInputError(f"bake bounces={bounces}, paths={paths}; accepted: both >= 1")
    p = np.asarray(points, dtype=np.float64)
    n = np.asarray(normals, dtype=np.float64)
    kd = np.asarray(albedo, dtype=np.float64)
    out = np.zeros((len(p), 3))
    if len(p) == 0:
        return out
    rng = np.random.default_rng([int(seed), 0x42414B45])  # "BAKE"
    direct = DirectLight(tracer, light, env_samples=env_samples)
    pattern = RayPattern(len(p), int(paths), int(seed))
    step = max(1, CHUNK_RAYS // int(paths))
    diagonal = tracer.diagonal
    for start in range(0, len(p), step):
        sl = slice(start, min(start + step, len(p)))
        frames = pattern.frames(n[sl], sl)
        dirs = pattern.world_directions(frames, sl).reshape(-1, 3).astype(np.float64)
        owner = np.repeat(np.arange(sl.start, sl.stop), paths)
        origins = offset_origins(np.repeat(p[sl], paths, axis=0), np.repeat(n[sl], paths, axis=0),
                                 diagonal=diagonal)
        throughput = kd[owner].copy()
        radiance = np.zeros((len(owner), 3))
        alive = np.arange(len(owner))
        for bounce in range(int(bounces)):
            hits = tracer.first_hit(origins, dirs)
            ok = hits.hit
            face = hits.face[ok]
            hit_n = _shading_normal(tracer, face, hits.u[ok].astype(np.float64),
                                    hits.v[ok].astype(np.float64))
            facing = np.einsum("ij,ij->i", hit_n, -dirs[ok]) > 0  # one-sided surfaces
            keep = np.flatnonzero(ok)[facing]
            face, hit_n = face[facing], hit_n[facing]
            alive, throughput = alive[keep], throughput[keep]
            hit_p = origins[keep] + dirs[keep] * hits.t[keep, None].astype(np.float64)
            hit_kd = face_albedo[face]
            e = direct.irradiance(hit_p, hit_n, rng)
            radiance[alive] += throughput * hit_kd / math.pi * e
            if bounce + 1 == bounces or len(alive) == 0:
                break
            throughput = throughput * hit_kd
            dirs = _cosine_directions(hit_n, rng)
            origins = offset_origins(hit_p, hit_n, diagonal=diagonal)
        out[sl] = radiance.reshape(-1, paths, 3).mean(axis=1)
    return out
