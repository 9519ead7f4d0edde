"""neural-wavelet (Raghavan 2023): model pieces, indirect-only data, training, cache, bad input."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

import methods.neural_wavelet.method  # noqa: E402,F401  (registers the method without a reinstall)
from methods.neural_wavelet.model import ModelSpec, NeuralWaveletModel, PixelInputs, wavelet_lookup
from prtbench.api.cache import cache_root  # noqa: E402
from prtbench.api.errors import InvalidInputError  # noqa: E402
from prtbench.api.method import METHODS, load_or_precompute  # noqa: E402
from prtbench.cli import main  # noqa: E402
from prtbench.scene.registry import get_scene  # noqa: E402
from prtbench.transport.lights import get_light  # noqa: E402


def _scene(variant="glossy"):
    return get_scene("sphere-over-plane", variant=variant, sphere_segments=16,
                     plane_subdivisions=4).with_views(2)


def _spec(**kw):
    base = dict(features="hashgrid", levels=4, features_per_level=2, base_resolution=4,
                per_level_scale=1.5, log2_table=10, vertex_features=8, feature_dim=8, hidden=16,
                layers=2, reflect_degree=2, cubemap=4, wavelet_grid=4,
                bounds=(-1.0, -1.0, -1.0, 1.0, 1.0, 1.0), vertices=3)
    base.update(kw)
    return ModelSpec(**base)


def _inputs(p=12, seed=0):
    g = torch.Generator().manual_seed(seed)
    n = torch.nn.functional.normalize(torch.randn(p, 3, generator=g), dim=1)
    wo = torch.nn.functional.normalize(torch.randn(p, 3, generator=g), dim=1)
    return PixelInputs(torch.rand(p, 3, generator=g) * 2 - 1, n, wo, torch.rand(p, 3, generator=g),
                       torch.rand(p, 3, generator=g), torch.full((p,), 32.0),
                       torch.zeros(p, dtype=torch.int64))


# --- model pieces --------------------------------------------------------------------------------

def test_wavelet_grid_is_one_texel_at_cubemap_resolution_and_bilinear_below():
    n = 8
    terms = np.arange(6 * n * n)
    rows, weights = wavelet_lookup(terms, cubemap=n, grid=n)
    np.testing.assert_array_equal(rows[:, 0], terms)  # j = f·N² + r·N + c is W's row
    np.testing.assert_array_equal(weights[:, 0], 1.0)
    rows, weights = wavelet_lookup(terms, cubemap=n, grid=n // 2)
    np.testing.assert_allclose(weights.sum(axis=1), 1.0, atol=1e-6)
    # Coefficient (face 2, row 3, column 4) sits at face position (4.5/8, 3.5/8): texel-centre
    # coordinates (col 1.75, row 1.25) of the 4×4 grid: rows 1..2 with t = 0.25, columns 1..2
    # with t = 0.75.
    j = 2 * n * n + 3 * n + 4
    base = 2 * 16
    assert rows[j].tolist() == [base + 1 * 4 + 1, base + 1 * 4 + 2, base + 2 * 4 + 1,
                                base + 2 * 4 + 2]
    np.testing.assert_allclose(weights[j], [0.75 * 0.25, 0.75 * 0.75, 0.25 * 0.25, 0.25 * 0.75])
    assert set(np.unique(rows // 16)) == set(range(6))  # faces never blend


def test_radiance_is_the_dot_product_of_transport_and_light():
    model = NeuralWaveletModel(_spec(), seed=3)
    model.target_scale.fill_(2.5)
    inputs, terms = _inputs(), np.array([0, 7, 33, 95])
    light = torch.rand(4, 3)
    t = model.transport(inputs, terms)
    assert t.shape == (12, 4, 3)
    want = (t * light[None]).sum(dim=1) * 2.5
    torch.testing.assert_close(model.radiance(inputs, terms, light), want)
    # Reflection-direction encoding matters: flipping ωo changes T on most pixels.
    flipped = PixelInputs(inputs.positions, inputs.normals, -inputs.wo, inputs.kd, inputs.ks,
                          inputs.shininess, inputs.triangles)
    assert (model.transport(flipped, terms) - t).abs().max() > 1e-4


def test_vertex_features_are_barycentric_then_softplus():
    pos = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
    model = NeuralWaveletModel(_spec(features="vertex", vertex_features=2), mesh=(pos, [[0, 1, 2]]))
    with torch.no_grad():
        model.field.table.copy_(torch.tensor([[1.0, -1.0], [3.0, 0.0], [-2.0, 5.0]]))
    pts = torch.tensor([[0.2, 0.3, 0.0], [0.0, 0.0, 0.0], [0.5, 0.5, 0.1]])
    got = model.field(pts, torch.zeros(3, dtype=torch.int64))
    bary = torch.tensor([[0.5, 0.2, 0.3], [1.0, 0.0, 0.0], [0.0, 0.5, 0.5]])  # 3rd: projected
    want = torch.nn.functional.softplus(bary @ model.field.table.detach())
    torch.testing.assert_close(got, want)


def test_model_arrays_round_trip_exactly():
    model = NeuralWaveletModel(_spec(), seed=5)
    again = NeuralWaveletModel.from_arrays(model.to_arrays())
    inputs, terms = _inputs(seed=2), np.array([1, 2, 3])
    assert torch.equal(model.transport(inputs, terms), again.transport(inputs, terms))
    bytes_ = model.resident_bytes()
    assert bytes_["field"] == model.field.table.numel() * 4
    assert bytes_["wavelet_grid"] == 6 * 16 * 8 * 4 and bytes_["matrix"] == 8 * 8 * 4


def test_gbuffer_pixels_are_the_ray_tracers_first_hits():
    from methods.neural_wavelet.gbuffer import GBufferPass, pixel_rows
    from prtbench.transport.raytrace import Tracer

    scene = _scene()
    view = scene.trajectory.views[0]
    gpass = GBufferPass(scene, width=40, height=30)
    try:
        rows = pixel_rows(gpass.read(view), view.eye)
    finally:
        gpass.release()
    origins, dirs = view.primary_rays(40, 30)
    hits = Tracer.from_scene(scene).first_hit(origins.reshape(-1, 3), dirs.reshape(-1, 3))
    assert len(rows["pixel"]) > 300
    # Same pixels covered and, at each, the same triangle (the vertex variant's input).
    assert np.array_equal(np.flatnonzero(hits.face >= 0), rows["pixel"])
    assert np.mean(hits.face[rows["pixel"]] == rows["triangles"]) > 0.99
    sphere = rows["ks"][:, 0] > 0.4  # the glossy sphere: ks 0.45, s 128
    assert sphere.any() and np.allclose(rows["shininess"][sphere], 128.0, rtol=1e-5)
    np.testing.assert_allclose(np.linalg.norm(rows["wo"], axis=1), 1.0, atol=1e-5)


# --- training data: indirect only ---------------------------------------------------------------

def test_indirect_is_full_minus_direct_and_adds_back_to_an_independent_full_render():
    from methods.neural_wavelet.data import indirect_image
    from prtbench.render.reference import render_reference

    scene, light = _scene(), get_light("sky")
    view = scene.trajectory.views[0]
    kw = dict(width=40, height=30, spp=64)
    indirect, direct, facts = indirect_image(scene, light, view, bounces=1, seed=11, **kw)
    peak = float(direct.max())
    # Same seed: the direct samples cancel, so the difference is never negative beyond rounding.
    assert facts["negative"] >= -1e-5 * peak, (facts["negative"], peak)
    assert indirect.mean() > 0.005 * direct.mean()  # sphere and ground light each other
    other = render_reference(scene, light, view, bounces=1, seed=12, **kw)
    mask = other.image.max(axis=-1) > 0
    rms = float(np.sqrt(np.mean((direct + indirect - other.image)[mask] ** 2)))
    # Two independent full estimates differ by ~√2 × the per-render noise.
    assert rms < 3.0 * np.sqrt(2.0) * other.noise_rmse, (rms, other.noise_rmse)


def test_nan_in_a_training_image_is_refused_and_nothing_is_cached(monkeypatch):
    import methods.neural_wavelet.data as data  # patched where the training data renders

    real = data.render_reference

    def poisoned(*args, **kwargs):
        ref = real(*args, **kwargs)
        ref.image[0, 0, 1] = np.nan
        return ref

    monkeypatch.setattr(data, "render_reference", poisoned)
    cls = METHODS.get("neural-wavelet")
    config = cls.make_config({"direct": "none", "seed": 99}, profile="smoke")
    with pytest.raises(InvalidInputError, match="non-finite pixels"):
        load_or_precompute(cls, _scene(), config, progress=False)
    for kind in ("nw-data", "nw-model", "artifacts/neural-wavelet"):
        folder = cache_root() / kind
        assert not folder.exists() or not any(folder.glob("*.npz")), kind


# --- training, cache, renderer --------------------------------------------------------------------

@pytest.fixture(scope="module")
def trained():
    cls = METHODS.get("neural-wavelet")
    config = cls.make_config({"direct": "none"}, profile="smoke")
    scene = _scene()
    artifact = load_or_precompute(cls, scene, config, progress=False)
    return cls, config, scene, artifact


def test_training_loss_falls(trained):
    _, _, _, artifact = trained
    meta = artifact.meta
    assert meta["data_images"] == 4 and meta["data_rows"] > 500
    assert meta["loss_last"] < 0.5 * meta["loss_first"], (meta["loss_first"], meta["loss_last"])
    assert meta["pixels_per_s"] > 0


def test_model_reloaded_from_the_cache_renders_bit_identically(trained):
    cls, config, scene, first = trained
    assert not first.cache_hit
    again = load_or_precompute(cls, scene, config, progress=False)
    assert again.cache_hit
    view, light = scene.trajectory.views[0], get_light("sun")
    images = []
    for artifact in (first, again):
        renderer = cls.renderer(scene, artifact, config, width=48, height=36)
        try:
            images.append(renderer.render(view, light))
            bytes_ = renderer.memory_bytes()
            parts = renderer.model.resident_bytes()
        finally:
            renderer.release()
    assert np.array_equal(images[0], images[1])
    covered = images[0].max(axis=-1) != 0
    assert covered.sum() > 200 and np.isfinite(images[0]).all()
    assert bytes_ == sum(parts.values()) and parts["field"] > parts["mlp"] > 0


def test_renderer_uses_the_k_selected_terms(trained):
    cls, config, scene, artifact = trained
    renderer = cls.renderer(scene, artifact, config, width=32, height=24)
    try:
        renderer.render(scene.trajectory.views[0], get_light("sky"))
        assert len(renderer.last_terms) == config.light_terms
        times = renderer.frame_time(scene.trajectory.views[0], get_light("sky"), warmup=1,
                                    frames=2)
        assert times.median_ms > 0 and times.source == "wall+sync"
    finally:
        renderer.release()


# --- bad input -------------------------------------------------------------------------------------

@pytest.mark.parametrize("sets, fragment", [
    (["light_terms=1000"], "light_terms=1000 exceeds the 384"),
    (["levels=64", "features_per_level=16", "log2_table=30"], "bytes"),
    (["heldout_lights=purple"], "both train_lights and heldout_lights"),
    (["features=mesh"], "accepted: hashgrid, vertex"),
    (["cubemap=12"], "cubemap=12; accepted: a power of two"),
    (["heldout_lights=sunsett"], "unknown light 'sunsett'; did you mean 'sunset'?"),
])
def test_bad_input_is_one_line_exit_2_and_caches_nothing(tmp_path, monkeypatch, capsys, sets,
                                                          fragment):
    cache = tmp_path / "cache"
    monkeypatch.setenv("PRTBENCH_CACHE", str(cache))
    out, results = tmp_path / "out", tmp_path / "results.sqlite"
    argv = ["run", "--method", "neural-wavelet", "--scene", "sphere-over-plane", "--variant",
            "glossy", "--profile", "smoke"] + [x for s in sets for x in ("--set", s)]
    status = main([*argv, "--out", str(out), "--results", str(results)])
    err = capsys.readouterr().err.strip()
    assert status == 2 and err.startswith("prtbench: error: ") and "\n" not in err, err
    assert fragment in err, err
    assert not out.exists() and not results.exists()
    assert not cache.exists() or not any(p.is_file() for p in cache.rglob("*"))


def test_artifact_key_holds_the_training_cameras():
    """The training cameras are derived from the trajectory, so another trajectory of the same
    geometry is another artifact (it was the same key once, and a cache hit returned a model
    trained around other cameras); per-vertex transfer, which reads no camera, keeps one key."""
    from prtbench.api.method import artifact_key

    cls = METHODS.get("neural-wavelet")
    config = cls.make_config({}, profile="smoke")
    two, one = _scene(), _scene().with_views(1)
    assert artifact_key(cls, two, config) == artifact_key(cls, _scene(), config)
    assert artifact_key(cls, two, config) != artifact_key(cls, one, config)
    vertex = METHODS.get("vertex")
    vcfg = vertex.make_config({}, profile="smoke")
    assert artifact_key(vertex, two, vcfg) == artifact_key(vertex, one, vcfg)


def test_a_tilted_light_moves_its_sun_by_the_tilt_and_keeps_its_power():
    """Turning about a horizontal axis carries the brightest direction s to R s (Rodrigues) and,
    being a rotation, keeps the total power up to the bilinear resampling's blur."""
    from methods.neural_wavelet.data import tilted_light

    sun = get_light("sun")
    assert tilted_light(sun, 0.0, axis_azimuth_deg=30.0) is sun
    tilted = tilted_light(sun, 40.0, axis_azimuth_deg=90.0)  # axis +Z: x-y plane turns by 40°
    s = sun.brightest_direction()
    c, k = np.cos(np.radians(40.0)), np.sin(np.radians(40.0))
    want = np.array([c * s[0] - k * s[1], k * s[0] + c * s[1], s[2]])
    got = tilted.brightest_direction()
    angle = np.degrees(np.arccos(np.clip(got @ want, -1.0, 1.0)))
    assert angle < 0.6, (got, want)  # within about one texel of the 512-row map (0.35°)
    moved = np.degrees(np.arccos(np.clip(got @ s, -1.0, 1.0)))
    assert moved > 20.0, moved  # the sun really moved (it is not on the axis)
    np.testing.assert_allclose(tilted.total_power(), sun.total_power(), rtol=0.02)


