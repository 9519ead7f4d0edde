"""Mesh utilities: area-uniform surface sampling, UV atlases, degenerate faces, grid planes.

Surface samples follow Turk ("Generating random points in triangles", Graphics Gems 1990):
a triangle is picked with probability proportional to its area and a point inside it with the
square-root trick, which is uniform in area. Samples are kept a small barycentric distance off
vertices and edges, where shading normals and transfer are ill-defined (shared by several
faces) and where ray origins self-intersect most.

UV atlases for transfer textures come from xatlas (run in a child process, see
:mod:`prtbench.scene.uv_pack`) and are cached on disk by mesh content, as they take seconds to minutes
on large meshes.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Union

import numpy as np

from prtbench.api.cache import cached_arrays, content_key
from prtbench.api.errors import InvalidInputError
from prtbench.scene.model import Scene, TriangleMesh
from prtbench.scene.uv_pack import pack_atlas  # xatlas loads there, in the function

#: Bump when the atlas parameters or algorithm change, to invalidate cached atlases.
ATLAS_VERSION = 1

MeshLike = Union[TriangleMesh, Scene]


# --- basic queries ----------------------------------------------------------------------------

def bounds(mesh_or_scene: MeshLike) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned bounds (lo, hi), each (3,) float64, of a mesh or all objects of a scene."""
    if isinstance(mesh_or_scene, Scene):
        return mesh_or_scene.bounds()
    p = mesh_or_scene.positions.astype(np.float64)
    return p.min(axis=0), p.max(axis=0)


def degenerate_faces(positions: np.ndarray, faces: np.ndarray, *, eps: float = 1e-12,
                     ) -> np.ndarray:
    """Mask of faces with repeated vertex indices or area ≤ ``eps`` · (bbox diagonal)².

    Parameters
    ----------
    positions : ndarray, shape (V, 3)
    faces : ndarray, shape (F, 3), int
    eps : float
        Relative area threshold (scale-free, so it works for any mesh size).

    Returns
    -------
    ndarray, shape (F,), bool
        True where the face is degenerate.
    """
    p = np.asarray(positions, dtype=np.float64)
    f = np.asarray(faces)
    if len(f) == 0:
        return np.zeros(0, dtype=bool)
    diag2 = float(np.sum((p.max(axis=0) - p.min(axis=0)) ** 2)) if len(p) else 0.0
    area = 0.5 * np.linalg.norm(np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]]), axis=1)
    repeated = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2])
    return repeated | (area <= eps * diag2)


def remove_degenerate(mesh: TriangleMesh, *, eps: float = 1e-12) -> tuple[TriangleMesh, int]:
    """``mesh`` without degenerate faces (vertices are kept); returns (mesh, faces removed)."""
    bad = degenerate_faces(mesh.positions, mesh.faces, eps=eps)
    if not bad.any():
        return mesh, 0
    return TriangleMesh(mesh.positions, mesh.faces[~bad], mesh.normals, mesh.uvs), int(bad.sum())


def remove_duplicate_faces(faces: np.ndarray) -> tuple[np.ndarray, int]:
    """Drop faces that reuse another face's three vertices.

    A set of identically wound copies keeps one; a set with both windings is a zero-volume fin
    (crude decimations make them) and is dropped entirely, since no outward side exists.

    Returns
    -------
    faces : ndarray, shape (F', 3)
    removed : int
    """
    f = np.asarray(faces, dtype=np.int64)
    if len(f) == 0:
        return f, 0
    # Rotate each face so its smallest index comes first: equal cycles then compare equal.
    first = np.argmin(f, axis=1)
    rotated = np.stack([f[np.arange(len(f)), (first + k) % 3] for k in range(3)], -1)
    winding = rotated[:, 1] < rotated[:, 2]
    _, group, counts = np.unique(np.sort(f, axis=1), axis=0, return_inverse=True,
                                 return_counts=True)
    group = group.reshape(-1)
    n_groups = len(counts)
    forward = np.bincount(group, weights=winding, minlength=n_groups)
    mixed = (forward > 0) & (forward < counts)
    _, first_of_group = np.unique(group, return_index=True)
    keep = np.zeros(len(f), dtype=bool)
    keep[first_of_group] = True
    keep &= ~mixed[group]
    return f[keep], int(len(f) - keep.sum())


