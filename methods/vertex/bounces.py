"""Interreflected glossy transfer matrices (Sloan, Kautz and Snyder 2002, §6) at vertices.

The zero-bounce matrix of ``sloan-matrix`` maps the light's SH L to the transferred incident
radiance H = M⁰·L, the SH projection of L·V·max(n·ω, 0) (cosine included). Bounce b adds the
radiance that arrives at p from the surface point q(p, ω) its ray hits, reflected there
towards p by q's own shading of its (b−1)-bounce incident radiance::

    M^b_c(p) = ∫ y(ω) [R_c(q, −ω)ᵀ M^{b−1}_c(q)] max(n_p·ω, 0) dω        over front-face hits

    R_c(q, ωo) = kd_c(q)/π·√(4π)·e_0 + ks_c(q)·[√(4π/(2l+1))·g_l(s_q)·y_lm(r)]_lm,
                 r = reflect(ωo, n_q)

R_cᵀ H is exactly ``shade_transferred`` of prt_shading.glsl (the renderer's own outgoing
radiance, diffuse and Phong lobe: glossy at the bounce, not only diffuse), M^{b−1}(q) is
interpolated from the hit triangle's vertices by barycentrics (Gouraud, like the renderer's
radiance) and n_q is the interpolated shading normal. The result is light-independent: one
n² × n² matrix per vertex and colour channel, since the albedos of the surfaces hit colour
the light, and H_c = (M⁰ + M¹ + … + M^B)_c · L_c. Rays are cosine weighted about p's normal,
so M^b_c(p) ≈ π/M Σ_j y(ω_j) ⊗ r_j with r_j = R_cᵀ M^{b−1}_c(q_j).
"""

from __future__ import annotations

import math

import numpy as np

from prtbench.api.errors import InvalidInputError
from prtbench.transport.parallel import map_chunks, parallel_chunks, single_threaded_blas
from prtbench.transport.ray_pattern import RayPattern
from prtbench.transport.raytrace import Tracer, offset_origins
from prtbench.transport.sh import eval_sh, lm_of, phong_zonal
from prtbench.transport.transfer import progress_bar

#: Rays traced per chunk of points (bounds the per-ray SH and radiance rows to ~20 MB).
_RAYS_PER_CHUNK = 1 << 14
#: Hits whose vertex matrices are gathered at once (bounds that gather to ~30 MB).
_HITS_PER_BATCH = 1 << 12