@pytest.mark.parametrize("knob, value, changes_data", [
    ("light_tilt", 30.0, True), ("random_lights", 4, True), ("relative_eps", 0.1, False)])
def test_a_knob_added_later_keeps_the_keys_at_its_default_and_changes_them_otherwise(
        knob, value, changes_data):
    from methods.neural_wavelet.data import LATE_KNOB_DEFAULTS, dataset_key, training_views
    from methods.neural_wavelet.train import training_key
    from prtbench.api.method import artifact_key

    cls = METHODS.get("neural-wavelet")
    scene = _scene()
    # At the value it had before it existed (random_lights: 0; its default is now 16).
    plain = cls.make_config({knob: LATE_KNOB_DEFAULTS[knob]}, profile="smoke")
    changed = cls.make_config({knob: value}, profile="smoke")
    views = training_views(scene, count=2, jitter=20.0, seed=0)
    # The knob was added after models were trained: at that value it is in no key.
    assert knob not in cls.cache_identity(plain)
    assert artifact_key(cls, scene, plain) != artifact_key(cls, scene, changed)
    data_keys = [dataset_key(scene, c, views) for c in (plain, changed)]
    assert (data_keys[0] != data_keys[1]) == changes_data
    # A training knob changes the model's key on the same data; a data knob only the data's.
    assert ((training_key(data_keys[0], plain) != training_key(data_keys[0], changed))
            == (not changes_data))


