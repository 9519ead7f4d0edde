"""prtbench.transport.sdf: exact primitives, smooth Booleans, NumPy ↔ GLSL agreement, sphere tracing,
SDF transfer (analytic occlusion and embree on the marching-cubes mesh), marching cubes,
surface samples and the sphere-traced G-buffer."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from prtbench.api.errors import InvalidInputError
from prtbench.render import sdf_gl
from prtbench.scene.model import Material, View
from prtbench.transport import sdf

RNG = np.random.default_rng(1234)


def _surface(root, bounds=((-3.0, -0.1, -3.0), (3.0, 2.0, 3.0))):
    ids = root.material_ids()
    return sdf.SdfSurface(root, bounds, tuple(Material(name=f"m{i}") for i in range(max(ids) + 1)))


def sphere_over_plane(r: float = 0.5, h: float = 1.0, bounds=((-3.0, -0.1, -3.0), (3.0, 2.0, 3.0))):
    return _surface(sdf.union(sdf.Plane(material=0), sdf.Sphere(r, material=1).translate(0, h, 0)),
                    bounds)


def every_node() -> sdf.SdfNode:
    """A tree using every node type (and several material ids)."""
    parts = [
        sdf.Sphere(0.3, material=1).translate(0.8, 0.5, 0.0),
        sdf.Box((0.2, 0.3, 0.25), material=2).rotate((1, 2, 3), 37.0).translate(-0.7, 0.4, 0.3),
        sdf.RoundedBox((0.3, 0.2, 0.2), 0.05, material=3).translate(0.0, 1.2, -0.6),
        sdf.Capsule((-0.2, 0.2, 0.8), (0.4, 0.9, 0.7), 0.1, material=4),
        sdf.Torus(0.35, 0.08, material=5).rotate((1, 0, 0), 70.0).translate(0.0, 0.6, 0.0),
        sdf.Cylinder(0.15, 0.3, material=6).scale(1.5).translate(-0.9, 0.45, -0.8),
        sdf.Cone(0.25, 0.3, 0.05, material=7).translate(0.9, 0.3, -0.9),
        sdf.Ellipsoid((0.4, 0.15, 0.25), material=8).translate(0.3, 1.5, 0.5),
        sdf.Mirror(sdf.Sphere(0.1, material=9).translate(0.5, 1.9, 0.0), "x"),
        sdf.Round(sdf.Box((0.1, 0.1, 0.1), material=10), 0.05).translate(-0.4, 1.6, 0.2),
    ]
    blob = sdf.union(*parts[:4], k=0.15)
    cut = sdf.subtract(blob, sdf.Sphere(0.25, material=11).translate(0.8, 0.7, 0.2), k=0.05)
    inter = sdf.intersection(parts[4], sdf.Box((1, 0.6, 1), material=12).translate(0, 0.3, 0),
                             k=0.02)
    return sdf.union(sdf.Plane(material=0), cut, inter, *parts[5:])


# --- primitives ---------------------------------------------------------------------------------

def test_sphere_box_plane_are_exact_distances():
    p = RNG.uniform(-2, 2, (4000, 3))
    np.testing.assert_allclose(sdf.Sphere(0.7).evaluate(p), np.linalg.norm(p, axis=1) - 0.7,
                               atol=1e-12)
    half = np.array([0.5, 0.3, 0.8])
    clamped = np.clip(p, -half, half)
    outside = np.linalg.norm(p - clamped, axis=1)
    inside = -np.min(half - np.abs(p), axis=1)  # distance to the nearest face, negative
    expected = np.where(np.all(np.abs(p) <= half, axis=1), inside, outside)
    np.testing.assert_allclose(sdf.Box(tuple(half)).evaluate(p), expected, atol=1e-12)
    n = np.array([1.0, 2.0, -0.5]) / np.linalg.norm([1.0, 2.0, -0.5])
    np.testing.assert_allclose(sdf.Plane(tuple(n * 3), 0.25).evaluate(p), p @ n - 0.25, atol=1e-12)


def _brute_unsigned(surface_points: np.ndarray, queries: np.ndarray) -> np.ndarray:
    from scipy.spatial import cKDTree

    return cKDTree(surface_points).query(queries)[0]


def _cone_profile(h: float, r1: float, r2: float, n: int = 4000) -> np.ndarray:
    """Dense points (3n, 2) on the capped cone's (ρ, y) profile: bottom cap, side, top cap.

    The cone is a solid of revolution, so the 3D distance of a point is the 2D distance of
    (ρ, y) to the profile mirrored about the axis; for ρ ≥ 0 the unmirrored half is nearer.
    """
    return np.concatenate([np.stack([np.linspace(0, r1, n), np.full(n, -h)], 1),
                           np.stack([np.linspace(r1, r2, n), np.linspace(-h, h, n)], 1),
                           np.stack([np.linspace(0, r2, n), np.full(n, h)], 1)])


@pytest.mark.parametrize("shape,kind", [
    (sdf.Capsule((-0.3, -0.2, 0.1), (0.4, 0.5, -0.2), 0.2), "capsule"),
    (sdf.Torus(0.5, 0.15), "torus"),
    (sdf.Cylinder(0.4, 0.3), "cylinder"),
    (sdf.Cone(0.35, 0.45, 0.1), "cone"),
    (sdf.RoundedBox((0.4, 0.3, 0.2), 0.1), "rounded box"),
])
def test_other_primitives_match_closed_forms(shape, kind):
    """Each against an independent formulation: segment/circle/clamp distances or dense samples."""
    p = RNG.uniform(-1.0, 1.0, (3000, 3))
    d = shape.evaluate(p)
    if kind == "capsule":
        a, b = np.array(shape.a), np.array(shape.b)
        t = np.linspace(0, 1, 4001)
        seg = a + t[:, None] * (b - a)
        expected = _brute_unsigned(seg, p) - shape.radius
        np.testing.assert_allclose(d, expected, atol=2e-4)  # segment sampling 2.7e-4 apart
    elif kind == "torus":
        rho = np.hypot(p[:, 0], p[:, 2])
        expected = np.hypot(rho - 0.5, p[:, 1]) - 0.15
        np.testing.assert_allclose(d, expected, atol=1e-12)
    elif kind == "cylinder":
        rho = np.hypot(p[:, 0], p[:, 2])
        q = np.stack([rho, p[:, 1]], 1)
        half = np.array([0.4, 0.3])
        outside = np.linalg.norm(q - np.clip(q, [0, -0.3], half), axis=1)
        inside = -np.minimum(0.4 - rho, 0.3 - np.abs(p[:, 1]))
        expected = np.where((rho <= 0.4) & (np.abs(p[:, 1]) <= 0.3), inside, outside)
        np.testing.assert_allclose(d, expected, atol=1e-12)
    elif kind == "cone":
        h, r1, r2 = 0.35, 0.45, 0.1
        rho = np.hypot(p[:, 0], p[:, 2])
        expected = _brute_unsigned(_cone_profile(h, r1, r2), np.stack([rho, p[:, 1]], 1))
        np.testing.assert_allclose(np.abs(d), expected, atol=1e-4)  # profile spacing 1.8e-4
        inside = (np.abs(p[:, 1]) < h) & (rho < r1 + (r2 - r1) * (p[:, 1] + h) / (2 * h))
        assert np.all((d < 0) == inside)
    else:
        inner = np.array([0.3, 0.2, 0.1])
        core = np.linalg.norm(p - np.clip(p, -inner, inner), axis=1)
        inside_core = -np.min(inner - np.abs(p), axis=1)
        expected = np.where(np.all(np.abs(p) <= inner, 1), inside_core, core) - 0.1
        np.testing.assert_allclose(d, expected, atol=1e-12)


def test_ellipsoid_bound_is_zero_on_surface_and_conservative():
    radii = np.array([0.6, 0.25, 0.4])
    e = sdf.Ellipsoid(tuple(radii))
    u, v = np.meshgrid(np.linspace(0, np.pi, 300), np.linspace(0, 2 * np.pi, 600))
    surface = np.stack([np.sin(u) * np.cos(v), np.cos(u), np.sin(u) * np.sin(v)], -1).reshape(-1, 3)
    surface *= radii
    assert np.abs(e.evaluate(surface)).max() < 1e-12
    p = RNG.uniform(-1, 1, (1500, 3))
    true = _brute_unsigned(surface, p)  # overestimates by <= ~4e-3 (sample spacing 6.3e-3)
    assert np.all(np.abs(e.evaluate(p)) <= true + 4e-3)
    # Conservative but not useless: outside, at least min(r)/max(r) of the distance.
    out = e.evaluate(p) > 0
    assert np.all(e.evaluate(p)[out] >= 0.25 / 0.6 * (true[out] - 4e-3))


def test_transforms_and_mirror():
    p = RNG.uniform(-2, 2, (3000, 3))
    moved = sdf.Sphere(0.4).scale(2.5).translate(0.3, -0.2, 0.5)
    np.testing.assert_allclose(moved.evaluate(p),
                               np.linalg.norm(p - [0.3, -0.2, 0.5], axis=1) - 1.0, atol=1e-12)
    rot = sdf.rotation_matrix((0.3, 1.0, -0.2), 50.0)
    box = sdf.Box((0.5, 0.2, 0.3))
    # d(p) of the rotated box is the box's distance at Rᵀp.
    np.testing.assert_allclose(box.rotate((0.3, 1.0, -0.2), 50.0).evaluate(p),
                               box.evaluate(p @ rot), atol=1e-12)
    child = sdf.Sphere(0.3).translate(0.7, 0.1, 0.0)
    both = sdf.union(child, sdf.Sphere(0.3).translate(-0.7, 0.1, 0.0))
    np.testing.assert_allclose(sdf.Mirror(child, "x").evaluate(p), both.evaluate(p), atol=1e-12)


def test_smooth_union_bounds_and_material():
    a = sdf.Sphere(0.5, material=1)
    b = sdf.Box((0.3, 0.3, 0.3), material=2).translate(0.6, 0.0, 0.0)
    k = 0.2
    p = RNG.uniform(-1.5, 1.5, (20000, 3))
    da, db = a.evaluate(p), b.evaluate(p)
    smooth, ids = sdf.union(a, b, k=k).evaluate_with_material(p)
    hard = np.minimum(da, db)
    assert np.all(smooth <= hard + 1e-15)
    assert np.all(smooth >= hard - k / 4 - 1e-15)
    far = np.abs(da - db) >= k
    np.testing.assert_array_equal(smooth[far], hard[far])
    # The blend reaches its full depth k/4 where the operands are equal.
    equal = np.abs(da - db) < 1e-3
    assert equal.sum() > 10
    np.testing.assert_allclose(smooth[equal], hard[equal] - k / 4, atol=1e-3)
    np.testing.assert_array_equal(ids, np.where(da <= db, 1, 2))
    inter = sdf.intersection(a, b, k=k).evaluate(p)
    assert np.all(inter >= np.maximum(da, db)) and np.all(inter <= np.maximum(da, db) + k / 4)
    sub, sub_ids = sdf.subtract(a, b, k=k).evaluate_with_material(p)
    assert np.all(sub >= np.maximum(da, -db)) and np.all(sub_ids == 1)


@pytest.mark.parametrize("which", ["every-node", "sdf-car", "sdf-monster", "sdf-fish",
                                   "sdf-rabbit"])
def test_lipschitz_at_most_one(which):
    """|d(x) − d(y)| ≤ |x − y| on random pairs, near and far (sphere tracing relies on it)."""
    from scenes import sdf_scenes

    root = every_node() if which == "every-node" else {
        "sdf-car": sdf_scenes.car_shape, "sdf-monster": sdf_scenes.monster_shape,
        "sdf-fish": sdf_scenes.fish_shape, "sdf-rabbit": sdf_scenes.rabbit_shape}[which]()
    x = RNG.uniform([-2, -0.1, -2], [2, 2, 2], (20000, 3))
    for scale in (1.0, 0.05, 0.002):
        y = x + RNG.normal(0, scale, x.shape)
        ratio = np.abs(root.evaluate(x) - root.evaluate(y)) / np.linalg.norm(x - y, axis=1)
        assert ratio.max() <= 1.0 + 1e-9, (scale, ratio.max())


def test_invalid_parameters_raise():
    with pytest.raises(InvalidInputError, match="sphere radius"):
        sdf.Sphere(-1.0)
    with pytest.raises(InvalidInputError, match="proper rotation"):
        sdf.Rotate(sdf.Sphere(1.0), ((1, 0, 0), (0, 1, 0), (0, 0, -1)))
    with pytest.raises(InvalidInputError, match="material ids"):
        sdf.SdfSurface(sdf.Sphere(1.0, material=2), ((-1, -1, -1), (1, 1, 1)), (Material(),))
    with pytest.raises(InvalidInputError, match="accepted: numpy, gl"):
        sdf.SdfTracer(sphere_over_plane(), backend="cuda")
    with pytest.raises(InvalidInputError, match=r"\(N, 3\)"):
        sdf.Sphere(1.0).evaluate(np.zeros((4, 2)))
    with pytest.raises(InvalidInputError, match="not an SDF scene"):
        sdf.as_surface(object())


def test_spec_describes_the_tree():
    a = every_node()
    spec = a.spec()
    assert spec["type"] == "SmoothUnion" and len(spec["children"]) == 2
    from prtbench.api.cache import content_key

    assert content_key(a.spec()) == content_key(every_node().spec())
    other = sdf.union(sdf.Plane(material=0), sdf.Sphere(0.31, material=1))
    assert content_key(other.spec()) != content_key(
        sdf.union(sdf.Plane(material=0), sdf.Sphere(0.3, material=1)).spec())


# --- GLSL ---------------------------------------------------------------------------------------

def test_glsl_matches_numpy_on_random_points():
    root = every_node()
    surface = _surface(root)
    p = RNG.uniform([-1.5, -0.2, -1.5], [1.5, 2.2, 1.5], (30000, 3))
    d, ids = surface.evaluate_with_material(p)
    d_gl, ids_gl, n_gl = sdf_gl.evaluate_gl(surface, p)
    np.testing.assert_allclose(d_gl, d, atol=1e-4)
    # Material ids differ only where two operands tie to float32 rounding.
    assert np.mean(ids_gl == ids) > 0.999
    # Normals (GLSL tetrahedral vs NumPy central differences) agree away from creases.
    n = surface.normal(p)
    agree = np.einsum("ij,ij->i", n, n_gl) > 0.999
    assert agree.mean() > 0.99


def test_glsl_sources_define_the_trace_api():
    text = sphere_over_plane().glsl()
    for needle in ("float scene_sdf(vec3 p)", "int scene_material(vec3 p)",
                   "float scene_sdf_material(vec3 p, out int material)", "#define SDF_BOUNDS_LO",
                   '#include "sdf_primitives.glsl"'):
        assert needle in text
    from prtbench.render.gl import shader_dir

    trace = (shader_dir() / "sdf_trace.glsl").read_text()
    assert "bool trace(vec3 ro, vec3 rd, out vec3 p, out vec3 n, out int material)" in trace
    assert not (shader_dir() / "scene_sdf.glsl").exists()  # generated, never committed


def test_load_program_rejects_bad_virtual_names():
    from prtbench.render import gl

    with pytest.raises(InvalidInputError, match="plain file name"):
        gl.load_program(gl.create_context(), "sdf_fullscreen.vert", "sdf_gbuffer.frag",
                        sources={"../x.glsl": "// nothing"})


# --- sphere tracing -----------------------------------------------------------------------------

def test_primary_ray_hits_on_a_sphere_match_ray_sphere_intersection():
    r, c = 0.6, np.array([0.2, 0.8, -0.1])
    surface = _surface(sdf.Sphere(r, material=0).translate(*c), ((-1, -0.5, -1), (1.5, 2, 1)))
    view = View(eye=(1.2, 1.6, 2.5), target=tuple(c))
    o, d = view.primary_rays(64, 48)
    o, d = o.reshape(-1, 3), d.reshape(-1, 3)
    hits = sdf.first_hit(surface, o, d)
    # Analytic: |o + t d − c|² = r².
    oc = o - c
    b = np.einsum("ij,ij->i", oc, d)
    disc = b * b - (np.einsum("ij,ij->i", oc, oc) - r * r)
    analytic_hit = disc > 0
    t_true = -b - np.sqrt(np.maximum(disc, 0))
    eps = surface.hit_eps
    # Rays passing within eps of the silhouette may hit the eps-inflated sphere.
    clear = np.abs(np.sqrt(np.maximum(np.einsum("ij,ij->i", oc, oc) - b * b, 0)) - r) > 2 * eps
    np.testing.assert_array_equal(hits.hit[clear], analytic_hit[clear])
    both = hits.hit & analytic_hit
    cos = -np.einsum("ij,ij->i", d, (o + t_true[:, None] * d - c) / r)
    ok = both & (cos > 0.05)
    assert ok.sum() > 300
    # Tracing stops where d < eps: at most eps/cos before the surface, never behind it.
    err = t_true[ok] - hits.t[ok]
    assert np.all(err >= -1e-9) and np.all(err <= eps / cos[ok] + 1e-9)
    radial = hits.positions[ok] - c
    np.testing.assert_allclose(hits.normals[ok], radial / np.linalg.norm(radial, axis=1)[:, None],
                               atol=1e-6)


def test_occlusion_of_thin_and_grazing_geometry():
    """Over-relaxed steps must not jump through a thin slab, and rays grazing a plane miss."""
    slab = _surface(sdf.Box((0.5, 0.002, 0.5)).translate(0, 1.0, 0), ((-2, -0.5, -2), (2, 2, 2)))
    o = np.tile([0.0, 0.0, 0.0], (400, 1)) + RNG.uniform(-0.3, 0.3, (400, 3)) * [1, 0, 1]
    d = np.tile([0.0, 1.0, 0.0], (400, 1))
    assert sdf.occluded(slab, o, d).all()
    plane = _surface(sdf.Plane(), ((-2, -0.5, -2), (2, 2, 2)))
    low = np.stack([np.ones(200), np.linspace(1e-3, 0.05, 200), np.zeros(200)], 1)
    res = sdf.march(plane, np.tile([-1.9, 0.01, 0.0], (200, 1)), low)
    assert not res.hit.any() and res.exhausted == 0


def test_transfer_under_a_sphere_over_a_plane_is_analytic():
    """√(4π)·T_0 below a sphere (radius r, centre height h) is π(1 − (r/h)²)."""
    r, h = 0.5, 1.0
    surface = sphere_over_plane(r, h)
    # One point per ray pattern (transfer.N_PATTERNS): with the sphere straight above, a
    # point's spin about its normal changes nothing, so only the 16 patterns are independent.
    n = 16
    points, normals = np.zeros((n, 3)), np.tile([0.0, 1.0, 0.0], (n, 1))
    t = sdf.compute_sdf_transfer(surface, points, normals, bands=3, rays_per_point=4096, seed=3,
                                 progress=False)
    values = math.sqrt(4 * math.pi) * t[:, 0].astype(np.float64)
    mean, stderr = values.mean(), values.std(ddof=1) / math.sqrt(n)
    # Two known tolerances of the tracer: rays start offset_origins' 1e-4·diagonal above the
    # ground (δ), and passing within the hit threshold ε of the sphere counts as a hit.
    delta, eps = 1e-4 * surface.diagonal, surface.hit_eps
    expected = math.pi * (1 - ((r + eps) / (h - delta)) ** 2)
    assert abs(mean - expected) < 3 * stderr, (mean, expected, stderr)
    assert abs(mean - math.pi * (1 - (r / h) ** 2)) < 1.5e-3 * math.pi  # 0.15 % all told


def test_sdf_transfer_uses_the_mesh_estimator_exactly_when_nothing_occludes():
    """On an unoccluded plane the SDF transfer equals compute_transfer's bit for bit (same rays,
    patterns and rotations), for any band count."""
    from prtbench.scene.geometry import grid_plane
    from prtbench.scene.model import Scene, SceneObject
    from prtbench.transport.transfer import compute_transfer

    surface = _surface(sdf.Plane(material=0), ((-2, -0.1, -2), (2, 1, 2)))
    scene = Scene("plane-test", [SceneObject("ground", grid_plane(4.0), Material())])
    p = np.concatenate([RNG.uniform(-1.5, 1.5, (300, 2))[:, [0]], np.zeros((300, 1)),
                        RNG.uniform(-1.5, 1.5, (300, 1))], axis=1)
    n = np.tile([0.0, 1.0, 0.0], (300, 1))
    mesh_t = compute_transfer(scene, p, n, bands=4, rays_per_point=64, seed=9, progress=False)
    sdf_t = sdf.compute_sdf_transfer(surface, p, n, bands=4, rays_per_point=64, seed=9,
                                     progress=False)
    np.testing.assert_allclose(sdf_t, mesh_t, atol=1e-6)


def _blob_scene(resolution: int):
    from prtbench.scene.model import Scene

    root = sdf.union(
        sdf.Plane(material=0),
        sdf.union(sdf.Sphere(0.45, material=1).translate(0.0, 0.55, 0.0),
                  sdf.Torus(0.4, 0.1, material=1).rotate((1, 0, 0), 60).translate(0.5, 0.3, 0.3),
                  sdf.Capsule((-0.6, 0.1, -0.4), (-0.3, 0.9, 0.2), 0.12, material=1), k=0.15))
    surface = sdf.SdfSurface(root, ((-2, -0.05, -2), (2, 1.3, 2)),
                             (Material(name="ground"), Material(name="blob")))
    scene = Scene("blob", sdf.sdf_scene_objects(surface, resolution=resolution))
    scene.sdf = surface
    return scene


def test_sdf_transfer_agrees_with_embree_on_the_marching_cubes_mesh():
    """Same rays (seed) traced against the SDF and against its marching-cubes mesh (embree).

    The two differ only where the mesh and the SDF do: the mesh's chords lie up to h²κ/8 off
    the surface (h = 4/192 ≈ 0.021 cells, curvature radius ≥ 0.1 here: ≤ 5e-4, comparable to
    the 1e-4·diagonal origin offset), so points in concave creases can start just behind the
    mesh, and silhouettes move by as much. Measured (T_0 ≈ 0.75): mean |ΔT_0| 0.0014 (0.19 %),
    99th percentile 0.010, mean ΔT_0 +0.0008, RMS over all coefficients 0.015 (a few crease
    points, max |ΔT_0| 0.57); a systematic tracer bias would show in the mean of ΔT_0.
    """
    from prtbench.transport.transfer import compute_transfer

    scene = _blob_scene(192)
    points, normals = sdf.sample_sdf_surface(scene, 1500, seed=4)
    kwargs = dict(bands=3, rays_per_point=256, seed=5, progress=False)
    t_sdf = sdf.compute_sdf_transfer(scene, points, normals, backend="gl", **kwargs)
    t_mesh = compute_transfer(scene, points, normals, **kwargs)
    diff = (t_sdf - t_mesh).astype(np.float64)
    scale = float(np.abs(t_mesh[:, 0]).mean())
    assert np.abs(diff[:, 0]).mean() < 0.005 * scale
    assert np.percentile(np.abs(diff[:, 0]), 99) < 0.05 * scale
    assert abs(diff[:, 0].mean()) < 0.004 * scale
    assert np.sqrt((diff ** 2).mean()) < 0.035 * scale


def test_gl_and_numpy_occlusion_agree():
    scene = _blob_scene(64)
    points, normals = sdf.sample_sdf_surface(scene, 400, seed=6)
    kwargs = dict(bands=3, rays_per_point=128, seed=2, progress=False, use_cache=False)
    t_np = sdf.compute_sdf_transfer(scene, points, normals, backend="numpy", **kwargs)
    t_gl = sdf.compute_sdf_transfer(scene, points, normals, backend="gl", **kwargs)
    # float32 vs float64 marching flips only rays grazing a surface within rounding.
    assert np.abs(t_gl - t_np).max() < 0.1
    assert np.abs(t_gl - t_np).mean() < 1e-3


# --- marching cubes and samples -----------------------------------------------------------------

def test_marching_cubes_mesh_lies_on_the_sdf_and_faces_outward():
    surface = sphere_over_plane(bounds=((-1.5, -0.1, -1.5), (1.5, 1.8, 1.5)))
    mesh = sdf.marching_cubes_mesh(surface, resolution=96)
    p = mesh.positions.astype(np.float64)
    size = surface.diagonal
    assert np.abs(surface.evaluate(p)).max() < 1e-4 * size
    np.testing.assert_allclose(np.linalg.norm(mesh.normals, axis=1), 1.0, atol=1e-5)
    np.testing.assert_allclose(mesh.normals, surface.normal(p), atol=1e-4)
    f = mesh.faces
    geometric = np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]])
    agree = np.einsum("ij,ij->i", geometric, mesh.normals[f].sum(axis=1)) > 0
    assert agree.mean() > 0.999
    # The sphere part: area 4πr² (inscribed mesh, ~h²/r² smaller).
    centroid = p[f].mean(axis=1)
    on_sphere = np.linalg.norm(centroid - [0, 1.0, 0], axis=1) < 0.55
    area = 0.5 * np.linalg.norm(geometric[on_sphere], axis=1).sum()
    assert abs(area - 4 * math.pi * 0.25) < 0.005 * 4 * math.pi * 0.25


def test_narrow_band_grid_gives_the_full_evaluation_mesh():
    from skimage import measure

    surface = _surface(every_node(), ((-1.5, -0.1, -1.5), (1.5, 2.2, 1.5)))
    band, axes = sdf.sdf_grid(surface, resolution=64)
    full, _ = sdf.sdf_grid(surface, resolution=64, narrow_band=False)
    assert np.all(np.sign(band) == np.sign(full))
    v1, f1, _, _ = measure.marching_cubes(band, 0.0)
    v2, f2, _, _ = measure.marching_cubes(full, 0.0)
    np.testing.assert_array_equal(f1, f2)
    np.testing.assert_allclose(v1, v2, atol=1e-6)
    # On a simpler surface at a finer grid the band skips most of the nodes.
    simple = sphere_over_plane(bounds=((-1.5, -0.1, -1.5), (1.5, 1.8, 1.5)))
    band, _ = sdf.sdf_grid(simple, resolution=128)
    full, _ = sdf.sdf_grid(simple, resolution=128, narrow_band=False)
    assert np.all(np.sign(band) == np.sign(full))
    assert np.mean(band == full) < 0.35


def test_surface_samples_are_on_the_sdf_and_area_uniform():
    surface = sphere_over_plane(bounds=((-1.5, -0.1, -1.5), (1.5, 1.8, 1.5)))
    points, normals = sdf.sample_sdf_surface(surface, 20000, seed=2, resolution=96)
    assert np.abs(surface.evaluate(points)).max() < 1e-7 * surface.diagonal
    on_sphere = np.linalg.norm(points - [0, 1.0, 0], axis=1) < 0.51
    np.testing.assert_allclose(normals[on_sphere], (points[on_sphere] - [0, 1, 0]) / 0.5,
                               atol=1e-5)
    np.testing.assert_allclose(normals[~on_sphere], np.tile([0, 1.0, 0], ((~on_sphere).sum(), 1)),
                               atol=1e-6)
    sphere_area, plane_area = math.pi, 9.0  # 4π·0.25 and the 3 × 3 ground
    expected = sphere_area / (sphere_area + plane_area)
    sd = math.sqrt(expected * (1 - expected) / len(points))
    assert abs(on_sphere.mean() - expected) < 4 * sd + 0.003  # + mesh area bias


def test_split_by_material_indexes_objects_by_id():
    scene = _blob_scene(64)
    assert [o.name for o in scene.objects] == ["ground", "blob"]
    for k, obj in enumerate(scene.objects):
        assert obj.material is scene.sdf.materials[k]
        c = obj.mesh.positions[obj.mesh.faces].mean(axis=1).astype(np.float64)
        assert np.all(scene.sdf.material_at(c) == k)


# --- G-buffer -----------------------------------------------------------------------------------

def test_gl_gbuffer_matches_numpy_sphere_tracing_of_view_primary_rays():
    from prtbench.render import gl

    scene = _blob_scene(64)
    view = View(eye=(2.2, 1.6, 2.8), target=(0.0, 0.4, 0.0), fov_y=40.0)
    w, h = 80, 60
    g = sdf_gl.sdf_gbuffer(gl.create_context(), scene, view, w, h)
    o, d = view.primary_rays(w, h)
    hits = sdf.first_hit(scene, o.reshape(-1, 3), d.reshape(-1, 3))
    mask = hits.hit.reshape(h, w)
    assert 0.3 < g.mask.mean() < 0.95
    assert np.mean(mask == g.mask) > 0.998  # silhouette pixels may differ by rounding
    both = mask & g.mask
    size = scene.sdf.diagonal
    err = np.linalg.norm(hits.positions.reshape(h, w, 3)[both] - g.positions[both], axis=1)
    assert err.max() < 1e-3 * size, err.max()
    cos = np.einsum("ij,ij->i", hits.normals.reshape(h, w, 3)[both], g.normals[both])
    assert np.mean(cos > 0.999) > 0.99
    np.testing.assert_array_equal(g.material[both], hits.material.reshape(h, w)[both])
    assert np.all(g.material[~g.mask] == -1) and np.all(g.positions[~g.mask] == 0)
    # Row 0 is the top: the ground (material 0) fills the bottom rows, not the top ones.
    assert (g.material[-5:] == 0).mean() > (g.material[:5] == 0).mean()


CUSTOM_FRAG = """#version 430
// What a continuous method's fragment shader looks like: camera ray, trace, shade.
#include "sdf_camera.glsl"
#include "sdf_trace.glsl"
layout(location = 0) out vec4 color;
void main() {
    vec3 ro, rd, p, n;
    int material;
    primary_ray(gl_FragCoord.xy, ro, rd);
    if (!trace(ro, rd, p, n, material)) {
        color = vec4(0.0);
        return;
    }
    color = vec4(max(n.y, 0.0), float(material), p.y, 1.0);
}
"""


def test_a_custom_shader_includes_the_trace_api_and_a_pass_is_reusable(tmp_path):
    from prtbench.render import gl

    (tmp_path / "custom_sdf.frag").write_text(CUSTOM_FRAG)
    ctx = gl.create_context()
    scene = _blob_scene(64)
    w, h = 48, 36
    program = sdf_gl.load_sdf_program(ctx, scene, "custom_sdf.frag", search_path=[str(tmp_path)])
    vao = sdf_gl.fullscreen_vao(ctx, program)
    target = gl.RenderTarget(ctx, w, h)
    gbuffer = sdf_gl.GBufferPass(ctx, scene, w, h)
    try:
        for view in (View(eye=(2.0, 1.5, 2.5), target=(0, 0.4, 0)),
                     View(eye=(-2.5, 1.0, 1.0), target=(0, 0.3, 0), fov_y=30.0)):
            sdf_gl.bind_camera(program, view, w, h)
            target.use()
            target.clear()
            vao.render(gl.moderngl.TRIANGLES, vertices=3)
            image = target.read()
            g = gbuffer.render(view)
            np.testing.assert_array_equal(image[..., 3] > 0, g.mask)
            hit = g.mask
            np.testing.assert_allclose(image[..., 0][hit], np.maximum(g.normals[..., 1], 0)[hit],
                                       atol=1e-6)
            np.testing.assert_array_equal(image[..., 1][hit], g.material[hit])
            np.testing.assert_allclose(image[..., 2][hit], g.positions[..., 1][hit], atol=1e-6)
    finally:
        gbuffer.release()
        target.release()
        vao.release()
        program.release()


@dataclass(frozen=True, eq=False)
class _Slowed(sdf.SdfNode):
    """``child``'s distance times ``factor`` < 1: a valid bound that grows slower than distance,
    like a fitted neural SDF where |∇d| ≪ 1."""

    child: sdf.SdfNode
    factor: float

    @property
    def children(self):
        return (self.child,)

    def _eval(self, p, need_material):
        d, m = self.child._eval(p, need_material)
        return d * self.factor, m

    def _spec(self):
        return {"factor": self.factor}


def test_slow_sdf_does_not_shadow_itself():
    # A convex sphere occludes nothing of its own upper hemisphere of directions, whatever the
    # SDF's gradient: T_0 = ∫ Y_0 max(n·ω, 0) dω = √π/2 at its top. With |∇d| = 0.1 the usual
    # 1e-4·diagonal start offset reads d = 0.4·hit_eps, inside the hit shell.
    slow = _Slowed(sdf.Sphere(radius=0.5), 0.1)
    surface = sdf.SdfSurface(slow, ((-1.0, -1.0, -1.0), (1.0, 1.0, 1.0)), (Material(),))
    top, up = np.array([[0.0, 0.0, 0.5]]), np.array([[0.0, 0.0, 1.0]])
    origin = sdf.surface_origins(surface, top, up)
    assert surface.evaluate(origin)[0] >= sdf.CLEARANCE * surface.hit_eps
    transfer = sdf.compute_sdf_transfer(surface, top, up, bands=2, rays_per_point=256,
                                        progress=False, use_cache=False)
    assert transfer[0, 0] == pytest.approx(math.sqrt(math.pi) / 2, rel=1e-3)