class _Reflectance:
    """Per-object kd, ks and Phong zonal kernels √(4π/(2l+1))·g_l(s), by merged face."""

    def __init__(self, scene, bands: int):
        ls, _ = lm_of(bands)
        self.kd = np.array([o.material.kd for o in scene.objects], np.float64)
        self.ks = np.array([o.material.ks for o in scene.objects], np.float64)
        zonal = np.stack([phong_zonal(o.material.shininess, bands) for o in scene.objects])
        self.kernel = np.sqrt(4.0 * math.pi / (2 * ls + 1)) * zonal[:, ls]  # (O, n²)
        self.bands = bands

    def rows(self, obj: np.ndarray, normal: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """R (H, n², 3): outgoing radiance towards ``wo`` per unit of each H coefficient.

        Parameters
        ----------
        obj : ndarray, shape (H,), int
            Object index of each hit.
        normal, wo : ndarray, shape (H, 3)
            Unit shading normal at the hit and unit direction back towards the gathering point.
        """

        n2 = self.bands * self.bands
        out = np.zeros((len(obj), n2, 3))
        out[:, 0, :] = self.kd[obj] / math.pi * math.sqrt(4.0 * math.pi)
        glossy = np.flatnonzero(np.any(self.ks[obj] > 0, axis=1))
        if len(glossy):
            n, w = normal[glossy], wo[glossy]
            mirror = 2.0 * np.sum(n * w, axis=1, keepdims=True) * n - w
            lobe = self.kernel[obj[glossy]] * eval_sh(mirror, self.bands)  # (G, n²)
            out[glossy] += lobe[:, :, None] * self.ks[obj[glossy]][:, None, :]
        return out


def bounce_matrices(scene, direct: np.ndarray, *, bounces: int, rays_per_point: int,
                    seed: int = 0, progress: bool = True) -> np.ndarray:
    """M⁰ + M¹ + … + M^bounces at every vertex of ``scene.merged()``, per RGB channel.

    Parameters
    ----------
    scene : Scene
        Geometry and constant per-object materials.
    direct : ndarray, shape (V, n², n²)
        The zero-bounce (shadowed) matrices M⁰ at all vertices, in merged order.
    bounces : int
        Interreflection bounces, ≥ 1.
    rays_per_point : int
        Gather rays per vertex and bounce (bounce b uses the ray pattern of ``seed + b``).
    seed : int
    progress : bool

    Returns
    -------
    ndarray, shape (V, n², n², 3), float32
        ``out[v, k, i, c]``: H_kc = Σ_i out[v, k, i, c]·L_ic.
    """

    positions, vertex_normals, faces, object_of_face = scene.merged()
    m0 = np.asarray(direct, dtype=np.float32)
    n2 = m0.shape[1] if m0.ndim == 3 else 0
    bands = int(round(math.sqrt(n2)))
    if m0.ndim != 3 or m0.shape != (len(positions), n2, n2) or bands * bands != n2 or n2 < 1:
        raise InvalidInputError(f"direct matrices of shape {m0.shape}; accepted: "
                                f"({len(positions)}, n², n²) for scene '{scene.name}'")
    if int(bounces) != bounces or bounces < 1:
        raise InvalidInputError(f"bounces={bounces!r}; accepted: integers >= 1")
    m = int(rays_per_point)
    if m < 1:
        raise InvalidInputError(f"rays_per_point={rays_per_point!r}; accepted: integers >= 1")
    tracer = Tracer.from_scene(scene)
    reflectance = _Reflectance(scene, bands)
    vn = vertex_normals.astype(np.float64)
    vn /= np.maximum(np.linalg.norm(vn, axis=1, keepdims=True), 1e-300)
    corners = positions.astype(np.float64)[faces]
    face_normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    origins_all = offset_origins(positions.astype(np.float64), vn,
                                 diagonal=tracer.diagonal).astype(np.float32)
    chunks = parallel_chunks(len(positions), max(1, _RAYS_PER_CHUNK // m))
    total = np.repeat(m0[..., None], 3, axis=3)
    previous = m0  # (V, n², n²) grey for b = 1, then (V, n², n², 3)

    def reflected_rows(prev: np.ndarray, rows: np.ndarray, verts: np.ndarray,
                       bary: np.ndarray) -> np.ndarray:
        """r (H, n², 3) = R_cᵀ (Σ_corners β·M^{b−1}_c(corner)), in batches of hits."""
        out = np.empty((len(rows), n2, 3))
        for start in range(0, len(rows), _HITS_PER_BATCH):
            sl = slice(start, start + _HITS_PER_BATCH)
            shape = (-1,) + (1,) * (prev.ndim - 1)
            mats = sum(bary[sl, corner].reshape(shape) * prev[verts[sl, corner]]
                       for corner in range(3))  # (h, n², n²) grey or (h, n², n², 3)
            r = rows[sl].transpose(0, 2, 1)  # (h, 3, n²)
            if prev.ndim == 3:  # grey M⁰: Σ_k R_kc M_ki
                out[sl] = np.matmul(r, mats).transpose(0, 2, 1)
            else:  # coloured M^b: Σ_k R_kc M_kic
                for c in range(3):
                    out[sl, :, c] = np.matmul(r[:, c:c + 1, :], mats[..., c])[:, 0, :]
        return out

    with progress_bar(bounces * len(positions), f"glossy bounces {scene.name}", progress) as bar:
        for b in range(1, bounces + 1):
            pattern = RayPattern(len(positions), m, seed + b)

            def chunk(sl: slice, pattern=pattern, prev=previous) -> np.ndarray:
                count = sl.stop - sl.start
                frames = pattern.frames(vn[sl], sl)
                dirs = pattern.world_directions(frames, sl).reshape(-1, 3)
                hits = tracer.first_hit(np.repeat(origins_all[sl], m, axis=0), dirs)
                ray = np.flatnonzero(hits.face >= 0)
                face = hits.face[ray]
                d = dirs[ray].astype(np.float64)
                # One-sided surfaces: only the front (counter-clockwise side) reflects light.
                front = np.einsum("hj,hj->h", d, face_normals[face]) < 0
                ray, face, d = ray[front], face[front], d[front]
                u, v = hits.u[ray].astype(np.float64), hits.v[ray].astype(np.float64)
                bary = np.stack([1.0 - u - v, u, v], axis=1)
                verts = faces[face]
                normal = np.einsum("hk,hkj->hj", bary, vn[verts])
                normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
                rows = reflectance.rows(object_of_face[face], normal, -d)
                dense = np.zeros((count * m, n2, 3))
                dense[ray] = reflected_rows(prev, rows, verts, bary)
                y = eval_sh(dirs.astype(np.float64), bands).reshape(count, m, n2)
                # π/M Σ_j y(ω_j) ⊗ r_j: one (n² × M)·(M × 3n²) product per point.
                out = np.matmul(y.transpose(0, 2, 1), dense.reshape(count, m, n2 * 3))
                return (out * (math.pi / m)).reshape(count, n2, n2, 3).astype(np.float32)

            current = np.empty((len(positions), n2, n2, 3), dtype=np.float32)
            with single_threaded_blas():
                for values, sl in zip(map_chunks(chunk, chunks), chunks):
                    current[sl] = values
                    bar.update(sl.stop - sl.start)
            total += current
            previous = current
    return total
