"""Surface sampling, UV atlases and mesh clean-up."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from prtbench.api.errors import InvalidInputError
from prtbench.scene import geometry
from prtbench.scene.geometry import (
    boundary_loops,
    degenerate_faces,
    fill_holes,
    grid_plane,
    remove_degenerate,
    remove_duplicate_faces,
    sample_surface,
    scene_atlas,
    uv_atlas,
    uv_triangle_areas,
    weld_vertices,
)
from prtbench.scene.model import Material, Scene, SceneObject, TriangleMesh
from scenes.primitives import box, uv_sphere


def _unequal_triangles() -> TriangleMesh:
    """Disjoint right triangles with areas from 0.0005 to 0.5 (a 1000:1 range)."""
    scales = np.geomspace(0.03, 1.0, 12)
    positions, faces = [], []
    for k, s in enumerate(scales):
        base = np.array([3.0 * k, 0.0, 0.0])
        positions += [base, base + [s, 0, 0], base + [0, s, 0]]
        faces.append([3 * k, 3 * k + 1, 3 * k + 2])
    return TriangleMesh(np.array(positions), np.array(faces))


def test_sample_surface_is_area_uniform_across_triangles():
    mesh = _unequal_triangles()
    n = 200_000
    samples = sample_surface(mesh, n, seed=1)
    counts = np.bincount(samples.face_ids, minlength=mesh.n_triangles)
    areas = mesh.triangle_areas()
    expected = n * areas / areas.sum()
    assert expected.min() > 5  # chi-square validity
    p = stats.chisquare(counts, expected).pvalue
    assert p > 1e-3, p


def test_sample_surface_is_uniform_within_a_triangle():
    """For uniform points the first barycentric b0 has density 2(1 − b0) on [0, 1]."""
    mesh = TriangleMesh(np.array([[0, 0, 0], [2, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]))
    samples = sample_surface(mesh, 50_000, seed=2, min_barycentric=0.0)
    b0 = samples.barycentrics[:, 0]
    p = stats.kstest(b0, lambda x: 1 - (1 - x) ** 2).pvalue
    assert p > 1e-3, p
    # Points are the barycentric combination of the corners.
    np.testing.assert_allclose(samples.points, samples.barycentrics @ mesh.positions, atol=1e-6)


def test_samples_stay_off_vertices_and_edges_and_have_unit_normals():
    mesh = uv_sphere(radius=1.0, segments=12)
    min_b = 0.01
    samples = sample_surface(mesh, 20_000, seed=3, min_barycentric=min_b)
    assert samples.barycentrics.min() >= min_b
    np.testing.assert_allclose(samples.barycentrics.sum(axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(samples.normals, axis=1), 1.0, atol=1e-9)
    # On a sphere the interpolated normal points roughly along the position.
    assert np.all(np.einsum("ij,ij->i", samples.normals, samples.points) > 0.9)
    # Distance to the nearest vertex is bounded below (the point is not on a vertex).
    corners = mesh.positions[mesh.faces[samples.face_ids]].astype(np.float64)
    nearest = np.linalg.norm(corners - samples.points[:, None], axis=2).min(axis=1)
    assert nearest.min() > 1e-4


def test_sample_surface_on_a_scene_and_seed_reproducibility():
    big = SceneObject("big", grid_plane(2.0, 1), Material())            # area 4
    small = SceneObject("small", box((1.0, 1.0, 1.0), center=(0, 2, 0)), Material())  # area 6
    scene = Scene("t", [big, small])
    a = sample_surface(scene, 100_000, seed=5)
    b = sample_surface(scene, 100_000, seed=5)
    np.testing.assert_array_equal(a.points, b.points)
    frac_small = np.mean(a.object_ids == 1)
    assert abs(frac_small - 0.6) < 0.01
    on_big = a.object_ids == 0
    np.testing.assert_allclose(a.points[on_big, 1], 0.0, atol=1e-7)
    np.testing.assert_allclose(a.normals[on_big], [[0, 1, 0]] * on_big.sum())
    assert a.face_ids[on_big].max() < 2 and a.face_ids[~on_big].max() < 12
    with pytest.raises(InvalidInputError, match="min_barycentric"):
        sample_surface(scene, 10, seed=0, min_barycentric=0.5)


def test_degenerate_faces_and_removal():
    positions = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0]], dtype=float)
    faces = np.array([[0, 1, 2], [0, 1, 3], [1, 1, 2], [0, 2, 1]])
    mask = degenerate_faces(positions, faces)
    np.testing.assert_array_equal(mask, [False, True, True, False])  # collinear, repeated
    mesh, removed = remove_degenerate(TriangleMesh(positions, faces))
    assert removed == 2 and mesh.n_triangles == 2


def test_duplicate_faces():
    faces = np.array([[0, 1, 2], [1, 2, 0], [3, 4, 5], [5, 4, 3], [6, 7, 8]])
    kept, removed = remove_duplicate_faces(faces)
    # (0,1,2) twice with the same winding keeps one; (3,4,5) both ways is a fin: both go.
    assert removed == 3
    np.testing.assert_array_equal(kept, [[0, 1, 2], [6, 7, 8]])


def test_weld_and_fill_holes_close_an_open_box():
    closed = box((1.0, 2.0, 3.0))
    open_faces = closed.faces[2:]  # drop the two triangles of one side
    positions, faces = weld_vertices(closed.positions, open_faces)
    assert len(positions) == 8
    loops = boundary_loops(faces)
    assert len(loops) == 1 and len(loops[0]) == 4
    positions, faces, filled = fill_holes(positions, faces)
    assert filled == 1
    welded, welded_faces = weld_vertices(positions, faces)
    assert boundary_loops(welded_faces) == []
    volume = np.einsum("ij,ij->i", positions[faces[:, 0]],
                       np.cross(positions[faces[:, 1]], positions[faces[:, 2]])).sum() / 6
    assert np.isclose(volume, 6.0)


def test_grid_plane():
    mesh = grid_plane(3.0, 4, center=(1.0, 0.5, -1.0))
    assert mesh.n_triangles == 32 and mesh.n_vertices == 25
    p = mesh.positions.astype(np.float64)
    f = mesh.faces
    normals = np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]])
    assert np.all(normals[:, 1] > 0) and np.allclose(normals[:, [0, 2]], 0)
    assert np.isclose(mesh.triangle_areas().sum(), 9.0)
    np.testing.assert_allclose(p.min(axis=0), [-0.5, 0.5, -2.5])
    assert mesh.uvs.min() == 0 and mesh.uvs.max() == 1
    with pytest.raises(InvalidInputError):
        grid_plane(1.0, 0)


# --- atlases ----------------------------------------------------------------------------------

def _rasterise(atlas, resolution: int) -> np.ndarray:
    """How many UV triangles cover each texel centre (strictly inside, small tolerance)."""
    coverage = np.zeros((resolution, resolution), dtype=np.int32)
    uv = atlas.uvs.astype(np.float64) * resolution
    for tri in uv[atlas.faces]:
        lo = np.floor(tri.min(axis=0)).astype(int)
        hi = np.ceil(tri.max(axis=0)).astype(int)
        xs = np.arange(max(lo[0], 0), min(hi[0], resolution)) + 0.5
        ys = np.arange(max(lo[1], 0), min(hi[1], resolution)) + 0.5
        if len(xs) == 0 or len(ys) == 0:
            continue
        px, py = np.meshgrid(xs, ys)
        a, b, c = tri
        d = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
        w0 = ((b[0] - px) * (c[1] - py) - (b[1] - py) * (c[0] - px)) / d
        w1 = ((c[0] - px) * (a[1] - py) - (c[1] - py) * (a[0] - px)) / d
        w2 = 1 - w0 - w1
        inside = (w0 > 1e-6) & (w1 > 1e-6) & (w2 > 1e-6)
        coverage[py[inside].astype(int), px[inside].astype(int)] += 1
    return coverage


def test_uv_atlas_is_valid_and_cached(monkeypatch):
    mesh = uv_sphere(radius=1.0, segments=20)
    atlas = uv_atlas(mesh, resolution=256, padding=2)
    assert atlas.faces.shape == mesh.faces.shape
    assert atlas.uvs.min() >= 0 and atlas.uvs.max() <= 1
    # Same faces, same corners: the atlas only splits vertices along seams.
    np.testing.assert_array_equal(mesh.faces, atlas.vertex_map[atlas.faces])
    areas = uv_triangle_areas(atlas)
    assert np.abs(areas).min() > 0.05  # every face covers a non-degenerate UV triangle
    # No fold-overs: inside each chart (connected atlas faces) all UV triangles keep one
    # orientation (xatlas may mirror a whole chart, which is harmless).
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    f = atlas.faces
    n = len(atlas.uvs)
    graph = coo_matrix((np.ones(2 * len(f)), (np.r_[f[:, 0], f[:, 1]], np.r_[f[:, 1], f[:, 2]])),
                       shape=(n, n))
    n_charts, chart_of_vertex = connected_components(graph, directed=False)
    chart = chart_of_vertex[f[:, 0]]
    for c in range(n_charts):
        signs = np.sign(areas[chart == c])
        assert np.all(signs == signs[0])
    coverage = _rasterise(atlas, 256)
    assert coverage.max() == 1  # charts do not overlap
    assert 0.3 < (coverage > 0).mean() <= atlas.utilization + 0.05
    # Second call: served from the cache, xatlas is not run again.
    monkeypatch.setattr(geometry, "_pack", lambda *a, **k: pytest.fail("cache miss"))
    again = uv_atlas(mesh, resolution=256, padding=2)
    np.testing.assert_array_equal(again.uvs, atlas.uvs)


def test_scene_atlas_shared_and_per_object():
    scene = Scene("t", [SceneObject("a", uv_sphere(radius=0.5, segments=12), Material()),
                        SceneObject("b", box((1, 1, 1), center=(2, 0, 0)), Material())])
    shared = scene_atlas(scene, resolution=128, padding=2)
    assert [a.texture for a in shared] == [0, 0]
    both = type(shared[0])(np.concatenate([shared[0].vertex_map, shared[1].vertex_map]),
                           np.concatenate([shared[0].faces, shared[1].faces + len(shared[0].uvs)]),
                           np.concatenate([shared[0].uvs, shared[1].uvs]), 128, 2, 0.0)
    assert _rasterise(both, 128).max() == 1  # objects' charts do not overlap either
    per_object = scene_atlas(scene, resolution=128, padding=2, per_object=True)
    assert [a.texture for a in per_object] == [0, 1]
    for atlas, obj in zip(per_object, scene.objects):
        np.testing.assert_array_equal(obj.mesh.faces, atlas.vertex_map[atlas.faces])
    with pytest.raises(InvalidInputError, match="resolution"):
        scene_atlas(scene, resolution=8)
