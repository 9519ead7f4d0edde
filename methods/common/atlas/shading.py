"""Shading frames of transfer textures: tangent frames and normal maps (PRTT §6.2).

The G-buffer pass writes the normal-mapped *shading* normal, so the transfer is computed at the
normal the renderer shades with; ``texture_normal.glsl`` applies the map in both GL passes and
:func:`apply_normal_map` is its numpy twin for ray hits (bounce textures). A scene may use one
normal-map texture (a single sampler in the shaders).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from prtbench.scene.model import Scene, Texture


def vertex_tangents(mesh) -> np.ndarray:
    """Per-vertex tangent frames from a mesh's UVs, (V, 4) float32.

    xyz is the unit direction of dP/du orthogonalised against the vertex normal; w is the
    handedness: +1 when dP/dv points along cross(n, t). Vertices without a UV gradient get an
    arbitrary tangent (they only matter under a normal map). A grid plane from
    :func:`prtbench.scene.geometry.grid_plane` gets t = +x, w = +1 (bitangent −z), as the room's floor
    normal map expects.
    """
    n = mesh.normals.astype(np.float64)
    out = np.zeros((mesh.n_vertices, 4))
    out[:, 3] = 1.0
    if mesh.uvs is None or mesh.n_triangles == 0:
        out[:, :3] = _any_perpendicular(n)
        return out.astype(np.float32)
    p = mesh.positions.astype(np.float64)[mesh.faces]
    w = mesh.uvs.astype(np.float64)[mesh.faces]
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    d1, d2 = w[:, 1] - w[:, 0], w[:, 2] - w[:, 0]
    det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    ok = np.abs(det) > 1e-20
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)[:, None]
    dpdu = (e1 * d2[:, 1:2] - e2 * d1[:, 1:2]) * inv
    dpdv = (e2 * d1[:, 0:1] - e1 * d2[:, 0:1]) * inv
    su, sv = np.zeros_like(n), np.zeros_like(n)
    for k in range(3):
        np.add.at(su, mesh.faces[:, k], dpdu)
        np.add.at(sv, mesh.faces[:, k], dpdv)
    t = su - n * np.sum(n * su, axis=1, keepdims=True)
    length = np.linalg.norm(t, axis=1, keepdims=True)
    t = np.where(length > 1e-12, t / np.maximum(length, 1e-300), _any_perpendicular(n))
    out[:, :3] = t
    out[:, 3] = np.where(np.sum(np.cross(n, t) * sv, axis=1) < 0.0, -1.0, 1.0)
    return out.astype(np.float32)


def _any_perpendicular(n: np.ndarray) -> np.ndarray:
    helper = np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t = np.cross(n, helper)
    return t / np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-300)


def apply_normal_map(normal: np.ndarray, tangent: np.ndarray, texel: np.ndarray) -> np.ndarray:
    """numpy twin of ``apply_normal_map`` in ``texture_normal.glsl``.

    Parameters
    ----------
    normal : ndarray, shape (N, 3)
        Interpolated vertex normals.
    tangent : ndarray, shape (N, 4)
        Interpolated tangents (xyz) and handedness (w).
    texel : ndarray, shape (N, 3)
        Normal-map RGB in [0, 1].

    Returns
    -------
    ndarray, shape (N, 3), float64: unit shading normals.
    """
    nn = normal / np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    t = tangent[:, :3] - nn * np.sum(nn * tangent[:, :3], axis=1, keepdims=True)
    len_t = np.linalg.norm(t, axis=1, keepdims=True)
    t = t / np.maximum(len_t, 1e-300)
    b = np.where(tangent[:, 3:4] < 0, -1.0, 1.0) * np.cross(nn, t)
    m = np.asarray(texel, np.float64) * 2.0 - 1.0
    s = m[:, :1] * t + m[:, 1:2] * b + m[:, 2:3] * nn
    len_s = np.linalg.norm(s, axis=1, keepdims=True)
    s = np.where(len_s > 1e-12, s / np.maximum(len_s, 1e-300), nn)
    return np.where(len_t > 1e-12, s, nn)


@dataclass(frozen=True, eq=False)
class ShadingInputs:
    """Per merged-scene-vertex inputs of the shading normal, and the scene's normal map.

    Attributes
    ----------
    mesh_uvs : ndarray, shape (V, 2), float32
        The objects' own UVs (zeros where an object has none).
    tangents : ndarray, shape (V, 4), float32
    normal_mapped : ndarray, shape (V,), float32
        1 on vertices of objects with the normal map.
    normal_map : Texture or None
        The scene's one normal map.
    """

    mesh_uvs: np.ndarray
    tangents: np.ndarray
    normal_mapped: np.ndarray
    normal_map: Texture | None

    @classmethod
    def from_scene(cls, scene: Scene) -> "ShadingInputs":
        maps = distinct_normal_maps(scene)
        uvs, tangents, flags = [], [], []
        for obj in scene.objects:
            mesh = obj.mesh
            has_map = obj.material.normal_map is not None
            uvs.append(mesh.uvs if mesh.uvs is not None else np.zeros((mesh.n_vertices, 2), np.float32))
            tangents.append(vertex_tangents(mesh) if has_map else
                            np.tile(np.float32([1, 0, 0, 1]), (mesh.n_vertices, 1)))
            flags.append(np.full(mesh.n_vertices, 1.0 if has_map else 0.0, np.float32))
        return cls(np.concatenate(uvs).astype(np.float32), np.concatenate(tangents),
                   np.concatenate(flags), maps[0] if maps else None)

    def shading_normals(self, vertex_normals: np.ndarray, faces: np.ndarray, face: np.ndarray,
                        bary: np.ndarray) -> np.ndarray:
        """Unit shading normals at points ``bary`` (N, 3) of merged faces ``face`` (N,)."""
        corners = faces[face]
        n = np.einsum("nk,nkj->nj", bary, vertex_normals.astype(np.float64)[corners])
        length = np.linalg.norm(n, axis=1, keepdims=True)
        n = np.where(length > 1e-8, n / np.maximum(length, 1e-300), [[0.0, 1.0, 0.0]])
        if self.normal_map is None:
            return n
        mapped = self.normal_mapped[corners[:, 0]] > 0.5
        if mapped.any():
            c, w = corners[mapped], bary[mapped]
            uv = np.einsum("nk,nkj->nj", w, self.mesh_uvs.astype(np.float64)[c])
            tangent = np.einsum("nk,nkj->nj", w, self.tangents.astype(np.float64)[c])
            n[mapped] = apply_normal_map(n[mapped], tangent, self.normal_map.sample(uv)[:, :3])
        return n


def distinct_normal_maps(scene: Scene) -> list[Texture]:
    """The different normal-map textures of ``scene`` (by identity), in object order."""
    maps: list[Texture] = []
    for obj in scene.objects:
        nm = obj.material.normal_map
        if nm is not None and all(nm is not m for m in maps):
            maps.append(nm)
    return maps


def normal_map_texture(ctx, texture: Texture | None):
    """A GL RGB32F texture of the normal map (bilinear, repeat, row 0 = v 0), or a 1×1 dummy."""
    image = (np.asarray(texture.image[..., :3], np.float32) if texture is not None
             else np.float32([[[0.5, 0.5, 1.0]]]))
    if image.shape[2] < 3:
        image = np.repeat(image[..., :1], 3, axis=2)
    tex = ctx.texture((image.shape[1], image.shape[0]), 3, np.ascontiguousarray(image).tobytes(),
                      dtype="f4")
    tex.filter = (ctx.LINEAR, ctx.LINEAR)
    tex.repeat_x = tex.repeat_y = True
    return tex