def test_relative_loss_fits_the_mean_of_noisy_targets_where_mulaw_fits_below_it():
    """Monte Carlo pixel noise is heavy-tailed. The minimiser of the relative L2 (weight held
    constant) is the mean of the samples; the μ-law loss, a near-logarithm inside the square,
    fits close to their geometric mean instead: far below the mean that the image converges to."""
    from methods.neural_wavelet.train import mulaw, relative_l2

    g = torch.Generator().manual_seed(0)
    # Log-normal samples, sigma 1.5: median 1, mean exp(1.125) = 3.08 (2.93 for these 4000).
    # Measured: the relative fit lands on 2.930, the μ-law fit on 0.990.
    target = torch.exp(1.5 * torch.randn(4000, 1, generator=g, dtype=torch.float64))
    target = target.expand(-1, 3)
    mean = float(target.mean())
    white = float(torch.quantile(target[:, 0], 0.99))

    def fit(loss) -> float:
        value = torch.ones(1, 3, dtype=torch.float64, requires_grad=True)
        opt = torch.optim.Adam([value], lr=0.05)
        for _ in range(1500):
            opt.zero_grad()
            loss(value.expand_as(target)).backward()
            opt.step()
        return float(value.detach().mean())

    relative = fit(lambda p: relative_l2(p, target, 0.01))
    tonemapped = fit(lambda p: torch.mean((mulaw(p / white, 5000.0)
                                           - mulaw(target / white, 5000.0)) ** 2))
    assert relative == pytest.approx(mean, rel=0.01)
    assert tonemapped < 0.6 * mean, (tonemapped, mean)


