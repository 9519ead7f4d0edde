"""Interreflection textures T_1 … T_k of transfer textures (PRTT §4.2), light and BRDF baked.

T_b stores, per texel p, the SH projection of the indirect radiance arriving at p from the
(b−1)-bounce field, cosine included (the same quantity H as the triple product gives for the
direct light, so the renderer adds it to H before shading)::

    T_b,i(p) = ∫ Y_i(ω) B_{b−1}(q(p, ω), −ω) max(n_p·ω, 0) dω      over rays hitting a front face

    B_0(q, ωo) = shade(TP(T_0(q), L), kd_q, ks_q, s_q, n_q, ωo)      direct light reflected at q
    B_b(q, ωo) = shade(T_b(q), kd_q, ks_q, s_q, n_q, ωo)             b ≥ 1

with shade(H, …) = kd/π·√(4π)·H_0 + ks·Σ_l √(4π/(2l+1))·g_l(s)·Σ_m H_lm Y_lm(r) (DESIGN.md §5).
A hit's texel is found by interpolating the atlas UVs of the hit face with the hit's
barycentrics and sampling the (dilated) texture like the renderer does. Rays are cosine
weighted about p's shading normal, so T_b,i ≈ π/M Σ_j Y_i(ω_j) B(q_j, −ω_j); like
:func:`prtbench.transport.transfer.compute_transfer` the sum is formed in each point's local frame and
rotated to the world frame once per point.
"""

from __future__ import annotations

import math
import sys

import numpy as np
from tqdm import tqdm

from methods.common.atlas.atlas import AtlasMesh
from methods.common.atlas.shading import ShadingInputs
from methods.common.atlas.texels import texel_lookup
from prtbench.transport.parallel import map_chunks, parallel_chunks
from prtbench.transport.ray_pattern import RayPattern, ShRotation
from prtbench.transport.raytrace import Tracer, offset_origins
from prtbench.transport.sh import eval_sh, lm_of, phong_zonal, tpfl_matrix

#: Rays traced and shaded per batch (bounds the (hits, n², 3) float64 scratch to ~40 MB).
RAYS_PER_BATCH = 1 << 16


