"""Ray-cast G-buffer of one view: the surface seen through each pixel centre, with its material.

For per-pixel precomputes of a fixed view (``wavelet-image``). The pixel-centre rays are those
of :meth:`View.primary_rays`, the rays of the masked metrics' geometry mask
(:func:`prtbench.transport.raytrace.geometry_mask`), so the covered pixels are the measured ones; back faces
are left out (black), surfaces being one-sided (DESIGN.md §4).
"""

from __future__ import annotations

import numpy as np

from prtbench.scene.model import Texture
from prtbench.transport.raytrace import Tracer


def pixel_gbuffer(scene, view, *, width: int, height: int) -> dict[str, np.ndarray]:
    """Ray-cast G-buffer of the front-facing surface seen through each pixel centre.

    Returns
    -------
    dict
        ``pixels`` (P,) int64 flat indices (row-major, row 0 at the top) of the covered
        front-facing pixels; ``positions``, ``normals`` (shading, interpolated), ``reflect``
        (reflect(ωo, n), ωo towards the eye) (P, 3) float64/float32; ``kd``, ``ks`` (P, 3)
        float32; ``shininess`` (P,) float32; ``glossy`` (P,) float32 1 where ks > 0.
    """

    tracer = Tracer.from_scene(scene)
    origins, dirs = view.primary_rays(width, height)
    o, d = origins.reshape(-1, 3), dirs.reshape(-1, 3)
    hits = tracer.first_hit(o, d)
    positions_v, normals_v, faces, object_of_face = scene.merged()
    hit = np.flatnonzero(hits.hit)
    tri = faces[hits.face[hit]]
    p0, p1, p2 = (positions_v[tri[:, k]].astype(np.float64) for k in range(3))
    front = np.einsum("ij,ij->i", np.cross(p1 - p0, p2 - p0), d[hit]) < 0  # one-sided
    hit, tri = hit[front], tri[front]
    face = hits.face[hit]
    u, v = hits.u[hit, None].astype(np.float64), hits.v[hit, None].astype(np.float64)
    bary = np.concatenate([1.0 - u - v, u, v], axis=1)  # (P, 3)

    def interpolate(values: np.ndarray) -> np.ndarray:
        return np.einsum("pk,pkc->pc", bary, values[tri].astype(np.float64))

    points = interpolate(positions_v)
    normals = interpolate(normals_v)
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-300)
    wo = -d[hit]
    reflect = 2.0 * np.einsum("ij,ij->i", normals, wo)[:, None] * normals - wo
    uvs = np.concatenate([o_.mesh.uvs if o_.mesh.uvs is not None
                          else np.zeros((o_.mesh.n_vertices, 2), np.float32)
                          for o_ in scene.objects])
    uv = interpolate(uvs)
    kd, ks = np.zeros((len(hit), 3), np.float32), np.zeros((len(hit), 3), np.float32)
    shininess = np.zeros(len(hit), np.float32)
    owner = object_of_face[face]
    for i, obj in enumerate(scene.objects):
        mine = np.flatnonzero(owner == i)
        if len(mine) == 0:
            continue
        mat = obj.material
        kd[mine] = _sample(mat.kd, uv[mine], 3)
        ks[mine] = _sample(mat.ks, uv[mine], 3)
        shininess[mine] = _sample(mat.shininess, uv[mine], 1)[:, 0]
    return {"pixels": hit.astype(np.int64), "positions": points, "normals": normals,
            "reflect": reflect.astype(np.float32), "kd": kd, "ks": ks, "shininess": shininess,
            "glossy": (ks.max(axis=1) > 0).astype(np.float32)}


def _sample(value, uv: np.ndarray, channels: int) -> np.ndarray:
    """(P, channels) of a constant or textured material value at ``uv``."""

    if isinstance(value, Texture):
        out = value.sample(uv)
        return out[:, :channels] if out.shape[1] >= channels else np.repeat(out[:, :1], channels, 1)
    return np.broadcast_to(np.asarray(value, np.float32).reshape(-1)[:channels],
                           (len(uv), channels))