def test_light_tilt_tilts_only_later_turns_and_is_seeded():
    from methods.neural_wavelet.data import training_lights

    upright = training_lights(("sky",), 3)
    turned = training_lights(("sky",), 3, tilt=30.0, seed=0)
    assert [lt.name for lt in upright] == ["sky", "sky@120", "sky@240"]
    assert turned[0] is not None and turned[0].name == "sky"  # turn 0: the light as given
    assert all("~" in lt.name for lt in turned[1:]), [lt.name for lt in turned]
    again = training_lights(("sky",), 3, tilt=30.0, seed=0)
    assert [lt.content_hash() for lt in again] == [lt.content_hash() for lt in turned]
    with pytest.raises(InvalidInputError, match="light_tilt=200"):
        training_lights(("sky",), 3, tilt=200.0)


def test_random_lights_follow_the_named_ones():
    from methods.neural_wavelet.data import training_lights

    lights = training_lights(("sky",), 2, seed=5, random=3)
    assert [lt.name for lt in lights] == ["sky", "sky@180", "random1-5-0", "random1-5-1",
                                          "random1-5-2"]
    # Refused before any light is loaded: an unknown name is never reached.
    with pytest.raises(InvalidInputError, match="random_lights=-1"):
        training_lights(("no-such-light",), 2, random=-1)


