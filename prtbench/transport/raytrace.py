"""Batched ray queries against a triangle scene (embreex / Embree 4).

All precompute ray casting goes through :class:`Tracer` (DESIGN.md §8): rays are float32, sent
in bounded chunks, and a scene is built once. Large batches are split across the precompute
threads (``PRTBENCH_THREADS``, :mod:`prtbench.transport.parallel`; embree releases the GIL); inside a
worker thread of a chunked precompute loop, queries stay on that thread. Visibility is
geometric: a triangle blocks light from either side, even though surfaces are shaded one-sided.

Self-intersection: a ray leaving a surface point in float32 can hit the very triangle it starts
on (its origin is only within ~1e-7 relative of the plane). :func:`offset_origins` moves
origins along the normal by a fixed fraction of the scene's bounding-box diagonal, which is
scale-free and far above float32 rounding yet far below any feature the scenes model. The
Embree scene is built with its robust flag, so rays through shared edges and vertices of
adjacent triangles cannot slip between them (no light leaks through mesh seams).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from prtbench.api.errors import InvalidInputError
from prtbench.transport.parallel import in_worker, map_chunks, parallel_chunks, thread_count

if TYPE_CHECKING:
    from prtbench.scene.model import Scene

#: Rays per embree call: bounds the temporary float32 arrays (~40 bytes/ray) to ~80 MB.
CHUNK_RAYS = 1 << 21

#: Batches of at least this many rays are split across the precompute threads
#: (:mod:`prtbench.transport.parallel`); smaller ones are not worth a pool.
PARALLEL_RAYS = 1 << 15

#: Origin offset along the normal, as a fraction of the scene's bounding-box diagonal.
OFFSET_SCALE = 1e-4

#: Faces with area <= this fraction of diagonal² are skipped (they cannot block any ray).
DEGENERATE_AREA = 1e-14


@dataclass(frozen=True)
class Hits:
    """First hits of a batch of rays.

    Attributes
    ----------
    t : ndarray, shape (N,), float32
        Distance along the (unit) direction; ``inf`` where the ray misses.
    face : ndarray, shape (N,), int64
        Original face index of the hit triangle, -1 on a miss.
    u, v : ndarray, shape (N,), float32
        Barycentric coordinates: hit = (1 − u − v)·p0 + u·p1 + v·p2 of the face's vertices.
    """

    t: np.ndarray
    face: np.ndarray
    u: np.ndarray
    v: np.ndarray

    @property
    def hit(self) -> np.ndarray:
        """(N,) bool: the ray hit something."""
        return self.face >= 0


def offset_origins(points: np.ndarray, normals: np.ndarray, *, diagonal: float,
                   scale: float = OFFSET_SCALE) -> np.ndarray:
    """Ray origins moved off the surface along the normal.

    Parameters
    ----------
    points, normals : ndarray, shape (N, 3)
        Surface points and their normals (normalised here; zero normals give no offset).
    diagonal : float
        Scene bounding-box diagonal; the offset is ``scale · diagonal``.
    scale : float
        Relative offset (default 1e-4: ~1000× the float32 rounding of a coordinate of the
        scene's size, so a ray never re-hits its own triangle).

    Returns
    -------
    ndarray, shape (N, 3), float64
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    length = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.divide(n, length, out=np.zeros_like(n), where=length > 0)
    return p + n * (scale * float(diagonal))


def _as_rays(origins: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    o = np.asarray(origins).reshape(-1, 3)
    d = np.asarray(directions).reshape(-1, 3)
    if len(o) != len(d):
        raise InvalidInputError(f"{len(o)} ray origins but {len(d)} directions; accepted: equal counts")
    return o, d


def _float32_rows(a: np.ndarray) -> np.ndarray:
    """(N, 3) rays as embree reads them: ``a`` itself when float32 with each row's three
    values adjacent, at any row stride of at least 12 bytes (e.g. a view of padded (N, 4)
    records; embreex reads strided buffers), else a contiguous float32 copy."""
    if a.dtype == np.float32 and a.strides[1] == 4 and a.strides[0] >= 12:
        return a
    return np.ascontiguousarray(a, dtype=np.float32)


def _ray_chunks(n: int) -> tuple[list[slice], int]:
    """(slices, threads) for a batch of ``n`` rays: one slice per embree call.

    Large batches get several slices per thread (rays of unequal cost stay balanced). Rays are
    independent, so the split, which depends on the thread count, cannot change any result.
    """
    threads = thread_count()  # read (and checked) on every query, like every other user
    if in_worker() or n < PARALLEL_RAYS or threads == 1:
        return parallel_chunks(n, CHUNK_RAYS), 1
    per_chunk = min(CHUNK_RAYS, max(PARALLEL_RAYS // 2, -(-n // (4 * threads))))
    return parallel_chunks(n, per_chunk), threads


class Tracer:
    """An Embree scene over one triangle mesh, answering batched occlusion and first-hit queries.

    Parameters
    ----------
    positions : ndarray, shape (V, 3)
    faces : ndarray, shape (F, 3), int
        Triangles; those with non-finite vertices or (near-)zero area are skipped and counted
        in ``n_skipped``, never passed to Embree.

    Attributes
    ----------
    positions : ndarray, shape (V, 3), float32
    faces : ndarray, shape (F, 3), int32
        The original faces (face ids in :class:`Hits` index these).
    face_of_prim : ndarray, shape (F_kept,), int64
        Original face id of each Embree primitive.
    n_skipped : int
        Faces left out as degenerate.
    diagonal : float
        Bounding-box diagonal of the finite vertices.
    object_of_face : ndarray, shape (F,), int32, or None
        Scene object of each face (set by :meth:`from_scene`).
    normals : ndarray, shape (V, 3), float32, or None
        Vertex shading normals (set by :meth:`from_scene`).
    """

    def __init__(self, positions: np.ndarray, faces: np.ndarray):
        from embreex.mesh_construction import TriangleMesh as EmbreeMesh
        from embreex.rtcore_scene import EmbreeScene

        self.positions = np.ascontiguousarray(positions, dtype=np.float32).reshape(-1, 3)
        self.faces = np.ascontiguousarray(faces, dtype=np.int32).reshape(-1, 3)
        n_vertices = len(self.positions)
        if len(self.faces) and (self.faces.min() < 0 or self.faces.max() >= n_vertices):
            raise InvalidInputError(
                f"tracer faces index vertices outside 0..{n_vertices - 1}")
        finite_vertex = np.all(np.isfinite(self.positions), axis=1)
        finite = self.positions[finite_vertex].astype(np.float64)
        self.diagonal = float(np.linalg.norm(finite.max(axis=0) - finite.min(axis=0))) \
            if len(finite) else 0.0
        self.object_of_face: np.ndarray | None = None
        self.normals: np.ndarray | None = None

        keep = np.all(finite_vertex[self.faces], axis=1) if len(self.faces) else np.zeros(0, bool)
        if len(self.faces):
            p = self.positions.astype(np.float64)
            with np.errstate(invalid="ignore", over="ignore"):
                cross = np.cross(p[self.faces[:, 1]] - p[self.faces[:, 0]],
                                 p[self.faces[:, 2]] - p[self.faces[:, 0]])
                area = 0.5 * np.linalg.norm(cross, axis=1)
            keep &= np.isfinite(area) & (area > DEGENERATE_AREA * self.diagonal**2)
        self.face_of_prim = np.flatnonzero(keep).astype(np.int64)
        self.n_skipped = int(len(self.faces) - len(self.face_of_prim))

        self._scene = EmbreeScene(robust=True)
        if len(self.face_of_prim):
            # Embree keeps a pointer to the buffers: hold references for the scene's lifetime.
            self._vertices = np.ascontiguousarray(np.nan_to_num(self.positions), dtype=np.float32)
            self._indices = np.ascontiguousarray(self.faces[self.face_of_prim], dtype=np.int32)
            self._mesh = EmbreeMesh(self._scene, self._vertices, self._indices)
            # embreex builds the BVH on the first query, unguarded: build it now, before any
            # thread can race another into building it twice.
            self._scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32),
                            query="OCCLUDED")
        self._empty = len(self.face_of_prim) == 0

    @classmethod
    def from_scene(cls, scene: "Scene") -> "Tracer":
        """A tracer over all objects of ``scene`` merged (face ids follow ``Scene.merged()``)."""
        positions, normals, faces, object_of_face = scene.merged()
        tracer = cls(positions, faces)
        tracer.normals = normals
        tracer.object_of_face = object_of_face
        return tracer

    def occluded(self, origins: np.ndarray, directions: np.ndarray, *,
                 tfar: float | np.ndarray = np.inf) -> np.ndarray:
        """Whether each ray hits any triangle within distance ``tfar`` (either side).

        Parameters
        ----------
        origins, directions : ndarray, shape (N, 3)
            Directions need not be unit (``tfar`` is then in units of their length).
        tfar : float or ndarray, shape (N,)

        Returns
        -------
        ndarray, shape (N,), bool
        """
        o, d = _as_rays(origins, directions)
        n = len(o)
        out = np.zeros(n, dtype=bool)
        if self._empty or n == 0:
            return out
        per_ray = np.ndim(tfar) > 0
        if per_ray:
            tfar = np.asarray(tfar, dtype=np.float64).reshape(-1)
            if len(tfar) != n:
                raise InvalidInputError(f"tfar has {len(tfar)} values for {n} rays")
        fmax = np.finfo(np.float32).max
        scalar_far = None if per_ray else float(min(float(tfar), fmax))

        def trace(sl: slice) -> None:
            oc, dc = _float32_rows(o[sl]), _float32_rows(d[sl])
            # embreex may write into a tfar array it is given: always pass a fresh copy.
            dist = (np.minimum(tfar[sl], fmax).astype(np.float32) if per_ray else scalar_far)
            out[sl] = self._scene.run(oc, dc, dists=dist, query="OCCLUDED") != -1

        chunks, threads = _ray_chunks(n)
        for _ in map_chunks(trace, chunks, threads=threads):
            pass
        return out

    def first_hit(self, origins: np.ndarray, directions: np.ndarray) -> Hits:
        """The nearest triangle along each ray (either side).

        Parameters
        ----------
        origins, directions : ndarray, shape (N, 3)

        Returns
        -------
        Hits
        """
        o, d = _as_rays(origins, directions)
        n = len(o)
        t = np.full(n, np.inf, dtype=np.float32)
        face = np.full(n, -1, dtype=np.int64)
        u = np.zeros(n, dtype=np.float32)
        v = np.zeros(n, dtype=np.float32)
        if self._empty or n == 0:
            return Hits(t, face, u, v)

        def trace(sl: slice) -> None:
            oc, dc = _float32_rows(o[sl]), _float32_rows(d[sl])
            res = self._scene.run(oc, dc, output=1)
            prim = res["primID"]
            hit = prim >= 0
            face[sl][hit] = self.face_of_prim[prim[hit]]
            t[sl][hit] = res["tfar"][hit]
            u[sl][hit] = res["u"][hit]
            v[sl][hit] = res["v"][hit]

        chunks, threads = _ray_chunks(n)
        for _ in map_chunks(trace, chunks, threads=threads):
            pass
        return Hits(t, face, u, v)


def geometry_mask(scene: Scene, view, width: int, height: int) -> np.ndarray:
    """(H, W) bool: pixels whose centre ray hits geometry (the masked metrics' support)."""
    tracer = _tracer_for(scene)
    origins, dirs = view.primary_rays(width, height)
    hits = tracer.first_hit(origins.reshape(-1, 3), dirs.reshape(-1, 3))
    return (hits.face >= 0).reshape(height, width)


_TRACERS: dict[str, Any] = {}


def _tracer_for(scene: Scene) -> "Tracer":
    key = scene.content_hash()
    if key not in _TRACERS:
        _TRACERS.clear()  # one scene at a time keeps memory bounded on big scenes
        _TRACERS[key] = Tracer.from_scene(scene)
    return _TRACERS[key]
