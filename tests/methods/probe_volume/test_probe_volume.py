"""Probe volumes: placement and lookup, the pool layouts (engine: 16 / 32 bytes per probe),
the reduction to per-vertex irradiance, the white furnace, relight against a baked light,
validity, virtual offset, dilation, DDGI depth moments, bad input, and smoke runs through the
runner that beat the trivial images."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import methods.probe_volume.method  # noqa: F401 - registers "probe-volume"
from methods.probe_volume import bake, encoding, placement
from prtbench.api.errors import InvalidInputError
from prtbench.api.method import METHODS, load_or_precompute
from prtbench.scene.model import Material, Scene, SceneObject, Trajectory, View
from prtbench.scene.registry import get_scene
from prtbench.transport.lights import get_light
from prtbench.transport.raytrace import geometry_mask
from scenes.primitives import box

WIDTH, HEIGHT = 96, 72


def _render(name, scene, *, light="sky", **overrides):
    cls = METHODS.get(name)
    config = cls.make_config(overrides, profile="quick")
    artifact = load_or_precompute(cls, scene, config, progress=False)
    renderer = cls.renderer(scene, artifact, config, width=WIDTH, height=HEIGHT)
    try:
        image = renderer.render(scene.trajectory.views[0], get_light(light))
        return image, renderer, artifact
    finally:
        renderer.release()


def _box_scene():
    view = View(eye=(1.6, 1.2, 2.2), target=(0.0, 0.0, 0.0), fov_y=40.0)
    return Scene("lone-box", [SceneObject("box", box(), Material(kd=(0.5, 0.5, 0.5)))],
                 trajectory=Trajectory((view,)), exposure=1.0)


def _plane_scene():
    scene = get_scene("plane", size=4.0)  # kd 0.5, normal +Y
    view = View(eye=(0.0, 2.5, 0.01), target=(0.0, 0.0, 0.0), fov_y=30.0)
    return dataclasses.replace(scene, trajectory=Trajectory((view,)))


# --- placement --------------------------------------------------------------------------------

def test_uniform_lookup_at_a_probe_is_that_probe():
    layout = placement.uniform_layout(get_scene("sphere-over-plane"), resolution=5, padding=0.02)
    ids, weights = placement.corners(layout, layout.positions)
    best = ids[np.arange(len(ids)), weights.argmax(axis=1)]
    assert np.array_equal(best, np.arange(layout.probes)) and np.allclose(weights.max(axis=1), 1)
    assert layout.pool_shape == (5, 5, 5) and np.array_equal(layout.texel[7], [0, 1, 2])


def test_bricks_refine_near_geometry_and_index_every_probe():
    scene = get_scene("plants")
    one = placement.brick_layout(scene, resolution=28, levels=1, padding=0.02)
    two = placement.brick_layout(scene, resolution=28, levels=2, padding=0.02)
    levels = two.index >> 24
    # Measured: 297 finest and 189 coarse index entries, 19456 probes against 25920.
    assert set(np.unique(levels)) == {0, 1} and two.probes < one.probes
    # Bricks hold 4×4×4 probes; an interior probe's lookup (nudged inside its brick) is itself.
    local = np.arange(two.probes) % 64
    interior = np.all(np.stack([local // 16, local // 4 % 4, local % 4], 1) % 3 != 0, axis=1)
    ids, weights = placement.corners(two, two.positions[interior] + 1e-9)
    best = ids[np.arange(len(ids)), weights.argmax(axis=1)]
    assert np.array_equal(best, np.flatnonzero(interior)) and weights.max(axis=1).min() > 0.999
    # Every texel of a used slot is a distinct probe; cells are cubes.
    assert len({tuple(t) for t in two.texel}) == two.probes
    assert np.allclose(two.cell, two.cell[0]) and two.pool_probes >= two.probes


def test_fine_bricks_sit_where_the_geometry_is():
    scene = get_scene("plants")
    layout = placement.brick_layout(scene, resolution=28, levels=2, padding=0.02)
    positions, _, _, _ = scene.merged()
    at = np.floor((positions - layout.origin) / (3 * layout.cell)).astype(int)
    assert np.all(layout.index[tuple(at.T)] >> 24 == 0)  # every vertex in a finest brick
    occupied = np.zeros(layout.index.shape, bool)
    occupied[tuple(at.T)] = True
    coarse = (layout.index >> 24) == 1
    assert coarse.any() and not (coarse & occupied).any()


# --- pool layouts -----------------------------------------------------------------------------

@pytest.mark.parametrize("code", list(encoding.COEFFICIENTS))
@pytest.mark.parametrize("storage", ["float16", "engine"])
@pytest.mark.parametrize("channels", [1, 3])
def test_pool_round_trip(code, storage, channels):
    rng = np.random.default_rng(0)
    k = encoding.COEFFICIENTS[code]
    values = np.abs(rng.normal(size=(300, k, channels))) + 0.2
    if code != "ambient-cube":  # SH of a non-negative function: |c_k| ≤ bound_k·c_0
        values[:, 1:] = rng.uniform(-0.55, 0.55, size=(300, k - 1, channels)) * values[:, :1]
    elif channels == 1:
        values = np.clip(values / 3.0, 0.0, 1.0)  # cosine-weighted visibilities
    texels = encoding.encode(values, encoding=code, storage=storage)
    decoded = encoding.decode(texels, encoding=code, storage=storage, channels=channels)
    # Measured: 3e-4 (half), 0.2 % (RGBE, unorm), 0.6-0.8 % of the peak (8-bit ratios).
    assert np.abs(decoded - values).max() < 0.01 * np.abs(values).max()


@pytest.mark.parametrize("code, channels, expected", [("l1", 3, 16), ("l2", 3, 32),
                                                      ("ambient-cube", 3, 24), ("l1", 1, 8),
                                                      ("l2", 1, 16), ("ambient-cube", 1, 8)])
def test_engine_bytes_per_probe(code, channels, expected):
    assert encoding.bytes_per_probe(code, "engine", channels) == expected


@pytest.mark.parametrize("code, per_probe", [("l1", 16), ("l2", 32)])
def test_engine_storage_reports_16_bytes_per_probe_at_l1_and_32_at_l2(code, per_probe):
    scene = get_scene("sphere-over-plane").with_views(1)
    _, renderer, artifact = _render("probe-volume", scene, light_mode="fixed", encoding=code,
                                    storage="engine", resolution=10, rays_per_probe=16)
    parts = renderer.memory_breakdown()
    pool = [v for name, v in parts.items() if name.startswith("gpu: probe pool")]
    slots = artifact.meta["pool_probes"]
    assert pool == [per_probe * slots]
    assert parts["gpu: probe validity (R8)"] == slots
    assert parts["gpu: brick index (R32UI)"] == artifact.arrays["brick_index"].size * 4
    assert renderer.memory_bytes() == pool[0] + slots + artifact.arrays["brick_index"].size * 4


def test_the_uploaded_pool_is_the_numpy_encoding():
    scene = get_scene("sphere-over-plane").with_views(1)
    cls = METHODS.get("probe-volume")
    config = cls.make_config({"light_mode": "fixed", "bake_light": "sky", "resolution": 10,
                              "rays_per_probe": 16}, profile="quick")
    artifact = load_or_precompute(cls, scene, config, progress=False)
    renderer = cls.renderer(scene, artifact, config, width=8, height=8)
    try:
        uploaded = renderer.pool_texels()
    finally:
        renderer.release()
    expected = encoding.encode(artifact.arrays["radiance"], encoding="l2", storage="engine")
    assert all(np.array_equal(a, b) for a, b in zip(uploaded, expected))


# --- exactness and lighting -------------------------------------------------------------------

@pytest.mark.parametrize("storage, tolerance", [("float16", 0.001), ("engine", 0.008)])
def test_one_probe_per_vertex_reduces_to_per_vertex_irradiance(storage, tolerance):
    # The box's 8 corners are its vertices: a 2³ grid without padding puts one probe on each.
    # Unshadowed, every probe holds V = √(4π)·δ_i0 exactly, so interpolation is exact and each
    # pixel gets Σ_{l≤2} Â_l L_lm Y_lm(n): the unshadowed vertex transfer on flat faces.
    scene = _box_scene()
    image, _, artifact = _render("probe-volume", scene, light="sun", placement="uniform",
                                 resolution=2, padding=0.0, visibility=False, storage=storage,
                                 normal_bias=0.0)
    positions = artifact.arrays["probe_positions"]
    assert {tuple(p) for p in positions} == {tuple(v) for v in box().positions}
    transfer = artifact.arrays["transfer"]
    assert np.allclose(transfer[:, 0], np.sqrt(4 * np.pi)) and np.allclose(transfer[:, 1:], 0)
    vertex, *_ = _render("vertex", scene, light="sun", sh_bands=3, visibility=False,
                         rays_per_point=4096)
    mask = geometry_mask(scene, scene.trajectory.views[0], WIDTH, HEIGHT)
    # Measured: 0.0002 (float16) and 0.004 (8-bit L2 ratios) of a 0.42 peak.
    assert np.abs(image - vertex)[mask].max() < tolerance


@pytest.mark.parametrize("overrides", [{"encoding": "l1"}, {"encoding": "l2"},
                                       {"encoding": "ambient-cube"},
                                       {"encoding": "l2", "light_mode": "fixed"},
                                       {"encoding": "ambient-cube", "light_mode": "fixed"}])
def test_white_light_over_a_ground_plane_is_the_albedo(overrides):
    # Probes above the ground see the upper hemisphere; white light: E = π at the normal +Y
    # (exact from l ≤ 1 on: V has no even l > 0, the cosine no odd l > 1), B = kd.
    image, _, artifact = _render("probe-volume", _plane_scene(), light="white",
                                 placement="uniform", resolution=8, rays_per_probe=4096,
                                 padding=0.002, **overrides)
    covered = image[..., 0] > 0
    assert covered.mean() > 0.5
    # Measured: within 0.4 % (fixed L2, whose 6-band bake rings a little at the plane's rim).
    assert np.allclose(image[covered], 0.5, rtol=0.006), (image[covered].min(), image[covered].max())
    valid = artifact.arrays["valid"].reshape(8, 8, 8).astype(bool)
    assert not valid[2:6, :4, 2:6].any() and valid[:, 4:, :].all()


def test_relight_equals_a_fixed_bake_at_the_same_bands_and_follows_the_light():
    scene = get_scene("sphere-over-plane").with_views(1)
    common = {"resolution": 10, "rays_per_probe": 64, "storage": "float16"}
    for light in ("sky", "sun"):
        relit, *_ = _render("probe-volume", scene, light=light, **common)
        baked, *_ = _render("probe-volume", scene, light=light, light_mode="fixed",
                            bake_bands=3, **common)
        covered = relit.max(axis=2) > 0
        # Measured: 0.035 % (sky) and 0.024 % (sun) of the peak: the transfer's half floats.
        assert np.abs(relit - baked)[covered].max() < 0.002 * relit[covered].max()
    sky, *_ = _render("probe-volume", scene, light="sky", **common)
    assert np.abs(sky - relit).max() > 0.05  # the same artifact under another light


def test_a_baked_light_renders_as_the_per_light_bake_and_refuses_others():
    scene = get_scene("sphere-over-plane").with_views(1)
    common = {"resolution": 10, "rays_per_probe": 32, "light_mode": "fixed"}
    folded, *_ = _render("probe-volume", scene, light="sun", **common)
    baked, *_ = _render("probe-volume", scene, light="sun", bake_light="sun", **common)
    assert np.array_equal(folded, baked)
    with pytest.raises(InvalidInputError) as info:
        _render("probe-volume", scene, light="sky", bake_light="sun", **common)
    assert "--set bake_light=sky" in str(info.value) and "\n" not in str(info.value)


# --- validity, virtual offset, dilation, depth moments ----------------------------------------

def _block_scene():
    block = dataclasses.replace(box(), positions=box().positions * np.array([2.0, 0.6, 2.0]))
    view = View(eye=(0.0, 3.0, 3.0), target=(0.0, 0.0, 0.0), fov_y=40.0)
    return Scene("block", [SceneObject("block", block, Material(kd=(0.5, 0.5, 0.5)))],
                 trajectory=Trajectory((view,)), exposure=1.0)


def test_virtual_offset_moves_probes_out_of_geometry():
    scene = _block_scene()
    layout = placement.uniform_layout(scene, resolution=5, padding=0.0)
    kwargs = {"bands": 2, "rays": 128, "seed": 0, "occlusion": True,
              "invalid_backface_fraction": 0.25, "dilation_iterations": 0, "depth_texels": 0,
              "progress": False}
    still = bake.bake_probes(scene, layout, virtual_offset=0.0, **kwargs)
    moved = bake.bake_probes(scene, layout, virtual_offset=1.0, **kwargs)
    inside = ~still.valid
    assert inside.sum() >= 3 and np.array_equal(still.capture, layout.positions)
    # Probes just inside the thin block's faces find a back face within a spacing: captured
    # outside, they see the sky and become valid; the lattice position is unchanged.
    rescued = inside & moved.valid
    assert rescued.sum() >= 1
    shift = np.linalg.norm(moved.capture - layout.positions, axis=1)
    assert np.all(shift[rescued] > 0) and np.all(shift[~inside] == 0)


def test_dilation_fills_invalid_probes_from_valid_neighbours():
    layout = placement.uniform_layout(get_scene("sphere-over-plane"), resolution=3, padding=0.0)
    valid = np.ones(27, bool)
    valid[13] = False  # the centre probe: 26 valid neighbours
    values = np.arange(27, dtype=np.float64)[:, None] * np.ones((1, 2))
    values[13] = -100.0
    (filled,) = bake.dilate(layout, valid, [values], iterations=1)
    d2 = np.sum((layout.positions - layout.positions[13]) ** 2, axis=1)
    w = np.where(valid, 1.0 / np.where(valid, d2, 1.0), 0.0)
    assert np.allclose(filled[13], (w @ values[:, 0]) / w.sum())
    assert np.array_equal(np.delete(filled, 13, 0), np.delete(values, 13, 0))
    (untouched,) = bake.dilate(layout, valid, [values], iterations=0)
    assert untouched[13, 0] == -100.0


def test_depth_moments_of_a_probe_over_a_plane():
    plane = get_scene("plane", size=200.0)
    layout = dataclasses.replace(
        placement.uniform_layout(plane, resolution=2, padding=0.0),
        positions=np.array([[0.0, 0.5, 0.0]]), spacing=np.ones((1, 3)),
        texel=np.zeros((1, 3), np.int64))
    result = bake.bake_probes(plane, layout, bands=2, rays=4096, seed=0, occlusion=True,
                              invalid_backface_fraction=0.25, virtual_offset=0.0,
                              dilation_iterations=0, depth_texels=8, progress=False)
    directions = bake.depth_texel_directions(8)
    assert np.allclose(np.linalg.norm(directions, axis=1), 1.0)
    moments = result.depth[0].reshape(-1, 2)
    down, up = directions[:, 1].argmin(), directions[:, 1].argmax()
    clamp = bake.DEPTH_RANGE * np.sqrt(3.0)
    assert moments[down, 0] == pytest.approx(0.5, rel=0.05)  # straight down: the height
    assert moments[up, 0] == pytest.approx(clamp, rel=1e-3)  # up: nothing, the clamp
    assert np.all(moments[:, 1] >= moments[:, 0] ** 2 - 1e-3)  # E[d²] ≥ E[d]²


def test_chebyshev_and_every_test_render_finite_images():
    scene = get_scene("sphere-over-plane").with_views(1)
    images = {t: _render("probe-volume", scene, visibility_test=t, resolution=10,
                         rays_per_probe=64)[0] for t in ("none", "validity", "chebyshev")}
    covered = images["none"].max(axis=2) > 0
    for test, image in images.items():
        assert np.all(np.isfinite(image)) and image[covered].mean() > 0.1, test
    _, renderer, _ = _render("probe-volume", scene, visibility_test="chebyshev",
                             resolution=10, rays_per_probe=64)
    assert "gpu: depth moments (RG16F, 8×8 per probe)" in renderer.memory_breakdown()


# --- bad input and the runner -----------------------------------------------------------------

@pytest.mark.parametrize("overrides, match", [
    ({"bake_light": "sun"}, "bake_light only with light_mode=fixed"),
    ({"light_mode": "fixed", "bake_bands": 2}, "bake_bands >= 3"),
])
def test_contradictory_knobs_are_refused(overrides, match):
    from prtbench.bench.job import Job
    from prtbench.bench.runner import prepare

    with pytest.raises(InvalidInputError, match=match):
        prepare(Job(method="probe-volume", scene="plane", profile="smoke", overrides=overrides),
                store=False)


def test_a_light_beyond_half_floats_is_refused_in_fixed_mode():
    scene = get_scene("sphere-over-plane").with_views(1)
    huge = dataclasses.replace(get_light("white"), image=get_light("white").image * 1e6,
                               name="huge").as_new_light()
    cls = METHODS.get("probe-volume")
    config = cls.make_config({"light_mode": "fixed", "resolution": 4, "rays_per_probe": 8})
    artifact = load_or_precompute(cls, scene, config, progress=False)
    renderer = cls.renderer(scene, artifact, config, width=8, height=8)
    try:
        with pytest.raises(InvalidInputError, match="beyond the half floats"):
            renderer.render(scene.trajectory.views[0], huge)
    finally:
        renderer.release()


def test_glossy_scene_is_refused_in_one_line():
    from prtbench.bench.job import Job
    from prtbench.bench.runner import prepare

    with pytest.raises(InvalidInputError) as info:
        prepare(Job(method="probe-volume", scene="sphere-over-plane", variant="glossy",
                    profile="smoke"), store=False)
    assert "glossy" in str(info.value) and "\n" not in str(info.value)


@pytest.mark.slow  # 8-20 s each; `prtbench regress` gates the same cases
@pytest.mark.parametrize("case", ["probe-volume", "probe-volume:fixed"])
def test_smoke_run_through_the_runner_beats_the_trivial_images(case):
    from prtbench.bench.regress import case_job, trivial_results
    from prtbench.bench.submit import run
    from prtbench.bench.trivial import gate_failures

    job = case_job(case)  # plants diffuse under sky, smoke profile
    summary = run(job, store=False, progress=False, echo=False).summary
    metrics = summary.mean_metrics()
    trivial, _ = trivial_results(job)
    assert not gate_failures(metrics, trivial)  # flat, half and the unshadowed render
    # Measured: 21.7 (relight) and 21.5 dB (fixed) against the flat image's 17.2.
    assert metrics["psnr_masked"] >= trivial["flat"]["psnr_masked"] + 3.0


def test_op_counts_grow_with_the_coefficients_and_the_test():
    cls = METHODS.get("probe-volume")

    def ops(**overrides):
        counts = cls.op_counts(cls.make_config(overrides, profile="smoke"), scene_vertices=1000,
                               scene_triangles=2000, covered_pixels=5000, width=64, height=64,
                               memory_bytes=1)
        return counts["madds"] + 4 * counts["fetches"] + 0.5 * counts["bytes"]

    assert ops(encoding="l1") < ops(encoding="l2")
    assert ops(visibility_test="validity") < ops(visibility_test="chebyshev")
    assert ops(placement="uniform") < ops(placement="bricks")
