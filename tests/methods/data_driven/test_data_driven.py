"""Data-driven PRT (Belcour et al. 2022): analytic pieces, bake vs Mitsuba, GL vs numpy, runner."""

from __future__ import annotations

import math

import numpy as np
import pytest

import methods.data_driven  # noqa: F401 - registers the method
from methods.data_driven import basis as basis_mod
from methods.data_driven.families import sample_family
from methods.data_driven.lights import (
    DirectionalLight,
    PointLight,
    SpotLight,
    median_cut,
    rotate_environment,
)
from methods.data_driven.measurement import eliminate, hull_mesh, measurement_points
from prtbench.api.errors import InvalidInputError, UnknownNameError
from prtbench.api.method import METHODS, load_or_precompute
from prtbench.scene.geometry import grid_plane, sample_surface
from prtbench.scene.model import Material, Scene, SceneObject, Trajectory, View
from prtbench.scene.registry import get_scene
from prtbench.transport.lights import get_light

# --- measurement points --------------------------------------------------------------------

def test_sample_elimination_spreads_points_as_blue_noise():
    plane = grid_plane(1.0, 1)
    dense = sample_surface(plane, 1000, seed=3)
    keep = eliminate(dense.points, dense.normals, 200, area=1.0)
    assert len(keep) == 200 and len(np.unique(keep)) == 200

    def min_distance(points):
        from scipy.spatial import cKDTree

        d, _ = cKDTree(points).query(points, k=2)
        return d[:, 1].min()

    r_max = math.sqrt(1.0 / (2 * math.sqrt(3) * 200))
    random_subset = dense.points[np.random.default_rng(0).choice(1000, 200, replace=False)]
    # Yuksel reports ~0.75·r_max minimum spacing for 5x elimination; random subsets are far closer.
    assert min_distance(dense.points[keep]) > 0.6 * r_max
    assert min_distance(random_subset) < 0.3 * r_max


def test_opposite_sides_of_a_wall_do_not_repel():
    top = grid_plane(1.0, 1)
    bottom_pos = top.positions.copy()
    bottom_pos[:, 1] -= 1e-3
    pts_top = sample_surface(top, 500, seed=1)
    pts = np.concatenate([pts_top.points, pts_top.points + [0, -1e-3, 0]])
    nrm = np.concatenate([pts_top.normals, -pts_top.normals])
    keep = eliminate(pts, nrm, 200, area=2.0)
    assert abs(int((keep < 500).sum()) - 100) <= 15  # half on each side


def test_hull_and_supersampled_points():
    scene = get_scene("sphere-over-plane", radius=0.5, height=1.0)
    hull = hull_mesh(scene)
    mp = measurement_points(scene, 32, placement="hull", supersample=4, seed=0)
    assert mp.points.shape == (32, 4, 3) and np.all(mp.albedo == 1.0)
    # Every hull point lies on the hull: no hull plane has it strictly outside.
    p = hull.positions[hull.faces]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    offsets = np.einsum("fk,nk->nf", n, mp.points[:, 0]) - np.einsum("fk,fk->f", n, p[:, 0])
    assert offsets.max() < 1e-4
    surface = measurement_points(scene, 32, placement="surface", supersample=3, seed=0)
    # Sub-points are the nearest dense samples: closer to their point than the point spacing.
    spread = np.linalg.norm(surface.points[:, 1:] - surface.points[:, :1], axis=-1)
    assert spread.max() < 0.5 * scene.diagonal()
    with pytest.raises(UnknownNameError):
        measurement_points(scene, 8, placement="sphere")


# --- lights ---------------------------------------------------------------------------------

def test_spot_falloff_is_mitsubas_linear_ramp():
    spot = SpotLight((0, 0, 0), (0, 0, 1), cutoff_deg=40.0, beam_deg=20.0)
    angles = np.radians([0.0, 20.0, 30.0, 39.9, 40.0, 60.0])
    dirs = np.stack([np.sin(angles), np.zeros_like(angles), np.cos(angles)], axis=1)
    assert np.allclose(spot.falloff(dirs), [1.0, 1.0, 0.5, 0.005, 0.0, 0.0], atol=1e-3)
    with pytest.raises(InvalidInputError):
        SpotLight((0, 0, 0), (0, 0, 1), cutoff_deg=20.0, beam_deg=30.0)


