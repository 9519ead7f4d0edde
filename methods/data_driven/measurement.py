"""Measurement points: where the data-driven method measures direct light (paper §4.1, Fig. 4).

Points are spread as blue noise by Yuksel's weighted sample elimination ("Sample Elimination
for Generating Poisson Disk Sample Sets", 2015): draw ``ratio``·n area-uniform Turk samples,
give each the weight W_i = Σ_j (1 − d̂_ij / 2r_max)^α over its neighbours closer than 2·r_max,
and repeatedly remove the heaviest sample (updating its neighbours' weights) until n remain.
r_max = √(A / (2√3 n)) is the densest-packing radius on a surface of area A; d̂ clamps small
distances to r_min = 2·r_max·(1 − (n/m)^1.5)·0.65 (Yuksel's weight limiting) so clusters do not
dominate. Points on opposite sides of a thin wall (normals more than 90° apart) do not repel:
they measure different light.

``placement='visible'`` (the default) keeps only surface samples that some camera of the scene's
trajectory sees (inside its frustum, front-facing, unoccluded): the asset the views frame rather
than, say, the far corners of a 4 m ground plane, which would otherwise take most of the points
because blue noise spreads them by area. ``'surface'`` uses the whole surface; ``'hull'`` puts the
points on the convex hull of the scene (the paper's choice for hair), with unit albedo. ``supersample`` > 1 attaches to each point its nearest
dense samples (its Voronoi neighbours), whose shaded values are averaged at run time (§5.1).
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass

import numpy as np

from prtbench.api.errors import InvalidInputError, UnknownNameError
from prtbench.scene.geometry import sample_surface
from prtbench.scene.model import Scene, TriangleMesh
from prtbench.transport.raytrace import Tracer, offset_origins

PLACEMENTS = ("visible", "surface", "hull")

#: Yuksel's defaults: weight exponent, weight-limiting γ and β.
ALPHA = 8.0
GAMMA = 1.5
BETA = 0.65


@dataclass(frozen=True, eq=False)
class MeasurementPoints:
    """The fake G-buffer: positions, normals and albedo of every (sub-)point.

    Attributes
    ----------
    points, normals : ndarray, shape (P, S, 3), float32
        S sub-points per measurement point (S = 1 without supersampling); sub-point 0 is the
        point itself.
    albedo : ndarray, shape (P, S, 3), float32
        Diffuse albedo kd (1 on the hull).
    """

    points: np.ndarray
    normals: np.ndarray
    albedo: np.ndarray

    def __len__(self) -> int:
        return int(self.points.shape[0])

    @property
    def supersample(self) -> int:
        return int(self.points.shape[1])


def eliminate(points: np.ndarray, normals: np.ndarray | None, n: int, *, area: float,
              alpha: float = ALPHA, weight_limiting: bool = True) -> np.ndarray:
    """Yuksel's weighted sample elimination; the indices of the ``n`` kept samples.

    Parameters
    ----------
    points : ndarray, shape (m, 3)
        Dense input samples (m ≥ n).
    normals : ndarray, shape (m, 3), or None
        Samples whose normals point more than 90° apart never interact.
    n : int
        Samples to keep.
    area : float
        Area of the sampled surface (sets r_max).

    Returns
    -------
    ndarray, shape (n,), int64, sorted
    """
    from scipy.spatial import cKDTree

    m = len(points)
    if not 0 < n <= m:
        raise InvalidInputError(f"sample elimination keeps {n} of {m} samples; accepted: 0 < n <= m")
    if n == m:
        return np.arange(m)
    r_max = math.sqrt(area / (2.0 * math.sqrt(3.0) * n))
    d_max = 2.0 * r_max
    d_min = d_max * (1.0 - (n / m) ** GAMMA) * BETA if weight_limiting else 0.0
    tree = cKDTree(points)
    pairs = tree.query_pairs(d_max, output_type="ndarray")
    if normals is not None and len(pairs):
        same_side = np.einsum("ij,ij->i", normals[pairs[:, 0]], normals[pairs[:, 1]]) > 0
        pairs = pairs[same_side]
    dist = np.linalg.norm(points[pairs[:, 0]] - points[pairs[:, 1]], axis=1) if len(pairs) \
        else np.zeros(0)
    w = (1.0 - np.maximum(dist, d_min) / d_max) ** alpha
    weight = np.zeros(m)
    np.add.at(weight, pairs[:, 0], w)
    np.add.at(weight, pairs[:, 1], w)
    # Symmetric adjacency in CSR form for the weight updates.
    rows = np.concatenate([pairs[:, 0], pairs[:, 1]])
    cols = np.concatenate([pairs[:, 1], pairs[:, 0]])
    ws = np.concatenate([w, w])
    order = np.argsort(rows, kind="stable")
    rows, cols, ws = rows[order], cols[order], ws[order]
    start = np.searchsorted(rows, np.arange(m + 1))
    alive = np.ones(m, dtype=bool)
    # Max-heap with lazy deletion: an entry is current only if it matches the live weight.
    heap = [(-weight[i], i) for i in range(m)]
    heapq.heapify(heap)
    remaining = m
    while remaining > n:
        neg, i = heapq.heappop(heap)
        if not alive[i] or -neg != weight[i]:
            continue
        alive[i] = False
        remaining -= 1
        for k in range(start[i], start[i + 1]):
            j = cols[k]
            if alive[j]:
                weight[j] -= ws[k]
                heapq.heappush(heap, (-weight[j], j))
    return np.flatnonzero(alive)


def hull_mesh(scene: Scene) -> TriangleMesh:
    """The convex hull of all scene vertices as an outward-facing triangle mesh."""
    from scipy.spatial import ConvexHull

    pts = np.concatenate([o.mesh.positions for o in scene.objects]).astype(np.float64)
    hull = ConvexHull(pts)
    faces = hull.simplices.copy()
    centre = pts[hull.vertices].mean(axis=0)
    p = pts[faces]
    normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    inward = np.einsum("ij,ij->i", normal, p.mean(axis=1) - centre) < 0
    faces[inward] = faces[inward][:, ::-1]
    used, faces = np.unique(faces, return_inverse=True)
    positions = pts[used]
    faces = faces.reshape(-1, 3)
    # Flat normals: duplicate vertices per face so sample normals are the facet normals.
    flat = positions[faces].reshape(-1, 3)
    fn = np.cross(positions[faces[:, 1]] - positions[faces[:, 0]],
                  positions[faces[:, 2]] - positions[faces[:, 0]])
    fn /= np.linalg.norm(fn, axis=1, keepdims=True)
    return TriangleMesh(flat, np.arange(len(flat)).reshape(-1, 3), np.repeat(fn, 3, axis=0))


def visible_from_views(scene: Scene, points: np.ndarray, normals: np.ndarray, *,
                       aspect: float = 4.0 / 3.0) -> np.ndarray:
    """(N,) bool: each point is seen by at least one trajectory camera (frustum, facing, unoccluded)."""

    tracer = Tracer.from_scene(scene)
    origins = offset_origins(points, normals, diagonal=tracer.diagonal)
    seen = np.zeros(len(points), dtype=bool)
    for view in scene.trajectory.views:
        eye = np.asarray(view.eye, dtype=np.float64)
        to_eye = eye - points
        dist = np.linalg.norm(to_eye, axis=1)
        cam = (view.camera_from_world() @ np.c_[points, np.ones(len(points))].T).T
        f = 1.0 / math.tan(math.radians(view.fov_y) / 2)
        depth = -cam[:, 2]
        inside = (depth > 0) & (np.abs(cam[:, 0] * f / aspect) <= depth) & (np.abs(cam[:, 1] * f) <= depth)
        facing = np.einsum("ij,ij->i", normals, to_eye) > 0
        test = np.flatnonzero(inside & facing & ~seen)
        if len(test):
            blocked = tracer.occluded(origins[test], to_eye[test] / dist[test, None],
                                      tfar=dist[test] * (1 - 1e-4))
            seen[test[~blocked]] = True
    return seen


def _albedo(scene: Scene, object_ids: np.ndarray) -> np.ndarray:
    kd = np.array([o.material.kd for o in scene.objects], dtype=np.float64)
    return kd[object_ids]


def measurement_points(scene: Scene, count: int, *, placement: str = "surface",
                       supersample: int = 1, ratio: int = 5, seed: int = 0) -> MeasurementPoints:
    """Blue-noise measurement points on the scene's surface or its convex hull.

    Parameters
    ----------
    scene : Scene
    count : int
        Measurement points P.
    placement : {"surface", "hull"}
    supersample : int
        Sub-points S per point (§5.1): the point and its S − 1 nearest dense samples.
    ratio : int
        Dense samples per kept point (Yuksel uses 3–5).
    seed : int

    Returns
    -------
    MeasurementPoints
    """
    if placement not in PLACEMENTS:
        raise UnknownNameError("measurement placement", placement, PLACEMENTS)
    if count < 1 or supersample < 1 or ratio < 1:
        raise InvalidInputError(f"measurement points {count}, supersample {supersample}, ratio "
                                f"{ratio}; accepted: all >= 1")
    dense_count = max(count * ratio, count * supersample)
    if placement in ("surface", "visible"):
        total_area = float(sum(o.mesh.triangle_areas().sum() for o in scene.objects))
        dense = sample_surface(scene, dense_count, seed=seed)
        area = total_area
        if placement == "visible" and len(scene.trajectory):
            # A pilot sample measures the visible fraction, then enough samples are drawn to
            # keep ``dense_count`` visible ones.
            seen = visible_from_views(scene, dense.points, dense.normals)
            fraction = max(float(seen.mean()), 1.0 / dense_count)
            if seen.sum() < count:
                raise InvalidInputError(
                    f"only {int(seen.sum())} of {dense_count} surface samples of scene "
                    f"'{scene.name}' are visible from its views; use placement 'surface'")
            dense = sample_surface(scene, int(math.ceil(dense_count / fraction * 1.1)), seed=seed)
            seen = visible_from_views(scene, dense.points, dense.normals)
            dense = type(dense)(dense.points[seen], dense.normals[seen], dense.face_ids[seen],
                                dense.barycentrics[seen], dense.object_ids[seen])
            area = total_area * float(seen.mean())
        albedo = _albedo(scene, dense.object_ids)
    else:
        hull = hull_mesh(scene)
        dense = sample_surface(hull, dense_count, seed=seed)
        area = float(hull.triangle_areas().sum())
        albedo = np.ones((dense_count, 3))
    keep = eliminate(dense.points, dense.normals, count, area=area)
    points, normals = dense.points, dense.normals
    s = int(supersample)
    index = np.repeat(keep[:, None], s, axis=1)
    if s > 1:
        from scipy.spatial import cKDTree

        # Each dense sample belongs to its nearest kept point on the same side.
        owner_dist, owner = cKDTree(points[keep]).query(points, k=min(4, count))
        owner_dist = np.atleast_2d(owner_dist.T).T
        owner = np.atleast_2d(owner.T).T
        same = np.einsum("ijk,ik->ij", normals[keep][owner], normals) > 0
        pick = np.argmax(same, axis=1)
        own = np.where(same.any(axis=1), owner[np.arange(len(points)), pick], -1)
        d = owner_dist[np.arange(len(points)), pick]
        for slot, kept in enumerate(keep):
            members = np.flatnonzero((own == slot) & (np.arange(len(points)) != kept))
            members = members[np.argsort(d[members])][: s - 1]
            index[slot, 1:1 + len(members)] = members
    return MeasurementPoints(points[index].astype(np.float32), normals[index].astype(np.float32),
                             albedo[index].astype(np.float32))