def weld_vertices(positions: np.ndarray, faces: np.ndarray, *, tol: float = 1e-7,
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Merge vertices closer than ``tol`` · (bbox diagonal) (patch seams of scanned/CAD meshes).

    Returns
    -------
    positions : ndarray, shape (V', 3)
    faces : ndarray, shape (F, 3), int64
        Faces may become degenerate; drop them with :func:`degenerate_faces`.
    """
    p = np.asarray(positions, dtype=np.float64)
    diag = float(np.linalg.norm(p.max(axis=0) - p.min(axis=0))) or 1.0
    grid = np.round(p / (tol * diag)).astype(np.int64)
    _, first, inverse = np.unique(grid, axis=0, return_index=True, return_inverse=True)
    return p[first], inverse.reshape(-1)[np.asarray(faces)].astype(np.int64)


def boundary_loops(faces: np.ndarray) -> list[np.ndarray]:
    """Closed loops of boundary edges (edges used by one face), in face winding order.

    Loops through vertices where several boundary edges meet (non-manifold) are skipped.
    """
    f = np.asarray(faces)
    directed = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    _, inverse, counts = np.unique(np.sort(directed, axis=1), axis=0, return_inverse=True,
                                   return_counts=True)
    edges = directed[counts[inverse.reshape(-1)] == 1]
    starts, n_out = np.unique(edges[:, 0], return_counts=True)
    ambiguous = set(starts[n_out > 1].tolist())
    following = {int(s): int(e) for s, e in edges if s not in ambiguous}
    loops, seen = [], set()
    for start in following:
        if start in seen:
            continue
        loop, v = [start], following[start]
        seen.add(start)
        while v != start and v in following and v not in seen:
            loop.append(v)
            seen.add(v)
            v = following[v]
        if v == start and len(loop) >= 3:
            loops.append(np.array(loop, dtype=np.int64))
    return loops


def fill_holes(positions: np.ndarray, faces: np.ndarray, *, max_loop: int = 10_000,
               ) -> tuple[np.ndarray, np.ndarray, int]:
    """Close each boundary loop with a fan around its centroid.

    Surfaces are one-sided, so a hole (a scan's cut, the teapot's lid gap) would show the
    black inside of the mesh; a fan keeps the winding of the surrounding faces. Each fan gets
    its own copy of the loop's vertices (same positions, so the surface stays watertight for
    rays) so that its flat normal does not bleed into the smooth normals around the hole.

    Returns
    -------
    positions (V', 3), faces (F', 3), number of holes filled.
    """
    p = np.asarray(positions, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    new_points, new_faces = [], []
    count = len(p)
    for loop in boundary_loops(f):
        if len(loop) > max_loop:
            continue
        ring = count + np.arange(len(loop))
        centre = count + len(loop)
        new_points += [p[loop], p[loop].mean(axis=0, keepdims=True)]
        # The hole's faces run each boundary edge backwards (s→e becomes e→s).
        new_faces.append(np.stack([np.roll(ring, -1), ring, np.full(len(loop), centre)], -1))
        count = centre + 1
    if not new_faces:
        return p, f, 0
    return np.concatenate([p] + new_points), np.concatenate([f] + new_faces), len(new_faces)


def grid_plane(size: float | tuple[float, float] = 1.0, subdivisions: int = 1, *,
               center: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> TriangleMesh:
    """A horizontal square (or rectangle) facing +Y, split into ``subdivisions``² quads.

    Parameters
    ----------
    size : float or (float, float)
        Edge length along x (and z).
    subdivisions : int
        Quads per side k ≥ 1; the plane has 2·k² triangles and (k+1)² vertices.
    center : 3 floats
        Plane centre (its y is the plane height).

    Returns
    -------
    TriangleMesh
        Normals +Y, UVs in [0, 1]² with u along +x and v along −z.
    """
    k = int(subdivisions)
    if k < 1:
        raise InvalidInputError(f"grid plane subdivisions={subdivisions}; accepted: integers >= 1")
    sx, sz = (size, size) if np.isscalar(size) else size
    t = np.linspace(0.0, 1.0, k + 1)
    u, v = np.meshgrid(t, t, indexing="xy")  # row j: v = t[j]
    x = center[0] + (u - 0.5) * sx
    z = center[2] - (v - 0.5) * sz
    positions = np.stack([x, np.full_like(x, center[1]), z], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(k), np.arange(k), indexing="xy")
    a = (j * (k + 1) + i).ravel()
    b, c, d = a + 1, a + k + 2, a + k + 1
    # a→b is +x, a→d is −z: (+x) × (−z) = +y, so (a, b, c) and (a, c, d) face up.
    faces = np.stack([np.stack([a, b, c], -1), np.stack([a, c, d], -1)], 1).reshape(-1, 3)
    normals = np.broadcast_to(np.array([0.0, 1.0, 0.0], dtype=np.float32), positions.shape)
    uvs = np.stack([u, v], -1).reshape(-1, 2)
    return TriangleMesh(positions, faces, normals.copy(), uvs)


# --- surface sampling -------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class SurfaceSamples:
    """Points on a surface.

    Attributes
    ----------
    points : ndarray, shape (N, 3), float64
    normals : ndarray, shape (N, 3), float64
        Interpolated shading normals, unit length.
    face_ids : ndarray, shape (N,), int64
        Face index within the object's own mesh (``scene.objects[object_ids[i]].mesh.faces``).
    barycentrics : ndarray, shape (N, 3), float64
        Weights of the face's three vertices (sum 1, each ≥ ``min_barycentric``).
    object_ids : ndarray, shape (N,), int64
        Object index in the scene (0 for a bare mesh).
    """

    points: np.ndarray
    normals: np.ndarray
    face_ids: np.ndarray
    barycentrics: np.ndarray
    object_ids: np.ndarray

    def __len__(self) -> int:
        return len(self.points)


def _meshes(mesh_or_scene: MeshLike) -> list[TriangleMesh]:
    if isinstance(mesh_or_scene, Scene):
        return [o.mesh for o in mesh_or_scene.objects]
    if isinstance(mesh_or_scene, TriangleMesh):
        return [mesh_or_scene]
    raise InvalidInputError(f"cannot sample a {type(mesh_or_scene).__name__}; "
                            "accepted: TriangleMesh or Scene")


def sample_surface(mesh_or_scene: MeshLike, n: int, *, seed: int,
                   min_barycentric: float = 1e-3) -> SurfaceSamples:
    """Draw ``n`` area-uniform points on a mesh or on all objects of a scene.

    Parameters
    ----------
    mesh_or_scene : TriangleMesh or Scene
    n : int
        Number of samples.
    seed : int
        Seed of the NumPy generator (results are reproducible).
    min_barycentric : float
        Samples with any barycentric coordinate below this are redrawn (uniformly in the same
        triangle), keeping them off vertices and edges. Must be < 1/3.

    Returns
    -------
    SurfaceSamples
    """
    if not 0.0 <= min_barycentric < 1.0 / 3.0:
        raise InvalidInputError(f"min_barycentric={min_barycentric}; accepted: [0, 1/3)")
    if n < 0:
        raise InvalidInputError(f"n={n}; accepted: n >= 0")
    meshes = _meshes(mesh_or_scene)
    areas = [m.triangle_areas() for m in meshes]
    all_areas = np.concatenate(areas) if areas else np.zeros(0)
    total = float(all_areas.sum())
    if not total > 0:
        raise InvalidInputError("cannot sample a surface with zero total area")
    rng = np.random.default_rng(seed)
    cdf = np.cumsum(all_areas) / total
    global_face = np.minimum(np.searchsorted(cdf, rng.random(n), side="right"), len(cdf) - 1)
    face_offsets = np.cumsum([0] + [len(a) for a in areas])
    object_ids = np.searchsorted(face_offsets, global_face, side="right") - 1
    face_ids = global_face - face_offsets[object_ids]

    # Turk's square-root trick: b = (1 − √r1, √r1 (1 − r2), √r1 r2) is uniform in area.
    bary = np.empty((n, 3))
    todo = np.arange(n)
    while len(todo):
        r1, r2 = rng.random(len(todo)), rng.random(len(todo))
        s = np.sqrt(r1)
        b = np.stack([1 - s, s * (1 - r2), s * r2], -1)
        ok = b.min(axis=1) >= min_barycentric
        bary[todo[ok]] = b[ok]
        todo = todo[~ok]

    points = np.empty((n, 3))
    normals = np.empty((n, 3))
    for k, mesh in enumerate(meshes):
        sel = np.nonzero(object_ids == k)[0]
        if len(sel) == 0:
            continue
        tri = mesh.faces[face_ids[sel]]
        w = bary[sel][:, :, None]
        p = mesh.positions.astype(np.float64)[tri]
        points[sel] = (w * p).sum(axis=1)
        nrm = (w * mesh.normals.astype(np.float64)[tri]).sum(axis=1)
        # Opposite vertex normals (a crease folded back) can cancel: use the face normal there.
        face_n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
        length = np.linalg.norm(nrm, axis=1, keepdims=True)
        bad = length[:, 0] < 1e-8
        nrm[bad] = face_n[bad]
        normals[sel] = nrm / np.linalg.norm(nrm, axis=1, keepdims=True)
    return SurfaceSamples(points, normals, face_ids.astype(np.int64), bary,
                          object_ids.astype(np.int64))


# --- UV atlases -------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class Atlas:
    """A UV parameterisation of one mesh for texture-space data (e.g. transfer textures).

    The atlas splits vertices along chart seams, so it has its own vertex list.

    Attributes
    ----------
    vertex_map : ndarray, shape (V',), int64
        Source-mesh vertex of each atlas vertex (gather positions/normals with it).
    faces : ndarray, shape (F, 3), int32
        Atlas-vertex indices, in the source mesh's face order.
    uvs : ndarray, shape (V', 2), float32
        Texture coordinates in [0, 1]; texel (i, j) of a ``resolution``² texture covers
        [i, i+1]/resolution × [j, j+1]/resolution.
    resolution : int
        Texture side the charts were packed for.
    padding : int
        Texels between charts.
    utilization : float
        Fraction of the texture covered by charts.
    texture : int
        Texture index within a texture set (0 when all objects share one texture).
    """

    vertex_map: np.ndarray
    faces: np.ndarray
    uvs: np.ndarray
    resolution: int
    padding: int
    utilization: float
    texture: int = 0


def _pack(meshes: list[TriangleMesh], resolution: int, padding: int) -> list[dict[str, np.ndarray]]:
    """Run xatlas on ``meshes`` packed into one ``resolution``² texture (in a child process)."""

    return pack_atlas([(m.positions, m.faces, m.normals) for m in meshes],
                      resolution=resolution, padding=padding)


def _check_resolution(resolution: int, padding: int) -> None:
    if resolution < 16 or padding < 0 or padding * 8 > resolution:
        raise InvalidInputError(f"atlas resolution={resolution}, padding={padding}; accepted: "
                                "resolution >= 16 and 0 <= padding <= resolution/8")


def _cached_pack(meshes: list[TriangleMesh], resolution: int, padding: int,
                 ) -> list[dict[str, np.ndarray]]:
    key = content_key("atlas", ATLAS_VERSION, resolution, padding,
                      [(m.positions, m.faces) for m in meshes])

    def compute() -> dict[str, np.ndarray]:
        flat: dict[str, np.ndarray] = {}
        for k, part in enumerate(_pack(meshes, resolution, padding)):
            flat.update({f"{name}_{k}": value for name, value in part.items()})
        return flat

    flat = cached_arrays("atlas", key, compute)
    return [{name: flat[f"{name}_{k}"] for name in ("vertex_map", "faces", "uvs", "utilization")}
            for k in range(len(meshes))]


def uv_atlas(mesh: TriangleMesh, *, resolution: int = 1024, padding: int = 2) -> Atlas:
    """A non-overlapping UV atlas of ``mesh`` packed for a ``resolution``² texture (cached).

    Parameters
    ----------
    mesh : TriangleMesh
    resolution : int
        Texture side in texels.
    padding : int
        Empty texels between charts (bilinear lookups never mix two charts).

    Returns
    -------
    Atlas
    """
    _check_resolution(resolution, padding)
    part = _cached_pack([mesh], resolution, padding)[0]
    return Atlas(part["vertex_map"], part["faces"], part["uvs"], resolution, padding,
                 float(part["utilization"]))


def scene_atlas(scene: Scene, *, resolution: int = 1024, padding: int = 2,
                per_object: bool = False) -> list[Atlas]:
    """Atlases for every object of ``scene``, one per object in object order (cached).

    Parameters
    ----------
    scene : Scene
    resolution, padding : int
        As in :func:`uv_atlas`.
    per_object : bool
        False: all objects share one texture (charts packed together, ``texture`` = 0).
        True: a texture set, one ``resolution``² texture per object (``texture`` = object index).

    Returns
    -------
    list of Atlas
    """
    _check_resolution(resolution, padding)
    meshes = [o.mesh for o in scene.objects]
    if per_object:
        parts = [_cached_pack([m], resolution, padding)[0] for m in meshes]
        textures = list(range(len(meshes)))
    else:
        parts = _cached_pack(meshes, resolution, padding)
        textures = [0] * len(meshes)
    return [Atlas(p["vertex_map"], p["faces"], p["uvs"], resolution, padding,
                  float(p["utilization"]), texture=t) for p, t in zip(parts, textures)]


def uv_triangle_areas(atlas: Atlas) -> np.ndarray:
    """(F,) float64 signed areas of the atlas faces in texels² (positive = counter-clockwise)."""
    uv = atlas.uvs.astype(np.float64) * atlas.resolution
    a, b, c = uv[atlas.faces[:, 0]], uv[atlas.faces[:, 1]], uv[atlas.faces[:, 2]]
    ab, ac = b - a, c - a
    return 0.5 * (ab[:, 0] * ac[:, 1] - ab[:, 1] * ac[:, 0])


def texel_area_ratio(mesh: TriangleMesh, atlas: Atlas) -> float:
    """Texels per unit surface area (the atlas's sampling density), for reports."""
    return float(np.abs(uv_triangle_areas(atlas)).sum() / max(mesh.triangle_areas().sum(), 1e-300))


__all__ = [
    "SurfaceSamples", "Atlas", "bounds", "degenerate_faces", "remove_degenerate", "grid_plane",
    "weld_vertices", "remove_duplicate_faces", "boundary_loops", "fill_holes",
    "sample_surface", "uv_atlas", "scene_atlas", "uv_triangle_areas", "texel_area_ratio",
    "ATLAS_VERSION",
]
