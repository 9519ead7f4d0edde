"""Ray queries: self-intersection, light leaks, degenerate input (DESIGN.md §8)."""

from __future__ import annotations

import numpy as np
import pytest

from prtbench.api.errors import InvalidInputError
from prtbench.scene.geometry import grid_plane
from prtbench.scene.model import Material, Scene, SceneObject, TriangleMesh
from prtbench.transport.ray_pattern import RayPattern
from prtbench.transport.raytrace import Tracer, offset_origins
from scenes.primitives import box, merge, uv_sphere


def _hemisphere_rays(points: np.ndarray, normals: np.ndarray, *, rays: int, diagonal: float,
                     seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Cosine-weighted rays about each normal (the transfer's own generator), offset origins."""
    normals = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    pattern = RayPattern(len(points), rays, seed)
    sl = slice(0, len(points))
    dirs = pattern.world_directions(pattern.frames(normals, sl), sl).reshape(-1, 3)
    origins = np.repeat(offset_origins(points, normals, diagonal=diagonal), rays, axis=0)
    return origins, dirs


def _grazing_dirs(normal: np.ndarray, n: int, cos_min: float = 1e-3) -> np.ndarray:
    """Directions around the horizon of ``normal`` (cosine ``cos_min``) plus a few steep ones."""
    normal = normal / np.linalg.norm(normal)
    t = np.cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 0.0, 1.0])
    t /= np.linalg.norm(t)
    b = np.cross(normal, t)
    phi = np.linspace(0, 2 * np.pi, n, endpoint=False)
    cos = np.concatenate([np.full(n // 2, cos_min), np.linspace(0.05, 1.0, n - n // 2)])
    sin = np.sqrt(1 - cos**2)
    return cos[:, None] * normal + sin[:, None] * (np.cos(phi)[:, None] * t + np.sin(phi)[:, None] * b)


def test_plane_with_nothing_above_is_unoccluded_for_all_upward_rays():
    mesh = grid_plane(4.0, 8)
    tracer = Tracer(mesh.positions, mesh.faces)
    rng = np.random.default_rng(0)
    points = np.c_[rng.uniform(-1.99, 1.99, 300), np.zeros(300), rng.uniform(-1.99, 1.99, 300)]
    # Vertices and edge midpoints of the grid are where a ray may re-hit a neighbouring triangle.
    points = np.concatenate([points, mesh.positions, 0.5 * (mesh.positions[:-1] + mesh.positions[1:])])
    normals = np.tile([0.0, 1.0, 0.0], (len(points), 1))
    origins, dirs = _hemisphere_rays(points, normals, rays=256, diagonal=tracer.diagonal)
    assert not tracer.occluded(origins, dirs).any()
    grazing = _grazing_dirs(np.array([0.0, 1.0, 0.0]), 64)
    o = np.repeat(offset_origins(points, normals, diagonal=tracer.diagonal), 64, axis=0)
    assert not tracer.occluded(o, np.tile(grazing, (len(points), 1))).any()
    # Straight down, the same origins do hit the plane (the query is not trivially false).
    assert tracer.occluded(o[::64][:300], -normals[:300]).all()


def test_floor_inside_closed_box_is_fully_occluded():
    room = box((2.0, 1.0, 2.0), center=(0.0, 0.5, 0.0))
    tracer = Tracer(room.positions, room.faces)
    rng = np.random.default_rng(1)
    # Interior floor points, including ones 1e-3 from the walls and in the corners.
    xz = np.concatenate([rng.uniform(-0.999, 0.999, (200, 2)),
                         [[0.999, 0.999], [-0.999, 0.999], [0.999, -0.999], [-0.999, -0.999]]])
    points = np.c_[xz[:, 0], np.zeros(len(xz)), xz[:, 1]]
    normals = np.tile([0.0, 1.0, 0.0], (len(points), 1))
    origins, dirs = _hemisphere_rays(points, normals, rays=256, diagonal=tracer.diagonal)
    assert tracer.occluded(origins, dirs).all()
    o = np.repeat(offset_origins(points, normals, diagonal=tracer.diagonal), 64, axis=0)
    assert tracer.occluded(o, np.tile(_grazing_dirs(normals[0], 64), (len(points), 1))).all()


def test_point_under_thin_plate_is_occluded_and_plate_top_sees_the_sky():
    ground = grid_plane(4.0, 1)
    thickness = 2e-3  # 1e-3 of the scene diagonal: ~10x the origin offset
    plate = box((1.0, thickness, 1.0), center=(0.0, 0.05, 0.0))
    scene_mesh = merge([ground, plate])
    tracer = Tracer(scene_mesh.positions, scene_mesh.faces)
    up = np.tile([0.0, 1.0, 0.0], (1, 1))
    # Ground points under the plate up to 1e-4 from its edge: straight-up rays must hit it.
    edge = 0.5 - 1e-4
    xs = np.concatenate([np.linspace(-edge, edge, 41), np.full(41, edge), np.full(41, -edge)])
    zs = np.concatenate([np.full(41, edge), np.linspace(-edge, edge, 41), np.linspace(-edge, edge, 41)])
    under = np.c_[xs, np.zeros_like(xs), zs]
    o = offset_origins(under, np.repeat(up, len(under), 0), diagonal=tracer.diagonal)
    assert tracer.occluded(o, np.repeat(up, len(under), 0)).all()
    # Rays tilted toward the plate's centre also hit it (through its edge region).
    toward = np.c_[-xs, np.full(len(xs), 0.5), -zs]
    assert tracer.occluded(o, toward).all()
    # Just outside the edge the sky is visible: the plate does not grow by the offset.
    outside = np.c_[xs * (0.5 + 1e-3) / edge, np.zeros_like(xs), zs * (0.5 + 1e-3) / edge]
    o_out = offset_origins(outside, np.repeat(up, len(xs), 0), diagonal=tracer.diagonal)
    assert not tracer.occluded(o_out, np.repeat(up, len(xs), 0)).any()
    # The plate's top face sees the whole upper hemisphere: no hit on its own top or bottom.
    rng = np.random.default_rng(2)
    top = np.c_[rng.uniform(-0.5, 0.5, 100), np.full(100, 0.05 + thickness / 2),
                rng.uniform(-0.5, 0.5, 100)]
    origins, dirs = _hemisphere_rays(top, np.repeat(up, 100, 0), rays=128, diagonal=tracer.diagonal)
    assert not tracer.occluded(origins, dirs).any()
    # Its bottom face looks down at the ground: every downward ray that reaches the ground
    # within its extent is blocked, none slips between the plate's bottom and top.
    bottom = top - [0.0, thickness, 0.0]
    origins, dirs = _hemisphere_rays(bottom, np.repeat(-up, 100, 0), rays=128, diagonal=tracer.diagonal)
    steep = -dirs[:, 1] > 0.1  # lands within 0.5 of the point, on the 4 x 4 ground
    assert tracer.occluded(origins[steep], dirs[steep]).all()
    assert tracer.first_hit(origins[steep], dirs[steep]).face.max() < ground.n_triangles


def test_rays_leaving_a_sphere_are_not_self_occluded():
    ball = uv_sphere(radius=0.7, segments=48, center=(0.2, 1.0, -0.3))
    tracer = Tracer(ball.positions, ball.faces)
    # Vertices with their smooth normals, and face centroids with their flat normals.
    corners = ball.positions.astype(np.float64)[ball.faces]
    centroids = corners.mean(axis=1)
    flat = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    points = np.concatenate([ball.positions, centroids])
    normals = np.concatenate([ball.normals, flat / np.linalg.norm(flat, axis=1, keepdims=True)])
    origins, dirs = _hemisphere_rays(points, normals, rays=128, diagonal=tracer.diagonal)
    assert not tracer.occluded(origins, dirs).any()
    # Straight inward from the same origins, the sphere is hit.
    o = offset_origins(points, normals, diagonal=tracer.diagonal)
    assert tracer.occluded(o, -normals).all()


def test_degenerate_triangles_are_skipped_counted_and_ids_map_back():
    positions = np.array([
        [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0],    # a real triangle (normal -Y)
        [2.0, 0.0, 0.0], [3.0, 0.0, 0.0], [4.0, 0.0, 0.0],    # collinear
        [np.nan, 0.0, 0.0], [np.inf, 1.0, 0.0],               # non-finite
    ])
    faces = np.array([[3, 4, 5], [0, 0, 1], [6, 1, 2], [0, 7, 2], [0, 1, 2], [3, 3, 3]])
    tracer = Tracer(positions, faces)
    assert tracer.n_skipped == 5
    origins = np.array([[0.2, 1.0, 0.2], [2.5, 1.0, 0.0], [0.9, 1.0, 0.9]])
    dirs = np.tile([0.0, -1.0, 0.0], (3, 1))
    np.testing.assert_array_equal(tracer.occluded(origins, dirs), [True, False, False])
    hits = tracer.first_hit(origins, dirs)
    np.testing.assert_array_equal(hits.face, [4, -1, -1])  # the original face id
    assert hits.t[0] == pytest.approx(1.0) and np.isinf(hits.t[1])
    assert np.isfinite(tracer.diagonal) and tracer.diagonal == pytest.approx(np.sqrt(17.0))


def test_all_degenerate_scene_answers_misses():
    tracer = Tracer(np.zeros((3, 3)), np.array([[0, 1, 2]]))
    assert tracer.n_skipped == 1
    o, d = np.zeros((4, 3)), np.tile([0.0, 1.0, 0.0], (4, 1))
    assert not tracer.occluded(o, d).any()
    assert (tracer.first_hit(o, d).face == -1).all()


def test_first_hit_barycentrics_distance_and_tfar():
    ball = uv_sphere(radius=1.0, segments=24)
    tracer = Tracer(ball.positions, ball.faces)
    rng = np.random.default_rng(3)
    targets = rng.uniform(-0.5, 0.5, size=(500, 3))  # inside the unit sphere
    origins = np.tile([0.0, 0.0, 5.0], (500, 1)) + rng.normal(size=(500, 3)) * 0.1
    dirs = targets - origins
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    hits = tracer.first_hit(origins, dirs)
    assert hits.hit.all()
    corners = ball.positions.astype(np.float64)[ball.faces[hits.face]]
    bary = np.stack([1 - hits.u - hits.v, hits.u, hits.v], axis=1)
    on_triangle = np.einsum("nk,nkj->nj", bary, corners)
    np.testing.assert_allclose(on_triangle, origins + hits.t[:, None] * dirs, atol=1e-5)
    assert (bary >= -1e-6).all()
    # The front side was hit: the ray runs against the outward face normal.
    face_n = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    assert (np.einsum("nj,nj->n", face_n, dirs) < 0).all()
    assert not tracer.occluded(origins, dirs, tfar=hits.t * 0.99).any()
    assert tracer.occluded(origins, dirs, tfar=hits.t * 1.01).all()
    assert tracer.occluded(origins, dirs, tfar=5.0).all()
    assert not tracer.occluded(origins, dirs, tfar=3.0).any()
    rays_away = tracer.first_hit(origins, -dirs)
    assert (rays_away.face == -1).all() and np.isinf(rays_away.t).all()


def test_rays_in_padded_records_trace_like_contiguous_ones():
    """float32 rays viewed out of (N, 4) records go to embree uncopied, with the same answers."""
    ball = uv_sphere(radius=1.0, segments=24)
    tracer = Tracer(ball.positions, ball.faces)
    rng = np.random.default_rng(5)
    origins = rng.uniform(-3, 3, size=(400, 3)).astype(np.float32)
    dirs = rng.normal(size=(400, 3)).astype(np.float32)
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    padded_o, padded_d = (np.full((400, 4), np.nan, np.float32) for _ in range(2))
    padded_o[:, :3], padded_d[:, :3] = origins, dirs
    blocked = tracer.occluded(origins, dirs)
    assert 0 < blocked.sum() < len(blocked)
    np.testing.assert_array_equal(tracer.occluded(padded_o[:, :3], padded_d[:, :3]), blocked)
    hits = tracer.first_hit(origins, dirs)
    padded_hits = tracer.first_hit(padded_o[:, :3], padded_d[:, :3])
    for name in ("t", "face", "u", "v"):
        np.testing.assert_array_equal(getattr(padded_hits, name), getattr(hits, name))


def test_from_scene_merges_objects_and_remembers_their_faces():
    ground = SceneObject("ground", grid_plane(4.0, 2), Material())
    ball = SceneObject("ball", uv_sphere(radius=0.5, segments=16, center=(0, 1, 0)), Material())
    scene = Scene("t", [ground, ball])
    tracer = Tracer.from_scene(scene)
    assert tracer.diagonal == pytest.approx(scene.diagonal())
    n_ground = ground.mesh.n_triangles
    np.testing.assert_array_equal(tracer.object_of_face, [0] * n_ground + [1] * ball.mesh.n_triangles)
    hits = tracer.first_hit(np.array([[0.0, 3.0, 0.0], [1.5, 3.0, 1.5]]), np.array([[0, -1.0, 0]] * 2))
    np.testing.assert_array_equal(tracer.object_of_face[hits.face], [1, 0])
    assert hits.t[0] == pytest.approx(1.5, abs=1e-3) and hits.t[1] == pytest.approx(3.0)


def test_bad_inputs_raise_one_line_errors():
    with pytest.raises(InvalidInputError, match="index vertices"):
        Tracer(np.zeros((3, 3)), np.array([[0, 1, 3]]))
    mesh = grid_plane(1.0, 1)
    tracer = Tracer(mesh.positions, mesh.faces)
    with pytest.raises(InvalidInputError, match="origins"):
        tracer.occluded(np.zeros((2, 3)), np.zeros((3, 3)))
    with pytest.raises(InvalidInputError, match="tfar"):
        tracer.occluded(np.zeros((2, 3)), np.ones((2, 3)), tfar=np.ones(3))


def test_offset_scales_with_the_scene_and_ignores_zero_normals():
    points = np.zeros((2, 3))
    normals = np.array([[0.0, 2.0, 0.0], [0.0, 0.0, 0.0]])
    out = offset_origins(points, normals, diagonal=10.0)
    np.testing.assert_allclose(out, [[0.0, 1e-3, 0.0], [0.0, 0.0, 0.0]])


def test_large_batches_are_chunked(monkeypatch):
    import prtbench.transport.raytrace as raytrace

    monkeypatch.setattr(raytrace, "CHUNK_RAYS", 1000)
    mesh = TriangleMesh(np.array([[-1.0, 0, -1], [1, 0, -1], [0, 0, 2]]), np.array([[0, 2, 1]]))
    tracer = Tracer(mesh.positions, mesh.faces)
    n = 4321
    x = np.linspace(-3, 3, n)
    x = x[np.abs(np.abs(x) - 2 / 3) > 1e-3]
    origins = np.c_[x, np.ones(len(x)), np.zeros(len(x))]
    dirs = np.tile([0.0, -1.0, 0.0], (len(x), 1))
    expected = np.abs(x) < 2 / 3  # the triangle spans |x| < 2/3 at z = 0
    assert (tracer.occluded(origins, dirs) == expected).all()
    assert ((tracer.first_hit(origins, dirs).face == 0) == expected).all()
