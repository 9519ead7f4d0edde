"""Lightmaps on the scene's UV atlas: which texels are on the surface, and where.

Indirect light is baked in texture space (paper §4.1: "each row of I is a lightmap"). The atlas
comes from :func:`prtbench.scene.geometry.scene_atlas` (all objects packed in one texture). A texel
is *covered* when its centre lies inside an atlas triangle; its surface point, interpolated
shading normal and albedo are what the bake shades. Texels around charts are then filled by
:func:`dilate` so that bilinear lookups near chart borders never read empty texels.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from prtbench.api.errors import InvalidInputError
from prtbench.scene.geometry import scene_atlas
from prtbench.scene.model import Scene


@dataclass(frozen=True, eq=False)
class Lightmap:
    """Covered texels of a ``resolution``² lightmap and the render mesh that samples it.

    Attributes
    ----------
    resolution : int
    texel : ndarray, shape (T,), int64
        Flat index ``row · resolution + column`` of each covered texel (row = v, column = u).
    points, normals : ndarray, shape (T, 3), float64
        Surface point at the texel centre and its unit shading normal.
    albedo : ndarray, shape (T, 3), float64
    face : ndarray, shape (T,), int64
        Face in ``scene.merged()`` order.
    mesh_positions, mesh_normals, mesh_albedo : ndarray, shape (V', 3), float32
        The atlas render mesh (vertices split at chart seams).
    mesh_uvs : ndarray, shape (V', 2), float32
    mesh_faces : ndarray, shape (F, 3), int32
        Same face order as ``scene.merged()``.
    """

    resolution: int
    texel: np.ndarray
    points: np.ndarray
    normals: np.ndarray
    albedo: np.ndarray
    face: np.ndarray
    mesh_positions: np.ndarray
    mesh_normals: np.ndarray
    mesh_albedo: np.ndarray
    mesh_uvs: np.ndarray
    mesh_faces: np.ndarray

    def __len__(self) -> int:
        return len(self.texel)

    def covered_mask(self) -> np.ndarray:
        """(R, R) bool, row 0 = v ≈ 0."""
        mask = np.zeros(self.resolution * self.resolution, dtype=bool)
        mask[self.texel] = True
        return mask.reshape(self.resolution, self.resolution)

    def image(self, values: np.ndarray, *, dilation: int = 2) -> np.ndarray:
        """Scatter per-texel ``values`` (T, C) into a dilated (R, R, C) float32 image."""
        values = np.asarray(values)
        flat = values.reshape(len(self.texel), -1)
        out = np.zeros((self.resolution * self.resolution, flat.shape[1]), dtype=np.float64)
        out[self.texel] = flat
        out = out.reshape(self.resolution, self.resolution, -1)
        return dilate(out, self.covered_mask(), iterations=dilation).astype(np.float32)

    def lookup(self, image: np.ndarray, uv: np.ndarray) -> np.ndarray:
        """Bilinear lookup of an (R, R, C) image at ``uv`` (N, 2), GL conventions (clamp)."""
        r = self.resolution
        x = np.clip(uv[:, 0] * r - 0.5, 0, r - 1)
        y = np.clip(uv[:, 1] * r - 0.5, 0, r - 1)
        x0 = np.minimum(np.floor(x).astype(int), r - 2)
        y0 = np.minimum(np.floor(y).astype(int), r - 2)
        fx, fy = (x - x0)[:, None], (y - y0)[:, None]
        return ((1 - fx) * (1 - fy) * image[y0, x0] + fx * (1 - fy) * image[y0, x0 + 1]
                + (1 - fx) * fy * image[y0 + 1, x0] + fx * fy * image[y0 + 1, x0 + 1])


def dilate(image: np.ndarray, covered: np.ndarray, *, iterations: int = 2) -> np.ndarray:
    """Fill uncovered texels next to covered ones with the mean of their covered 8-neighbours.

    Parameters
    ----------
    image : ndarray, shape (R, R, C)
    covered : ndarray, shape (R, R), bool
    iterations : int
        Rings of texels filled around each chart.
    """
    img = np.array(image, dtype=np.float64)
    filled = covered.copy()
    r0, r1 = img.shape[:2]
    for _ in range(int(iterations)):
        total = np.zeros_like(img)
        count = np.zeros((r0, r1))
        padded = np.pad(img * filled[..., None], ((1, 1), (1, 1), (0, 0)))
        padded_mask = np.pad(filled.astype(float), 1)
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                if dx == 0 and dy == 0:
                    continue
                total += padded[1 + dy:1 + dy + r0, 1 + dx:1 + dx + r1]
                count += padded_mask[1 + dy:1 + dy + r0, 1 + dx:1 + dx + r1]
        grow = (~filled) & (count > 0)
        if not grow.any():
            break
        img[grow] = total[grow] / count[grow][:, None]
        filled = filled | grow
    return img


def build_lightmap(scene: Scene, *, resolution: int, padding: int = 2) -> Lightmap:
    """Rasterise the scene's atlas at texel centres (cached atlas, see ``scene_atlas``).

    Raises
    ------
    InvalidInputError
        If a material is textured (albedo per object only) or the atlas does not pack.
    """

    try:
        atlases = scene_atlas(scene, resolution=resolution, padding=padding)
    except InvalidInputError as exc:
        raise InvalidInputError(
            f"lightmap_resolution={resolution}: {exc}; scene '{scene.name}' needs a larger "
            "lightmap (e.g. 256)") from None
    r = int(resolution)
    pos, nrm, alb, uvs, faces = [], [], [], [], []
    texel, points, normals, albedo, face_ids = [], [], [], [], []
    vert_offset, face_offset = 0, 0
    for obj, atlas in zip(scene.objects, atlases):
        kd = np.asarray(obj.material.kd, dtype=np.float64)
        p = obj.mesh.positions.astype(np.float64)[atlas.vertex_map]
        n = obj.mesh.normals.astype(np.float64)[atlas.vertex_map]
        uv = atlas.uvs.astype(np.float64)
        f = atlas.faces.astype(np.int64)
        pos.append(p)
        nrm.append(n)
        alb.append(np.broadcast_to(kd, p.shape))
        uvs.append(uv)
        faces.append(f + vert_offset)
        t, b, tri = _covered_texels(uv * r, f, r)
        w = b[:, :, None]
        q = (w * p[f[tri]]).sum(axis=1)
        nn = (w * n[f[tri]]).sum(axis=1)
        length = np.linalg.norm(nn, axis=1, keepdims=True)
        fn = np.cross(p[f[tri, 1]] - p[f[tri, 0]], p[f[tri, 2]] - p[f[tri, 0]])
        nn = np.where(length > 1e-8, nn, fn)
        texel.append(t)
        points.append(q)
        normals.append(nn / np.linalg.norm(nn, axis=1, keepdims=True))
        albedo.append(np.broadcast_to(kd, q.shape))
        face_ids.append(tri + face_offset)
        vert_offset += len(p)
        face_offset += len(f)
    texel = np.concatenate(texel)
    # A texel centre on a chart edge can fall in two triangles (or two objects' charts touch):
    # keep its first owner.
    _, first = np.unique(texel, return_index=True)
    first = np.sort(first)

    def pick(parts: list) -> np.ndarray:
        return np.concatenate(parts)[first]

    return Lightmap(r, texel[first], pick(points), pick(normals), pick(albedo), pick(face_ids),
                    np.concatenate(pos).astype(np.float32), np.concatenate(nrm).astype(np.float32),
                    np.concatenate(alb).astype(np.float32), np.concatenate(uvs).astype(np.float32),
                    np.concatenate(faces).astype(np.int32))


def _covered_texels(uv: np.ndarray, faces: np.ndarray, r: int,
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Texel centres inside atlas triangles: (flat texel, barycentrics (K, 3), triangle)."""
    a, b, c = uv[faces[:, 0]], uv[faces[:, 1]], uv[faces[:, 2]]
    area = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    lo = np.floor(np.minimum(np.minimum(a, b), c) - 0.5).astype(np.int64) + 1
    hi = np.floor(np.maximum(np.maximum(a, b), c) - 0.5).astype(np.int64)
    lo, hi = np.clip(lo, 0, r - 1), np.clip(hi, 0, r - 1)
    nx, ny = hi[:, 0] - lo[:, 0] + 1, hi[:, 1] - lo[:, 1] + 1
    ok = (np.abs(area) > 1e-12) & (nx > 0) & (ny > 0)
    tri_ids = np.flatnonzero(ok)
    counts = (nx * ny)[tri_ids]
    if counts.sum() == 0:
        return np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(0, np.int64)
    tri = np.repeat(tri_ids, counts)
    local = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    ix = lo[tri, 0] + local % nx[tri]
    iy = lo[tri, 1] + local // nx[tri]
    px, py = ix + 0.5, iy + 0.5
    ax, ay = a[tri, 0], a[tri, 1]
    e1x, e1y = b[tri, 0] - ax, b[tri, 1] - ay
    e2x, e2y = c[tri, 0] - ax, c[tri, 1] - ay
    dx, dy = px - ax, py - ay
    det = area[tri]
    w1 = (dx * e2y - dy * e2x) / det
    w2 = (e1x * dy - e1y * dx) / det
    w0 = 1.0 - w1 - w2
    inside = (w0 >= -1e-9) & (w1 >= -1e-9) & (w2 >= -1e-9)
    bary = np.clip(np.stack([w0, w1, w2], axis=1)[inside], 0.0, 1.0)
    bary /= bary.sum(axis=1, keepdims=True)
    return (iy * r + ix)[inside], bary, tri[inside]