def test_glossy_comparison_refuses_a_scene_without_glossy_materials():
    from reproductions.nw_evaluate import require_glossy

    require_glossy(_scene("glossy"))
    with pytest.raises(InvalidInputError, match="has no glossy material"):
        require_glossy(_scene("diffuse"))


# --- must hold (issue #19): the hash grid beats vertex features and SH on held-out lights -----

#: The must-hold's config (scripts/nw_holdout_experiment.py's overrides apply to it): 2048
#: training images (256 views × 8 lights), drawn from the seven named training lights at 32
#: turns each plus 224 seeded procedural environments, 512-spp targets, 16000 steps, two HDRIs
#: held out. With 128 images and 2000 steps (train_views 64, lights_per_view 2, no random
#: lights) the hash grid beat vertex features at seeds 0-3 but the SH baseline only at 1-3.
COMPARISON = {
    "cubemap": 8, "light_terms": 64, "train_terms": 96, "levels": 8, "log2_table": 14,
    "feature_dim": 16, "vertex_features": 16, "hidden": 64, "reflect_degree": 4,
    "train_lights": ("sky", "purple", "city", "courtyard", "forest", "interior", "studio"),
    "heldout_lights": ("sunrise", "sunset"), "light_rotations": 32, "random_lights": 224,
    "train_views": 256, "lights_per_view": 8, "train_width": 48, "train_height": 36,
    "train_spp": 512, "batch_pixels": 1024, "steps": 16000, "direct": "none", "seed": 0,
}
#: Samples of the must-hold's indirect reference. On the reduced four-animals an independent
#: 4096-spp Mitsuba render scores 32.85 (sunrise) and 40.72 dB (sunset) against it, far above
#: every method here. (At 256 spp the sphere over plane's sunrise reference scored below its
#: SH baseline.)
HOLDOUT_REFERENCE_SPP = 4096
#: SH baseline bands: 3, the most llvmpipe's 128 MiB storage block holds for the RGB (bounce)
#: matrices of four-animals' ~85k vertices (4 bands need 248 MiB).
MUST_HOLD_SH_BANDS = 3


def must_hold_scene():
    """The issue's glossy stand-in scene, reduced: glossy four-animals (lacquered animals, gold
    Phong ring s 400, glossy ground) with the ground 8×8, the first 3 views of its training
    orbit (training cameras are jittered away from them)."""
    return get_scene("four-animals", variant="glossy", trajectory="near",
                     ground_subdivisions=8).with_views(3)


