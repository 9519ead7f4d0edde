"""Mesh primitives shared by the scene builders.

Every primitive returns a :class:`~prtbench.scene.model.TriangleMesh` with outward, unit shading
normals and counter-clockwise faces seen from outside, because surfaces are one-sided
(DESIGN.md §3): a thin thing (leaf, rug, cup wall) must be a closed solid, never a single sheet.
Builders place primitives with 4×4 ``world_from_object`` matrices (:func:`translate`,
:func:`rotate_y`, :func:`scale`, composed with ``@``) and :func:`transformed`, then
:func:`merge` the parts of one object.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from prtbench.scene.geometry import degenerate_faces, grid_plane
from prtbench.scene.model import TriangleMesh, vertex_normals

__all__ = [
    "box", "uv_sphere", "lathe", "cylinder", "tube", "torus", "leaf", "outward", "grid_plane",
    "merge",
    "transformed", "translate", "scale", "rotate_x", "rotate_y", "rotate_z",
]


# --- transforms -------------------------------------------------------------------------------

def translate(x: float, y: float, z: float) -> np.ndarray:
    """(4, 4) translation."""
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def scale(x: float, y: float | None = None, z: float | None = None) -> np.ndarray:
    """(4, 4) axis scale (uniform when only ``x`` is given)."""
    y = x if y is None else y
    z = x if z is None else z
    return np.diag([x, y, z, 1.0])


def _rotation(axis: int, degrees: float) -> np.ndarray:
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    m = np.eye(4)
    m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
    return m


def rotate_x(degrees: float) -> np.ndarray:
    """(4, 4) right-handed rotation about +X."""
    return _rotation(0, degrees)


def rotate_y(degrees: float) -> np.ndarray:
    """(4, 4) right-handed rotation about +Y."""
    return _rotation(1, degrees)


def rotate_z(degrees: float) -> np.ndarray:
    """(4, 4) right-handed rotation about +Z."""
    return _rotation(2, degrees)


def transformed(mesh: TriangleMesh, world_from_object: np.ndarray) -> TriangleMesh:
    """``mesh`` moved by ``world_from_object`` (4, 4); normals by the inverse transpose.

    A mirroring transform (negative determinant) also flips the winding so faces stay
    counter-clockwise seen from the side the normals point to.
    """
    m = np.asarray(world_from_object, dtype=np.float64)
    p = mesh.positions.astype(np.float64) @ m[:3, :3].T + m[:3, 3]
    normal_matrix = np.linalg.inv(m[:3, :3]).T
    n = mesh.normals.astype(np.float64) @ normal_matrix.T
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    faces = mesh.faces if np.linalg.det(m[:3, :3]) > 0 else mesh.faces[:, ::-1]
    return TriangleMesh(p, faces.copy(), n, None if mesh.uvs is None else mesh.uvs.copy())


def merge(meshes: Sequence[TriangleMesh]) -> TriangleMesh:
    """One mesh holding all ``meshes`` (UVs kept only if every part has them)."""
    offsets = np.cumsum([0] + [m.n_vertices for m in meshes[:-1]])
    uvs = None
    if all(m.uvs is not None for m in meshes):
        uvs = np.concatenate([m.uvs for m in meshes])
    return TriangleMesh(np.concatenate([m.positions for m in meshes]),
                        np.concatenate([m.faces + o for m, o in zip(meshes, offsets)]),
                        np.concatenate([m.normals for m in meshes]), uvs)


# --- solids -----------------------------------------------------------------------------------

def box(size: Sequence[float] = (1.0, 1.0, 1.0), *, center: Sequence[float] = (0.0, 0.0, 0.0),
        ) -> TriangleMesh:
    """An axis-aligned box with flat faces: 24 vertices, 12 triangles.

    Parameters
    ----------
    size : 3 floats
        Edge lengths along x, y, z.
    center : 3 floats
        Box centre.
    """
    half = np.asarray(size, dtype=np.float64) / 2
    c = np.asarray(center, dtype=np.float64)
    positions, normals, faces = [], [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            n = np.zeros(3)
            n[axis] = sign
            # (u, v, n) right-handed so that u × v = n: the quad is CCW seen from outside.
            u = np.zeros(3)
            u[(axis + 1) % 3] = 1.0
            v = np.cross(n, u)
            base = len(positions)
            for du, dv in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                positions.append(c + half * (n + du * u + dv * v))
                normals.append(n)
            faces += [(base, base + 1, base + 2), (base, base + 2, base + 3)]
    return TriangleMesh(np.array(positions), np.array(faces), np.array(normals))


def uv_sphere(*, radius: float = 1.0, segments: int = 32, rings: int | None = None,
              center: Sequence[float] = (0.0, 0.0, 0.0), match_area: bool = False,
              ) -> TriangleMesh:
    """A latitude-longitude sphere with its poles on ±Y and smooth normals.

    Parameters
    ----------
    radius : float
        Sphere radius.
    segments : int
        Vertices per latitude ring (≥ 3).
    rings : int, optional
        Latitude bands (default ``segments // 2``, ≥ 2).
    center : 3 floats
        Sphere centre.
    match_area : bool
        Scale the inscribed polyhedron radially so its surface area equals 4πr². By Cauchy's
        formula the mean projected (silhouette) area of a convex body is a quarter of its
        surface area, so the polyhedron then casts the sphere's shadow in the mean instead of
        the systematically smaller shadow of an inscribed polyhedron.

    Returns
    -------
    TriangleMesh
        ``2 * segments * (rings - 1)`` triangles.
    """
    rings = max(2, segments // 2 if rings is None else rings)
    theta = np.linspace(0.0, math.pi, rings + 1)[1:-1]  # polar angle from +Y, poles excluded
    phi = np.linspace(0.0, 2 * math.pi, segments, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    ring_dirs = np.stack([np.sin(t) * np.sin(p), np.cos(t), np.sin(t) * np.cos(p)], -1)
    dirs = np.concatenate([[[0.0, 1.0, 0.0]], ring_dirs.reshape(-1, 3), [[0.0, -1.0, 0.0]]])
    top, bottom = 0, len(dirs) - 1

    def vid(ring: np.ndarray, seg: np.ndarray) -> np.ndarray:
        return 1 + ring * segments + seg % segments

    s = np.arange(segments)
    faces = [np.stack([np.full(segments, top), vid(0, s), vid(0, s + 1)], -1)]
    for r in range(rings - 2):
        a, b, c, d = vid(r, s), vid(r + 1, s), vid(r + 1, s + 1), vid(r, s + 1)
        faces += [np.stack([a, b, c], -1), np.stack([a, c, d], -1)]
    last = rings - 2
    faces.append(np.stack([vid(last, s), np.full(segments, bottom), vid(last, s + 1)], -1))
    faces = np.concatenate(faces)
    positions = dirs * radius
    if match_area:
        tri = positions[faces]
        area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
        positions = positions * math.sqrt(4 * math.pi * radius**2 / area.sum())
    return TriangleMesh(positions + np.asarray(center, dtype=np.float64), faces, dirs)


def lathe(profile: Sequence[Sequence[float]], *, segments: int = 48) -> TriangleMesh:
    """Revolve a profile curve (r, y) about the +Y axis.

    Walk the profile with the solid on the left of the direction of travel (for a solid of
    revolution: from the bottom centre outward, up the outside, back in over the top), so the
    normal (dy, -dr) of each segment points out of the solid. A point listed twice in a row is a
    crease: each copy takes the normal of its own segment. Points with r = 0 close the surface
    at the axis (one vertex per segment keeps the pole normal well defined).

    Parameters
    ----------
    profile : (K, 2) floats
        Profile points (radius ≥ 0, height).
    segments : int
        Divisions around the axis.

    Returns
    -------
    TriangleMesh
        ``2 * segments * (K' - 1)`` triangles minus degenerate pole triangles, where K' counts
        crease points once.
    """
    pts = np.asarray(profile, dtype=np.float64)
    # Split at creases into smooth runs; each run gets its own ring of vertices.
    runs, start = [], 0
    for i in range(1, len(pts)):
        if np.allclose(pts[i], pts[i - 1]):
            runs.append(pts[start:i])
            start = i
    runs.append(pts[start:])
    phi = np.linspace(0.0, 2 * math.pi, segments, endpoint=False)
    cos_p, sin_p = np.cos(phi), np.sin(phi)
    positions, normals, faces = [], [], []
    base = 0
    for run in runs:
        if len(run) < 2:
            continue
        seg = np.diff(run, axis=0)
        seg_n = np.stack([seg[:, 1], -seg[:, 0]], -1)
        seg_n /= np.maximum(np.linalg.norm(seg_n, axis=1, keepdims=True), 1e-300)
        pn = np.zeros_like(run)
        pn[:-1] += seg_n
        pn[1:] += seg_n
        pn /= np.maximum(np.linalg.norm(pn, axis=1, keepdims=True), 1e-300)
        r, y = run[:, 0:1], run[:, 1:2]
        ring_pos = np.stack([r * sin_p, np.broadcast_to(y, (len(run), segments)), r * cos_p], -1)
        ring_nrm = np.stack([pn[:, 0:1] * sin_p, np.broadcast_to(pn[:, 1:2], (len(run), segments)),
                             pn[:, 0:1] * cos_p], -1)
        positions.append(ring_pos.reshape(-1, 3))
        normals.append(ring_nrm.reshape(-1, 3))
        k = np.arange(len(run) - 1)[:, None]
        s = np.arange(segments)[None, :]
        a = base + k * segments + s
        b = base + k * segments + (s + 1) % segments
        c, d = a + segments, b + segments
        # With the solid on the left of travel, (a, b, d) runs counter-clockwise seen from out.
        quads = np.stack([np.stack([a, b, d], -1), np.stack([a, d, c], -1)], 2).reshape(-1, 3)
        keep = np.ones(len(quads), dtype=bool)
        on_axis = np.repeat(r[:, 0] < 1e-12, segments)
        tri_axis = on_axis[quads - base]
        # A triangle with two vertices on the axis has zero area.
        keep &= tri_axis.sum(axis=1) < 2
        faces.append(quads[keep])
        base += len(run) * segments
    return TriangleMesh(np.concatenate(positions), np.concatenate(faces), np.concatenate(normals))


def cylinder(*, radius: float = 0.5, height: float = 1.0, segments: int = 32,
             center: Sequence[float] = (0.0, 0.0, 0.0)) -> TriangleMesh:
    """A closed cylinder along +Y with flat caps, base centred at ``center``."""
    profile = [(0, 0), (radius, 0), (radius, 0), (radius, height), (radius, height), (0, height)]
    return transformed(lathe(profile, segments=segments), translate(*center))


def tube(start: Sequence[float], end: Sequence[float], *, radius: float, segments: int = 6,
         end_radius: float | None = None) -> TriangleMesh:
    """A closed (optionally tapered) cylinder from ``start`` to ``end`` (stems, legs, handles).

    Parameters
    ----------
    start, end : 3 floats
        Centres of the two caps.
    radius : float
        Radius at ``start``.
    segments : int
        Divisions around the axis; ``4 * segments`` triangles.
    end_radius : float, optional
        Radius at ``end`` (default ``radius``).
    """
    r1 = radius if end_radius is None else end_radius
    profile = [(0, 0), (radius, 0), (radius, 0), (r1, 1), (r1, 1), (0, 1)]
    unit = lathe(profile, segments=segments)
    a, b = np.asarray(start, dtype=np.float64), np.asarray(end, dtype=np.float64)
    axis = b - a
    length = float(np.linalg.norm(axis))
    if length <= 0:
        raise ValueError("tube with zero length")
    y = axis / length
    helper = np.array([1.0, 0.0, 0.0]) if abs(y[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    x = np.cross(y, helper)
    x /= np.linalg.norm(x)
    z = np.cross(x, y)  # (x, y, z) right-handed, so the winding is kept
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = x, y * length, z, a
    return transformed(unit, m)


def torus(*, major: float, minor: float, arc_degrees: float = 360.0, segments: int = 32,
          sides: int = 12) -> TriangleMesh:
    """A torus (or a capped arc of one) around +Z, its ring in the xy-plane starting at +x.

    Parameters
    ----------
    major, minor : float
        Ring radius and tube radius.
    arc_degrees : float
        Swept angle; below 360 the two ends get flat caps so the solid stays closed (handles).
    segments, sides : int
        Divisions along the ring and around the tube.
    """
    closed = arc_degrees >= 360.0
    n_u = segments if closed else segments + 1
    u = np.radians(arc_degrees) * np.arange(n_u) / segments
    v = 2 * math.pi * np.arange(sides) / sides
    uu, vv = np.meshgrid(u, v, indexing="ij")
    radial = np.stack([np.cos(uu), np.sin(uu), np.zeros_like(uu)], -1)
    normal = np.cos(vv)[..., None] * radial + np.sin(vv)[..., None] * np.array([0.0, 0.0, 1.0])
    positions = (major * radial + minor * normal).reshape(-1, 3)
    normals = normal.reshape(-1, 3)
    i = np.arange(segments)[:, None]
    j = np.arange(sides)[None, :]
    a = i * sides + j
    b = ((i + 1) % n_u) * sides + j
    c = ((i + 1) % n_u) * sides + (j + 1) % sides
    d = i * sides + (j + 1) % sides
    faces = np.stack([np.stack([a, b, c], -1), np.stack([a, c, d], -1)], 2).reshape(-1, 3)
    mesh = TriangleMesh(positions, outward(positions, faces), normals)
    if closed:
        return mesh
    caps = []
    for k, sign in ((0, -1.0), (n_u - 1, 1.0)):
        ring = positions[k * sides:(k + 1) * sides]
        tangent = sign * np.array([-math.sin(u[k]), math.cos(u[k]), 0.0])
        pos = np.concatenate([ring, ring.mean(axis=0, keepdims=True)])
        ring_ids = np.arange(sides)
        fan = np.stack([np.full(sides, sides), ring_ids, (ring_ids + 1) % sides], -1)
        if np.dot(np.cross(pos[fan[0, 1]] - pos[sides], pos[fan[0, 2]] - pos[sides]), tangent) < 0:
            fan = fan[:, ::-1]
        caps.append(TriangleMesh(pos, fan, np.broadcast_to(tangent, pos.shape).copy()))
    return merge([mesh] + caps)


def leaf(*, length: float = 0.3, width: float = 0.12, thickness: float = 0.006, bend: float = 0.25,
         fold: float = 0.15, along: int = 6, across: int = 4) -> TriangleMesh:
    """A closed, thin, bent leaf blade lying along +Z from the origin with its face up (+Y).

    Two sheets (top facing up, bottom facing down) meet at the outline, so the blade is closed
    and both sides render lit (surfaces are one-sided); the outline vertices are duplicated so
    each sheet keeps its own smooth normals.

    Parameters
    ----------
    length, width, thickness : float
        Blade size; the thickness is at the midrib, tapering to 0 at the outline.
    bend : float
        The tip droops by ``bend * length``.
    fold : float
        V-fold along the midrib: the edges rise by ``fold * width / 2``.
    along, across : int
        Grid cells along the blade and across it (per sheet).

    Returns
    -------
    TriangleMesh
        ``4 * (along - 1) * across`` triangles (the base and tip rows are fans).
    """
    t = np.linspace(0.0, 1.0, along + 1)
    u = np.linspace(-1.0, 1.0, across + 1)
    tt, uu = np.meshgrid(t, u, indexing="ij")
    shape = np.sin(math.pi * tt) ** 0.8          # blade half-width profile: round base, pointed tip
    x = uu * width / 2 * shape
    mid = -bend * length * tt**2 + fold * width / 2 * np.abs(uu) * shape
    half = thickness / 2 * (1 - uu**2) * np.sin(math.pi * tt)
    z = tt * length
    k = np.arange(along)[:, None]
    j = np.arange(across)[None, :]
    a = k * (across + 1) + j
    b, c, d = a + 1, a + across + 2, a + across + 1
    # a→b runs along +x, a→d along +z: (+x) × (+z) = −y, so (a, d, c), (a, c, b) face up.
    up_faces = np.stack([np.stack([a, d, c], -1), np.stack([a, c, b], -1)], 2).reshape(-1, 3)
    sheets = []
    for sign, faces in ((1.0, up_faces), (-1.0, up_faces[:, ::-1])):
        pos = np.stack([x, mid + sign * half, z], -1).reshape(-1, 3)
        faces = faces[~degenerate_faces(pos, faces)]  # base and tip rows collapse to points
        sheets.append(TriangleMesh(pos, faces, vertex_normals(pos, faces)))
    return merge(sheets)


def outward(positions: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """``faces`` of a closed mesh, reversed if needed so their normals point outward.

    Uses the sign of the enclosed volume (divergence theorem): positive for outward winding.
    """
    p = np.asarray(positions, dtype=np.float64)
    a, b, c = p[faces[:, 0]], p[faces[:, 1]], p[faces[:, 2]]
    volume = np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6
    return faces if volume >= 0 else faces[:, ::-1].copy()