def shade_transferred(h: np.ndarray, kd: np.ndarray, ks: np.ndarray, zonal: np.ndarray,
                      normal: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """numpy twin of ``shade_transferred_zonal`` (prt_shading.glsl).

    Parameters
    ----------
    h : ndarray, shape (N, n², 3)
        Transferred incident radiance (cosine included), RGB.
    kd, ks : ndarray, shape (N, 3)
    zonal : ndarray, shape (N, n)
        Phong zonal coefficients g_l(s) of each point's exponent.
    normal, wo : ndarray, shape (N, 3)
        Unit shading normal and unit direction towards the viewer.

    Returns
    -------
    ndarray, shape (N, 3): outgoing radiance.
    """
    out = kd / math.pi * (math.sqrt(4.0 * math.pi) * h[:, 0, :])
    glossy = np.flatnonzero(np.any(ks > 0, axis=1))
    if len(glossy):
        bands = zonal.shape[1]
        n, w = normal[glossy], wo[glossy]
        mirror = 2.0 * np.sum(n * w, axis=1, keepdims=True) * n - w
        ls, _ = lm_of(bands)
        kernel = np.sqrt(4.0 * math.pi / (2 * ls + 1)) * zonal[glossy][:, ls]  # (G, n²)
        weights = kernel * eval_sh(mirror, bands)
        out[glossy] += ks[glossy] * np.einsum("gk,gkc->gc", weights, h[glossy])
    return out


class _Materials:
    """Per-object kd, ks and Phong zonal coefficients, looked up per merged face."""

    def __init__(self, scene, bands: int):
        self.kd = np.array([o.material.kd for o in scene.objects], np.float64)
        self.ks = np.array([o.material.ks for o in scene.objects], np.float64)
        self.zonal = np.stack([phong_zonal(o.material.shininess, bands) for o in scene.objects])


def bounce_textures(scene, atlas: AtlasMesh, shading: ShadingInputs, *, points: np.ndarray,
                    normals: np.ndarray, texel_index: np.ndarray, direct: np.ndarray,
                    light_sh: np.ndarray, bounces: int, rays_per_point: int, seed: int,
                    dilate, filtering: str, progress: bool) -> list[np.ndarray]:
    """T_1 … T_bounces as dilated texture sets.

    Parameters
    ----------
    scene : Scene
    atlas : AtlasMesh
    shading : ShadingInputs
    points, normals : ndarray, shape (P, 3)
        Covered texels' surface points and unit shading normals.
    texel_index : ndarray, shape (P,), int
        Flat index ``(s·R + j)·R + i`` of each covered texel.
    direct : ndarray, shape (S, R, R, n²)
        The dilated zero-bounce transfer texture T_0.
    light_sh : ndarray, shape (n², 3)
        The light baked into the bounces.
    bounces : int
    rays_per_point, seed : int
    dilate : callable
        ``dilate(texture (S, R, R, C)) -> texture``: the artifact's dilation of covered texels.
    filtering : {"bilinear", "nearest"}
        How hits read textures (the renderer's filter).
    progress : bool

    Returns
    -------
    list of ndarray, each shape (S, R, R, 3·n²), float64
        T_b with coefficient k, channel c at index 3k + c.
    """

    bands = int(round(math.sqrt(direct.shape[-1])))
    n2 = bands * bands
    s, r = direct.shape[0], direct.shape[1]
    tracer = Tracer.from_scene(scene)
    positions, vertex_normals, faces, object_of_face = scene.merged()
    corners = positions.astype(np.float64)[faces]
    face_normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    face_set = atlas.face_texture_set
    materials = _Materials(scene, bands)
    tpfl = tpfl_matrix(light_sh, bands).reshape(n2, n2 * 3)  # H = T @ M, RGB last
    rotate = ShRotation.for_bands(bands)
    m = int(rays_per_point)
    step = max(1, RAYS_PER_BATCH // m)
    origins_all = offset_origins(points, normals, diagonal=tracer.diagonal)
    previous = direct
    out = []
    with tqdm(total=bounces * len(points), desc=f"bounces {scene.name}", unit="texel",
              file=sys.stderr, disable=not progress, dynamic_ncols=True) as bar:
        for b in range(1, bounces + 1):
            pattern = RayPattern(len(points), m, seed + b)
            local_sh = [eval_sh(d, bands) for d in pattern.local]

            def chunk(sl: slice, b=b, pattern=pattern, local_sh=local_sh,
                      previous=previous) -> np.ndarray:
                """T_b of the points in ``sl``, (n, n², 3): rays, hits, shading, SH sums."""
                frames = pattern.frames(normals[sl], sl)
                dirs = pattern.world_directions(frames, sl).reshape(-1, 3)
                hits = tracer.first_hit(np.repeat(origins_all[sl], m, axis=0), dirs)
                ray = np.flatnonzero(hits.face >= 0)
                face = hits.face[ray]
                # One-sided surfaces: only the front (counter-clockwise side) reflects light.
                front = np.einsum("hj,hj->h", dirs[ray].astype(np.float64), face_normals[face]) < 0
                ray, face = ray[front], face[front]
                u, v = hits.u[ray].astype(np.float64), hits.v[ray].astype(np.float64)
                bary = np.stack([1.0 - u - v, u, v], axis=1)
                uv = np.einsum("hk,hkj->hj", bary, atlas.uvs.astype(np.float64)[atlas.faces[face]])
                texels = texel_lookup(previous, face_set[face], uv, filtering=filtering)
                if b == 1:
                    h = (texels @ tpfl).reshape(-1, n2, 3)
                else:
                    h = texels.reshape(-1, n2, 3)
                obj = object_of_face[face]
                wo = -dirs[ray].astype(np.float64)
                radiance = shade_transferred(
                    h, materials.kd[obj], materials.ks[obj], materials.zonal[obj],
                    shading.shading_normals(vertex_normals, faces, face, bary), wo)
                dense = np.zeros(((sl.stop - sl.start) * m, 3))
                dense[ray] = radiance
                dense = dense.reshape(-1, m, 3)
                local = np.empty((len(dense), n2, 3))
                for k, rows in pattern.groups(sl):
                    # Σ_j B_jc Y_i(ω_j) for all points of this pattern as one GEMM.
                    block = dense[rows].transpose(0, 2, 1).reshape(-1, m) @ local_sh[k]
                    local[rows] = block.reshape(-1, 3, n2).transpose(0, 2, 1)
                world_from_local = frames.transpose(0, 2, 1)
                out = np.empty((len(dense), n2, 3))
                for c in range(3):
                    out[:, :, c] = rotate(local[:, :, c] * (math.pi / m), world_from_local)
                return out

            gathered = np.zeros((len(points), n2, 3))
            # Chunks on the precompute threads (prtbench.transport.parallel), reduced in chunk order;
            # their boundaries depend only on the point count, so results on every thread count.
            chunks = parallel_chunks(len(points), step)
            for values, sl in zip(map_chunks(chunk, chunks), chunks):
                gathered[sl] = values
                bar.update(sl.stop - sl.start)
            texture = np.zeros((s * r * r, n2 * 3))
            texture[texel_index] = gathered.reshape(len(points), n2 * 3)
            previous = dilate(texture.reshape(s, r, r, n2 * 3))
            out.append(previous)
    return out