def test_median_cut_conserves_power_and_finds_the_sun():
    for name in ("sky", "sun", "white"):
        light = get_light(name)
        lights = median_cut(light, 16)
        power = np.sum([l.irradiance for l in lights], axis=0)
        assert np.allclose(power, light.total_power(), rtol=2e-3), name
    from scenes.lights import SUN_DIRECTION

    lights = median_cut(get_light("sun"), 32)
    near = sum(l.irradiance[0] for l in lights
               if np.dot(l.to_light, SUN_DIRECTION) > math.cos(math.radians(2.0)))
    # The disc holds π of the map's π + 0.08π: that share of the power sits within 2° of it.
    assert abs(near / sum(l.irradiance[0] for l in lights) - 1.0 / 1.08) < 0.01


def test_rotating_an_environment_is_a_rotation_about_y():
    light = get_light("sun")
    turned = rotate_environment(light, light.width // 4)  # 90° about +Y
    before, after = light.brightest_direction(), turned.brightest_direction()
    assert abs(before[1] - after[1]) < 1e-9
    assert abs(np.dot(before[[0, 2]], after[[0, 2]])) < 0.05  # the azimuth moved by 90°


def test_families_are_seeded_and_lights_see_their_anchor():
    scene = get_scene("cornell")
    a = sample_family(scene, "spot", 6, seed=1)
    b = sample_family(scene, "spot", 6, seed=1)
    assert [l.position for l in a] == [l.position for l in b]
    lo, hi = scene.bounds()
    assert all(np.all(np.asarray(l.position) >= lo) and np.all(np.asarray(l.position) <= hi)
               for l in a)
    with pytest.raises(UnknownNameError):
        sample_family(scene, "area", 2, seed=0)


# --- basis and transfer ---------------------------------------------------------------------

def _synthetic(n_examples=40, points=12, texels=200, rank=5, seed=0):
    rng = np.random.default_rng(seed)
    modes = rng.normal(size=(texels, rank))
    mixing = rng.normal(size=(rank, points))
    x = np.abs(rng.normal(size=(points, n_examples)))
    return x, modes @ (mixing @ x), modes, mixing


def test_eigenfaces_basis_equals_the_svd_of_the_centred_data():
    x, y, _, _ = _synthetic(n_examples=30, points=40, rank=8)
    fitted = basis_mod.fit(x, y, count=6, ridge=0.0)
    norms = np.linalg.norm(x, axis=0)
    normalised = y / norms
    assert np.allclose(fitted.mean, normalised.mean(axis=1))
    left, sigma, _ = np.linalg.svd(normalised - fitted.mean[:, None], full_matrices=False)
    # The N×N Gram route gives the leading left singular vectors (up to sign), orthonormal.
    overlap = np.abs(left[:, :5].T @ fitted.vectors)
    assert np.allclose(overlap, np.eye(5), atol=1e-8)
    assert np.allclose(fitted.eigenvalues[:5], sigma[:5] ** 2)
    assert fitted.count == 6 and fitted.transfer.shape == (1, 5, 40)
    # P ≥ N and λ = 0: the transfer maps every training input to its coefficients C = Uᵀ(ỹ − μ),
    # so the fit reproduces |x| (μ + U Uᵀ (ỹ − μ)) for every training example.
    pred = fitted.reconstruct(fitted.coefficients(x))
    centred = normalised - fitted.mean[:, None]
    expected = (fitted.mean[:, None] + fitted.vectors @ (fitted.vectors.T @ centred)) * norms
    assert np.allclose(pred, expected, rtol=1e-6, atol=1e-8 * np.abs(y).max())


def test_rank_deficient_data_gives_finite_output():
    x, y, _, _ = _synthetic(n_examples=20, points=30)
    # Duplicated measurement points, repeated configurations and all-dark configurations: the
    # Gram matrix D̃ᵀD̃ is singular; λ = 0 is the plain Moore–Penrose pseudo-inverse.
    x_bad = np.concatenate([x, x[:6]], axis=0)
    x_bad = np.concatenate([x_bad, x_bad[:, :5], np.zeros((36, 4))], axis=1)
    y_bad = np.concatenate([y, y[:, :5], np.zeros((200, 4))], axis=1)
    test = np.abs(np.random.default_rng(5).normal(size=(30, 3)))
    test = np.concatenate([test, test[:6]], axis=0)
    outs = {}
    for ridge in (0.0, 1e-10, 1e-3):
        fitted = basis_mod.fit(x_bad, y_bad, count=16, ridge=ridge)
        assert np.all(np.isfinite(fitted.transfer)) and np.all(np.isfinite(fitted.vectors))
        assert fitted.examples == 25  # the dark ones are dropped
        outs[ridge] = fitted.reconstruct(fitted.coefficients(test))
        assert np.all(np.isfinite(outs[ridge]))
        zero = fitted.reconstruct(fitted.coefficients(np.zeros((36, 2))))
        assert np.all(zero == 0.0)
    # The pseudo-inverse is the λ → 0 limit of the ridge solution.
    assert np.allclose(outs[0.0], outs[1e-10], rtol=1e-4, atol=1e-6 * np.abs(outs[0.0]).max())
    dark = basis_mod.fit(np.zeros((5, 4)), np.zeros((9, 4)), count=4, ridge=0.0)
    assert dark.examples == 0 and np.all(dark.reconstruct(dark.coefficients(np.ones((5, 1)))) == 0)


def test_layouts_and_gamma_reproduce_training_examples():
    rng = np.random.default_rng(4)
    direct = np.abs(rng.normal(size=(6, 24, 3)))  # P ≥ examples: independent inputs
    indirect = np.abs(rng.normal(size=(6, 30, 3)))
    for layout, gamma, count in (("mono", 1.0, 19), ("interleaved", 1.0, 7), ("mono", 2.2, 19)):
        x, y = basis_mod.to_examples(direct, indirect, layout=layout)
        fitted = basis_mod.fit(basis_mod.encode(x, gamma), basis_mod.encode(y, gamma),
                               count=count, ridge=0.0, layout=layout, gamma=gamma)
        # As many elements as examples (+ mean) and an exact interpolating transfer.
        assert np.allclose(basis_mod.predict(fitted, direct), indirect, rtol=1e-5, atol=1e-6)
        assert np.allclose(basis_mod.projected(fitted, indirect), indirect, atol=1e-6)


def test_mono_layout_needs_a_transfer_matrix_per_channel():
    # White light on white measurement points (x_R = x_G = x_B) bouncing onto coloured
    # receivers: indirect = albedo_c(t) · G x, different per channel for the same input. One
    # shared matrix maps equal inputs to equal outputs and cannot tell the channels apart;
    # the paper's three matrices (§5.2, Fig. 5) can. Held-out relative RMSE measured: 0.38
    # shared, 0.055 per channel (what remains is the mean's affine offset, not the colour).
    rng = np.random.default_rng(3)
    points, texels = 12, 50
    transport = np.abs(rng.normal(size=(texels, points)))
    albedo = rng.uniform(0.1, 0.9, size=(texels, 3))

    def configurations(n, seed):
        white = np.abs(np.random.default_rng(seed).normal(size=(n, points, 1))) * np.ones(3)
        return white, np.einsum("tp,npc->ntc", transport, white) * albedo

    direct, indirect = configurations(60, 1)
    test_direct, test_indirect = configurations(10, 2)
    x, y = basis_mod.to_examples(direct, indirect, layout="mono")
    error = {}
    for channels in (1, 3):
        fitted = basis_mod.fit(x, y, count=40, ridge=0.0, layout="mono", channels=channels)
        assert fitted.transfer.shape == (channels, 39, points)
        miss = basis_mod.predict(fitted, test_direct) - test_indirect
        error[channels] = np.sqrt(np.mean(miss ** 2) / np.mean(test_indirect ** 2))
    assert error[3] < 0.1 and error[1] > 0.3, error
    with pytest.raises(InvalidInputError, match="multiple of the channel count"):
        basis_mod.fit(x[:, :-1], y[:, :-1], count=4, ridge=0.0, channels=3)


# --- shading: GL fake G-buffer against ray tracing ------------------------------------------

def _config(**overrides):
    cls = METHODS.get("data-driven")
    return cls.make_config(overrides, profile="smoke")


def test_point_light_over_a_plane_is_analytic():
    from methods.data_driven.dataset import measure_direct
    from methods.data_driven.measurement import MeasurementPoints

    plane = grid_plane(2.0, 1)
    scene = Scene("plane", [SceneObject("plane", plane, Material(kd=(0.5, 0.5, 0.5)))],
                  trajectory=Trajectory((View((0, 2, 2), (0, 0, 0)),)))
    xz = np.random.default_rng(1).uniform(-0.9, 0.9, size=(50, 2))
    pts = np.stack([xz[:, 0], np.zeros(50), xz[:, 1]], axis=1)
    mp = MeasurementPoints(pts[:, None].astype(np.float32),
                           np.tile([0, 1, 0], (50, 1, 1)).astype(np.float32),
                           np.full((50, 1, 3), 0.5, np.float32))
    light = PointLight((0.1, 0.8, -0.2), (2.0, 1.0, 0.5))
    x = measure_direct(scene, mp, _config(), [light])[0]
    d = np.asarray(light.position) - pts
    dist = np.linalg.norm(d, axis=1)
    expected = 0.5 / math.pi * np.outer(d[:, 1] / dist**3, light.intensity)
    assert np.allclose(x, expected, rtol=1e-4)


def test_gl_direct_vector_matches_ray_traced_shadows():
    from methods.data_driven.bake import analytic_irradiance
    from methods.data_driven.dataset import measure_direct
    from prtbench.transport.raytrace import Tracer

    scene = get_scene("sphere-over-plane", radius=0.5, height=1.0, plane_subdivisions=4)
    mp = measurement_points(scene, 400, placement="surface", seed=2)
    tracer = Tracer.from_scene(scene)
    lights = [PointLight((0.3, 2.2, 0.2), (3.0, 3.0, 3.0)),
              SpotLight((0.5, 2.5, -0.3), (-0.2, -1.0, 0.1), cutoff_deg=35.0,
                        intensity=(4.0, 4.0, 4.0)),
              DirectionalLight((0.3, 1.0, 0.2), (1.0, 0.8, 0.6))]
    x = measure_direct(scene, mp, _config(shadow_resolution=1024), lights)
    for k, light in enumerate(lights):
        e = analytic_irradiance(tracer, mp.points[:, 0], mp.normals[:, 0], [light],
                                diagonal=tracer.diagonal)
        expected = mp.albedo[:, 0] / math.pi * e
        scale = np.abs(expected).max()
        close = np.abs(x[k] - expected).max(axis=1) < 0.02 * scale
        assert close.mean() > 0.97, (k, close.mean())   # shadow-map edges may differ
        lit = expected[:, 0] > 0
        assert np.allclose(x[k][lit & close], expected[lit & close], rtol=2e-3, atol=1e-3 * scale)


# --- bake against Mitsuba ---------------------------------------------------------------------

def test_embree_bake_equals_mitsuba_indirect():
    from methods.data_driven.bake import bake_indirect, object_albedo
    from methods.data_driven.lightmap import build_lightmap
    from methods.data_driven.reference import render_light_reference
    from prtbench.transport.raytrace import Tracer

    scene = get_scene("cornell")
    view = scene.trajectory.views[0]
    lightmap = build_lightmap(scene, resolution=128)
    tracer = Tracer.from_scene(scene)
    light = PointLight((0.1, 0.7, 0.1), (1.0, 1.0, 1.0))
    baked = bake_indirect(tracer, object_albedo(scene, tracer), lightmap.points, lightmap.normals,
                          lightmap.albedo, light, bounces=1, paths=128)
    image = _lightmap_view(scene, tracer, lightmap, lightmap.image(baked), view, 64, 48)
    ref = render_light_reference(scene, light, view, width=64, height=48, spp=512, bounces=1,
                                 component="indirect")
    assert ref.image.min() >= 0.0  # shared seeds: the direct part cancels exactly
    ours_mean, ref_mean = image.mean(axis=(0, 1)), ref.image.mean(axis=(0, 1))
    assert np.allclose(ours_mean, ref_mean, rtol=0.03), (ours_mean, ref_mean)
    blocks = lambda im: im.reshape(6, 8, 8, 8, 3).mean(axis=(1, 3)).sum(-1)
    big = blocks(ref.image) > 0.2 * blocks(ref.image).max()
    rel = np.abs(blocks(image) - blocks(ref.image))[big] / blocks(ref.image)[big]
    assert np.median(rel) < 0.08, rel


def _lightmap_view(scene, tracer, lightmap, image, view, width, height):
    """CPU render of a lightmap: primary hit → atlas UV → bilinear lookup (back faces black)."""
    origins, dirs = view.primary_rays(width, height)
    hits = tracer.first_hit(origins.reshape(-1, 3), dirs.reshape(-1, 3))
    out = np.zeros((height * width, 3))
    ok = hits.hit
    f, u, v = hits.face[ok], hits.u[ok][:, None], hits.v[ok][:, None]
    corners = lightmap.mesh_uvs[lightmap.mesh_faces[f]]
    uv = (1 - u - v) * corners[:, 0] + u * corners[:, 1] + v * corners[:, 2]
    normal = tracer.normals[tracer.faces[f]].mean(axis=1)
    front = np.einsum("ij,ij->i", normal, -dirs.reshape(-1, 3)[ok]) > 0
    out[ok] = lightmap.lookup(image, uv) * front[:, None]
    return out.reshape(height, width, 3)


# --- the method end to end --------------------------------------------------------------------

def _box_scene():
    scene = get_scene("cornell")
    return scene.with_views(1)


@pytest.fixture(scope="module")
def spot_artifact():
    scene = _box_scene()
    cls = METHODS.get("data-driven")
    config = _config(light_family="spot", configurations=6, basis=16, ridge=0.01,
                     paths_per_texel=8, measurement_points=48)
    return scene, cls, config, load_or_precompute(cls, scene, config, progress=False)


def test_gl_transfer_and_blend_match_numpy(spot_artifact):
    from methods.data_driven.dataset import build_dataset
    from methods.data_driven.method import fit_basis
    from prtbench.transport.raytrace import Tracer

    scene, cls, config, artifact = spot_artifact
    dataset = build_dataset(scene, config)
    fitted = fit_basis(dataset, config)
    light = dataset.lights[2]
    renderer = cls.renderer(scene, artifact, config, width=64, height=48)
    try:
        x = renderer.direct_vector(light)
        assert np.allclose(x, dataset.direct[2], rtol=1e-5, atol=1e-7)
        gl_weights = renderer.coefficients(light)[:, : config.basis]
        assert np.allclose(gl_weights.T, fitted.coefficients(x.astype(np.float64)),
                           rtol=1e-3, atol=1e-4 * np.abs(gl_weights).max())
        image = renderer.render(scene.trajectory.views[0], light, direct=False)
    finally:
        renderer.release()
    # The GL image equals the CPU lookup of the numpy prediction (packing, transfer, blend).
    from methods.data_driven.basis import predict

    tracer = Tracer.from_scene(scene)
    expected = _lightmap_view(scene, tracer, dataset.lightmap,
                              dataset.lightmap.image(predict(fitted, x[None].astype(np.float64))[0]),
                              scene.trajectory.views[0], 64, 48)
    scale = np.abs(expected).max()
    close = np.abs(image - expected).max(axis=-1) < 0.02 * scale
    assert close.mean() > 0.95, close.mean()  # pixels straddling chart borders may differ


@pytest.mark.parametrize("channels,gamma,per_channel", [("interleaved", 1.0, True),
                                                       ("mono", 2.2, True), ("mono", 1.0, False)])
def test_gl_interleaved_and_gamma_paths_match_numpy(spot_artifact, channels, gamma, per_channel):
    import dataclasses

    from methods.data_driven.basis import encode, predict, to_examples
    from methods.data_driven.dataset import build_dataset
    from methods.data_driven.method import fit_basis
    from prtbench.transport.raytrace import Tracer

    scene, cls, base, _ = spot_artifact
    config = dataclasses.replace(base, channels=channels, gamma=gamma, basis=8, ridge=0.1,
                                 channel_transfer=per_channel)
    artifact = load_or_precompute(cls, scene, config, progress=False)
    dataset = build_dataset(scene, config)
    assert dataset.cache_hit  # layout, gamma, n and λ do not change the dataset
    fitted = fit_basis(dataset, config)
    assert len(fitted.transfer) == (3 if channels == "mono" and per_channel else 1)
    light = dataset.lights[1]
    renderer = cls.renderer(scene, artifact, config, width=64, height=48)
    try:
        x = renderer.direct_vector(light).astype(np.float64)
        weights = renderer.coefficients(light)
        image = renderer.render(scene.trajectory.views[0], light, direct=False)
    finally:
        renderer.release()
    encoded, _ = to_examples(x[None], np.zeros((1, 1, 3)), layout=channels)
    expected_w = fitted.coefficients(encode(encoded, gamma))      # (n, 3) or (n, 1)
    got_w = weights[:, : config.basis].T
    assert np.allclose(got_w, expected_w, rtol=1e-3, atol=1e-4 * np.abs(expected_w).max())
    lightmap = dataset.lightmap.image(predict(fitted, x[None])[0])
    expected = _lightmap_view(scene, Tracer.from_scene(scene), dataset.lightmap, lightmap,
                              scene.trajectory.views[0], 64, 48)
    close = np.abs(image - expected).max(axis=-1) < 0.02 * np.abs(expected).max()
    # Blending happens before the gamma decode on the GPU, after it in the CPU lookup: equal
    # except where bilinear filtering mixes texels (chart borders, gradients).
    assert close.mean() > (0.95 if gamma == 1.0 else 0.85), close.mean()


def test_gamma_space_is_finite_and_linear_for_a_light_a_million_times_brighter(spot_artifact):
    # Issue #15 (stability): at gamma 0.1 the transfer pass raised the direct light to the
    # 10th power in float32, so a 10⁶ light (10⁶⁰) overflowed and the image had NaN pixels.
    # The light's peak power is now factored out (the transfer is homogeneous of degree 1).
    import dataclasses

    scene, cls, base, _ = spot_artifact
    config = dataclasses.replace(base, gamma=0.1)
    artifact = load_or_precompute(cls, scene, config, progress=False)
    from methods.data_driven.dataset import build_dataset

    light = build_dataset(scene, config).lights[1]
    bright = dataclasses.replace(light, intensity=tuple(1e6 * c for c in light.intensity))
    renderer = cls.renderer(scene, artifact, config, width=64, height=48)
    try:
        view = scene.trajectory.views[0]
        unit = renderer.render(view, light, direct=False)
        huge = renderer.render(view, bright, direct=False)
        w_unit, w_huge = renderer.coefficients(light), renderer.coefficients(bright)
    finally:
        renderer.release()
    assert np.isfinite(huge).all() and unit.max() > 0
    assert np.allclose(huge / 1e6, unit, rtol=1e-3, atol=1e-4 * unit.max())
    # coefficients() stays relative to the light itself: 10⁶ˣ brighter scales them by 10⁶⁰.
    assert np.allclose(w_huge, w_unit * 1e60, rtol=1e-3, atol=1e-4 * np.abs(w_unit).max() * 1e60)


def test_all_dark_light_renders_finite_black_indirect(spot_artifact):
    scene, cls, config, artifact = spot_artifact
    renderer = cls.renderer(scene, artifact, config, width=32, height=24)
    try:
        dark = PointLight((0.0, 0.5, 0.0), (0.0, 0.0, 0.0))
        image = renderer.render(scene.trajectory.views[0], dark)
    finally:
        renderer.release()
    assert np.all(np.isfinite(image)) and np.all(image == 0.0)


def test_white_furnace_on_a_convex_object():
    # A lone convex sphere under a uniform sky: no interreflection (indirect exactly 0) and
    # direct light kd·(E/π) with E = π, drawn as 64 median-cut lights (≈ 2 % quadrature error).
    base = get_scene("sphere-over-plane", radius=0.5, height=1.0)
    sphere = max(base.objects, key=lambda o: o.mesh.n_vertices)
    view = View(eye=(0.0, 1.0, 3.0), target=(0.0, 1.0, 0.0), fov_y=40.0)
    scene = Scene("furnace-sphere", [SceneObject("sphere", sphere.mesh, Material(kd=(0.5,) * 3))],
                  trajectory=Trajectory((view,)), default_light="white")
    cls = METHODS.get("data-driven")
    config = _config(env_lights=64, configurations=3, measurement_points=32,
                     env_shadow_resolution=512, lightmap_resolution=64)
    artifact = load_or_precompute(cls, scene, config, progress=False)
    renderer = cls.renderer(scene, artifact, config, width=64, height=48)
    try:
        indirect = renderer.render(view, get_light("white"), direct=False)
        image = renderer.render(view, get_light("white"))
    finally:
        renderer.release()
    covered = image[..., 0] > 0
    assert covered.sum() > 300
    assert np.all(indirect == 0.0)
    assert abs(float(np.median(image[covered])) - 0.5) < 0.02
    assert np.all(image[~covered] == 0)


def test_validate_rejects_glossy_and_unknown_lights():
    cls = METHODS.get("data-driven")
    with pytest.raises(InvalidInputError, match="diffuse materials only"):
        cls.validate(get_scene("cornell", variant="glossy"), _config())
    with pytest.raises(UnknownNameError):
        cls.validate(get_scene("cornell"), _config(environment="not-a-light"))
    with pytest.raises(InvalidInputError):
        cls.make_config({"light_family": "area"}, profile="smoke")


def test_runner_smoke(tmp_path):
    from prtbench.bench.job import Outputs
    from prtbench.bench.regress import case_job, gate
    from prtbench.bench.submit import run

    job = case_job("data-driven")  # cornell, smoke
    summary = run(job, outputs=Outputs(out_dir=tmp_path), store=False, progress=False,
                  echo=False).summary
    assert summary.reference_spp == 32
    # Beats the flat and half-bright images (data-driven has no unshadowed render).
    assert not gate(job, summary.mean_metrics())
    assert summary.memory_bytes > 0 and summary.views[0].frame_ms > 0
    assert (tmp_path / "data-driven" / "cornell-diffuse" / "sky" / "view00.exr").is_file()


@pytest.mark.slow
def test_indirect_error_falls_with_basis_count_towards_the_projection():
    from methods.data_driven.evaluation import lightmap_study

    scene = get_scene("cornell")
    config = METHODS.get("data-driven").make_config(
        {"lightmap_resolution": 128, "configurations": 64, "ridge": 0.1}, profile="quick")
    study = lightmap_study(scene, config, [1, 4, 16, 64], test_lights=8, reference_factor=16)
    pred, proj = study.prediction_rmse, study.projection_rmse
    assert pred[0] > pred[1] > pred[2] and pred[3] < pred[1]
    assert pred[2] < 1.5 * proj[2] and pred[3] < 1.5 * proj[3]


@pytest.mark.slow  # ~18 s of fitting; make test keeps the runner smoke run and regress
def test_small_dataset_error_falls_and_stays_near_the_projection():
    # Belcour et al.'s Fig. 14 claim at test size: on held-out rotations of the sky, the
    # prediction from 64 measurement points falls with every added basis element up to 16 and
    # stays within 1.5x of projecting the reference itself (measured: 1.02-1.18x; the full
    # curve to n = 64 is `make figure-ddprt-14`).
    from methods.data_driven.evaluation import lightmap_study

    scene = get_scene("cornell")
    config = METHODS.get("data-driven").make_config(
        {"configurations": 64, "lightmap_resolution": 128, "paths_per_texel": 32,
         "light_family": "env-rotations", "ridge": 1e-2}, profile="smoke")
    study = lightmap_study(scene, config, [1, 2, 4, 8, 16], test_lights=4, reference_factor=8)
    pred, proj = np.array(study.prediction_rmse), np.array(study.projection_rmse)
    assert np.all(np.diff(pred) < 0), pred
    assert np.all(pred >= proj * (1 - 1e-9)) and pred[-1] <= 1.5 * proj[-1], pred / proj
