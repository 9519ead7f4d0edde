"""Interreflected transfer (Sloan, Kautz and Snyder 2002, §5): the light that bounces off other
surfaces before it reaches a point, as RGB transfer (hit surfaces colour it), from the direct
transfer of :mod:`prtbench.transport.transfer` and the same seeded ray pattern.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import TYPE_CHECKING

import numpy as np

from prtbench.api.cache import cached_arrays, content_key
from prtbench.api.errors import InvalidInputError
from prtbench.scene.model import Texture
from prtbench.transport.parallel import map_chunks
from prtbench.transport.ray_pattern import RayPattern
from prtbench.transport.raytrace import Tracer, offset_origins
from prtbench.transport.transfer import (
    TRANSFER_VERSION,
    check_inputs,
    compute_transfer,
    point_chunks,
    progress_bar,
)

if TYPE_CHECKING:
    from prtbench.scene.model import Scene


#: Keep the per-chunk gather matrices between bounces when they fit in this many bytes;
#: otherwise the same (seeded) rays are traced again for every bounce.
_GATHER_CACHE_BYTES = 256 << 20


class _Albedo:
    """Diffuse albedo kd (RGB) at ray hits: per-object constants or textures sampled at UVs."""

    def __init__(self, scene: "Scene", faces: np.ndarray, object_of_face: np.ndarray):
        self.faces = faces
        self.object_of_face = object_of_face
        self.constant = np.zeros((len(scene.objects), 3))
        self.textures: dict[int, Texture] = {}
        uvs = []
        for i, obj in enumerate(scene.objects):
            kd, mesh = obj.material.kd, obj.mesh
            if isinstance(kd, Texture):
                if mesh.uvs is None:
                    raise InvalidInputError(
                        f"object '{obj.name}' has a textured kd but no uvs; accepted: a mesh "
                        "with uvs, or a constant kd")
                self.textures[i] = kd
            else:
                self.constant[i] = kd
            uvs.append(mesh.uvs if mesh.uvs is not None else np.zeros((mesh.n_vertices, 2)))
        self.uvs = np.concatenate(uvs).astype(np.float64) if uvs else np.zeros((0, 2))

    def __call__(self, face: np.ndarray, bary: np.ndarray) -> np.ndarray:
        """kd (H, 3) at hits on ``face`` (H,) with barycentrics ``bary`` (H, 3)."""
        obj = self.object_of_face[face]
        kd = self.constant[obj]
        for i, tex in self.textures.items():
            sel = np.flatnonzero(obj == i)
            if len(sel):
                uv = np.einsum("hk,hkj->hj", bary[sel], self.uvs[self.faces[face[sel]]])
                texel = tex.sample(uv)
                kd[sel] = texel[:, :3] if texel.shape[1] >= 3 else np.repeat(texel[:, :1], 3, axis=1)
        return kd


def _gather_matrices(tracer: Tracer, albedo: _Albedo, points: np.ndarray, normals: np.ndarray,
                     *, rays_per_point: int, seed: int,
                     chunks: list[slice]) -> Iterator[tuple[slice, list]]:
    """Per chunk, the RGB matrices W_c (n_chunk, V) with T^{b+1}_c = W_c · T^b_c.

    W_c[p, v] = 1/M Σ_j [ray j of p hits the front of a triangle at q_j] kd_c(q_j) β_v(q_j),
    i.e. π/M Σ_j (kd/π) T^b(q_j) with T^b interpolated by the barycentrics β of the hit.
    """
    from scipy.sparse import csr_matrix

    m = rays_per_point
    pattern = RayPattern(len(points), m, seed)
    origins_all = offset_origins(points, normals, diagonal=tracer.diagonal).astype(np.float32)
    n_vertices = len(tracer.positions)
    corners = tracer.positions.astype(np.float64)[tracer.faces]
    face_normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])

    def chunk(sl: slice) -> list:
        frames = pattern.frames(normals[sl], sl)
        dirs = pattern.world_directions(frames, sl).reshape(-1, 3)
        hits = tracer.first_hit(np.repeat(origins_all[sl], m, axis=0), dirs)
        ray = np.flatnonzero(hits.face >= 0)
        face = hits.face[ray]
        u, v = hits.u[ray].astype(np.float64), hits.v[ray].astype(np.float64)
        bary = np.stack([1.0 - u - v, u, v], axis=1)
        verts = tracer.faces[face]
        # One-sided surfaces: only a hit on the front (counter-clockwise side) reflects. The
        # triangle's own normal decides, not the interpolated shading normal: near a ray's
        # origin vertex that one is ~ the origin's normal and would call grazing hits on the
        # neighbouring faces of a concave surface back-facing.
        front = np.einsum("hj,hj->h", dirs[ray].astype(np.float64), face_normals[face]) < 0
        ray, face, bary, verts = ray[front], face[front], bary[front], verts[front]
        weight = bary[:, :, None] * albedo(face, bary)[:, None, :] / m  # (H, 3 verts, 3 rgb)
        # Hits come sorted by ray, hence by row: build CSR directly (duplicates are fine for
        # products), the three channels sharing one index structure.
        n_rows = sl.stop - sl.start
        per_row = np.bincount(ray // m, minlength=n_rows) * 3
        indptr = np.concatenate([[0], np.cumsum(per_row)]).astype(np.int64)
        indices = verts.reshape(-1).astype(np.int32)
        return [csr_matrix((np.ascontiguousarray(weight[:, :, c]).reshape(-1), indices, indptr),
                           shape=(n_rows, n_vertices)) for c in range(3)]

    # Chunks are built on the precompute threads and come back in chunk order.
    for mats, sl in zip(map_chunks(chunk, chunks), chunks):  # the pool first: it ends first
        yield sl, mats


class _Gather:
    """Applies W (all chunks) to vertex transfer, keeping the matrices if they fit in memory."""

    def __init__(self, make, n_rows: int, bar):
        self.make, self.n_rows, self.bar = make, n_rows, bar
        self.kept: list | None = None

    def __call__(self, vertex_transfer: np.ndarray) -> np.ndarray:
        """W · T for vertex transfer (V, n², 1 or 3); returns (n_rows, n², 3) float64."""
        out = np.zeros((self.n_rows, vertex_transfer.shape[1], 3))
        record = self.kept is None
        source = self.make() if record else self.kept
        kept, size = [], 0
        for sl, mats in source:
            for c, mat in enumerate(mats):
                out[sl, :, c] = mat @ vertex_transfer[:, :, min(c, vertex_transfer.shape[2] - 1)]
            if record:
                size += sum(m.data.nbytes for m in mats) + mats[0].indices.nbytes
                record = size <= _GATHER_CACHE_BYTES
                kept.append((sl, mats))
            self.bar.update(sl.stop - sl.start)
        if record:
            self.kept = kept
        return out


def compute_bounce_transfer(scene: "Scene", points: np.ndarray, normals: np.ndarray, *,
                            vertex_transfer: np.ndarray, bounces: int, rays_per_point: int,
                            seed: int = 0, progress: bool = True, use_cache: bool = True,
                            tracer: Tracer | None = None) -> np.ndarray:
    """Interreflected diffuse transfer (Sloan et al. 2002): shadowed transfer plus ``bounces``.

    T^{b+1}(p) = π/M Σ_j [ray j hits the front of a surface at q] (kd(q)/π) · T^b(q), with
    T^b(q) interpolated from the hit triangle's vertices by barycentrics; hits on the back of a
    triangle add nothing (surfaces are one-sided; the front is the counter-clockwise side, the
    side its vertex normals face).
    T^b for b >= 1 is iterated on all scene vertices, then gathered at ``points`` (when the
    points are the vertices this is exactly Sloan's per-vertex iteration). Only the diffuse part
    (kd) of the surfaces hit is propagated; their specular lobe (ks) is ignored. Each iteration
    re-uses the same rays. Radiance with an SH light L (n², 3): B = kd(p)/π · Σ_i T_i L_i.

    Parameters
    ----------
    scene : Scene
        Geometry and materials (textured kd is sampled at the hit UVs; it needs mesh uvs).
    points, normals : ndarray, shape (N, 3)
    vertex_transfer : ndarray, shape (V, n²)
        Shadowed (zero-bounce) transfer at all vertices of ``scene.merged()``, in that order.
    bounces : int
        Interreflection bounces (0 returns the shadowed transfer).
    rays_per_point : int
        Gather rays per point and per vertex.
    seed : int
    progress, use_cache : bool
    tracer : Tracer, optional
        Built for ``scene`` with :meth:`Tracer.from_scene`.

    Returns
    -------
    ndarray, shape (N, n², 3), float32
        T^0 + T^1 + … + T^bounces per RGB channel.
    """
    p, n = check_inputs(points, normals, 1, rays_per_point)
    positions, vertex_normals, faces, object_of_face = scene.merged()
    vt = np.asarray(vertex_transfer, dtype=np.float64)
    bands = int(round(math.sqrt(vt.shape[1]))) if vt.ndim == 2 else 0
    if vt.ndim != 2 or len(vt) != len(positions) or bands * bands != vt.shape[1] or bands < 1:
        raise InvalidInputError(
            f"vertex_transfer shape {vt.shape}; accepted: ({len(positions)}, n²), one row per "
            f"vertex of scene '{scene.name}'")
    if not np.all(np.isfinite(vt)):
        raise InvalidInputError("vertex_transfer contains NaN/Inf; accepted: finite values")
    if int(bounces) != bounces or bounces < 0:
        raise InvalidInputError(f"bounces={bounces!r}; accepted: integers >= 0")
    bounces = int(bounces)
    albedo = _Albedo(scene, faces, object_of_face)  # fails early on textures without uvs
    at_vertices = (p.shape == positions.shape and np.array_equal(p, positions)
                   and np.array_equal(np.asarray(normals, np.float64).reshape(-1, 3), vertex_normals))

    def compute() -> dict[str, np.ndarray]:
        tr = tracer if tracer is not None else Tracer.from_scene(scene)
        if at_vertices:
            total = np.repeat(vt[:, :, None], 3, axis=2)
        else:
            total = np.repeat(compute_transfer(
                scene, p, n, bands=bands, rays_per_point=rays_per_point, seed=seed,
                progress=progress, use_cache=use_cache, tracer=tr)[:, :, None], 3, axis=2)
        if bounces == 0:
            return {"transfer": total.astype(np.float32)}
        vn = vertex_normals.astype(np.float64)
        length = np.linalg.norm(vn, axis=1, keepdims=True)
        vn_unit = np.where(length > 0, vn / np.maximum(length, 1e-300), [0.0, 1.0, 0.0])
        vertex_passes = bounces if at_vertices else bounces - 1
        n_rows = vertex_passes * len(positions) + (0 if at_vertices else bounces * len(p))
        with progress_bar(n_rows, f"bounces {scene.name}", progress) as bar:
            def gather(pts, nrm):
                return _Gather(lambda: _gather_matrices(
                    tr, albedo, pts, nrm, rays_per_point=rays_per_point, seed=seed,
                    chunks=point_chunks(len(pts), rays_per_point, None)), len(pts), bar)

            at_vertex = gather(positions.astype(np.float64), vn_unit)
            at_point = at_vertex if at_vertices else gather(p, n)
            previous = vt[:, :, None]  # T^0 is grey: the same for every channel
            for b in range(1, bounces + 1):
                if at_vertices:
                    previous = at_vertex(previous)  # T^b at the vertices, which are the points
                    total += previous
                else:
                    total += at_point(previous)  # T^b at the points from T^(b-1) at vertices
                    if b < bounces:
                        previous = at_vertex(previous)
        return {"transfer": total.astype(np.float32)}

    key = content_key("transfer-bounce", TRANSFER_VERSION, scene.content_hash(), p, n, vt,
                      bounces, int(rays_per_point), int(seed))
    return cached_arrays("transfer-bounce", key, compute, use_cache=use_cache)["transfer"]