@pytest.mark.slow
@pytest.mark.assets
def test_hashgrid_beats_vertex_features_and_sh_on_held_out_lights():
    """Held-out sunrise and sunset, indirect masked PSNR, 64×48, on the glossy stand-in.

    Measured from an empty cache on a 2-core AMD EPYC (two torch threads, 2 h 02 min in all:
    each 16000-step training ~26 min at ~10k pixels/s, the 2048 Mitsuba training images, the
    4096-spp references and the SH baseline the other ~69 min): black
    14.03, SH 23.28, hash grid 25.93, vertex features 22.17 dB, so the margins are 2.6 and
    3.8 dB against the 0.5 asked. Training is not reproducible across torch thread counts:
    scripts/nw_holdout_experiment.py with one thread per run (2-core Xeon) gave 25.66 and
    22.80. Seed 1 (the script, one thread per run, AMD EPYC): hash grid 26.13, vertex
    features 20.53.

    On the earlier reduced case, a glossy sphere over a glossy plane (Phong 32 and 128; commit
    01fbe87 has its measurements), the hash grid never beat a 5-band SH baseline (32.46 dB;
    at best 32.40 with 2048 images, seeds spreading 1.5 dB): its indirect light is
    low-frequency, which 5-band SH represents well. The paper's advantage is on sharp glossy
    transport like the gold ring's, which low-order SH blurs.
    """
    from reproductions.nw_evaluate import indirect_metrics, sh_baseline

    cls = METHODS.get("neural-wavelet")
    scene = must_hold_scene()
    width, height, heldout = 64, 48, COMPARISON["heldout_lights"]

    class Black:  # the trivial image every variant must clearly beat
        def indirect(self, view, light):
            return np.zeros((height, width, 3), np.float32)

    def held_out_psnr(renderer) -> float:
        return float(np.mean([m["psnr_masked"] for name in heldout
                              for m in indirect_metrics(renderer, scene, get_light(name),
                                                        scene.trajectory.views, width=width,
                                                        height=height,
                                                        spp=HOLDOUT_REFERENCE_SPP)]))

    psnr = {"black": held_out_psnr(Black())}
    baseline = sh_baseline(scene, width=width, height=height, bounces=1,
                           sh_bands=MUST_HOLD_SH_BANDS)
    try:
        psnr["sh"] = held_out_psnr(baseline)
    finally:
        baseline.release()
    for features in ("hashgrid", "vertex"):  # same data, same steps and batch for both
        config = cls.make_config({**COMPARISON, "features": features}, profile="quick")
        artifact = load_or_precompute(cls, scene, config, progress=False)
        meta = artifact.meta
        print(f"{features}: {meta['data_images']} images, train {meta['train_s']:.1f} s, "
              f"{meta['pixels_per_s']:.0f} pixels/s, loss {meta['loss_first']:.4g} -> "
              f"{meta['loss_last']:.4g}, bytes {meta['bytes']}")
        assert meta["loss_last"] < 0.5 * meta["loss_first"]
        renderer = cls.renderer(scene, artifact, config, width=width, height=height)
        try:
            psnr[features] = held_out_psnr(renderer)
        finally:
            renderer.release()
    print(f"held-out indirect masked PSNR: {psnr}")
    assert psnr["sh"] > psnr["black"] + 3.0, psnr  # the SH baseline is a real one
    assert psnr["hashgrid"] > psnr["vertex"] + 0.5, psnr
    assert psnr["hashgrid"] > psnr["sh"] + 0.5, psnr


def test_sh_baseline_indirect_is_the_bounce_light_sloan_matrix_adds():
    from reproductions.nw_evaluate import sh_baseline

    light = get_light("sky")
    # A lone plane reflects nothing onto itself: its SH indirect is zero to rounding. With a
    # sphere over it, the bounce matrices add light (the sphere lights the ground below it).
    lone = get_scene("plane", variant="glossy", subdivisions=4).with_views(1)
    scene = _scene()
    sums = {}
    for name, s in (("lone", lone), ("pair", scene)):
        baseline = sh_baseline(s, width=40, height=30, sh_bands=3, rays_per_point=64)
        try:
            view = s.trajectory.views[0]
            indirect = baseline.indirect(view, light)
            full = baseline.full.render(view, light)
        finally:
            baseline.release()
        assert indirect.shape == (30, 40, 3) and np.isfinite(indirect).all()
        sums[name] = float(np.abs(indirect).sum() / max(np.abs(full).sum(), 1e-12))
    assert sums["lone"] < 1e-4 and sums["pair"] > 1e-3, sums
