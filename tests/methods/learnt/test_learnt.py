"""Learnt transfer (thesis ch. 4): analytic cases, renderer agreement, bad input, runner smoke."""

from __future__ import annotations

import math

import numpy as np
import pytest

import methods.learnt  # noqa: F401 - registers "learnt"
from methods.learnt.model import LearntModel
from methods.learnt.network import NetworkSpec, encode, projection_canvas, train_network
from prtbench.api.errors import InvalidInputError
from prtbench.api.method import METHODS, load_or_precompute
from prtbench.scene.model import Material, Scene, SceneObject, Trajectory, View
from prtbench.scene.registry import get_scene
from prtbench.transport.lights import get_light

#: A small but well-trained network for analytic scenes (seconds on 2 cores).
SMALL = {"samples": 8000, "rays_per_point": 128, "heldout_vertices": 400, "heldout_rays": 256,
         "hidden": 32, "layers": 3, "pe_frequencies": 3, "epochs": 25, "batch_size": 512,
         "learning_rate": 5e-3}


@pytest.fixture(scope="module", autouse=True)
def _one_torch_thread():
    # The 2 cores are shared with other jobs: one torch thread trains these small networks
    # faster than two threads contending for them.
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


def _artifact(scene, **overrides):
    cls = METHODS.get("learnt")
    config = cls.make_config({**SMALL, **overrides}, profile="smoke")
    cls.validate(scene, config)
    return cls, config, load_or_precompute(cls, scene, config, progress=False)


def _render(scene, light, *, width=64, height=48, **overrides):
    cls, config, artifact = _artifact(scene, **overrides)
    renderer = cls.renderer(scene, artifact, config, width=width, height=height)
    try:
        return renderer.render(scene.trajectory.views[0], get_light(light)), artifact
    finally:
        renderer.release()


def _sphere_scene(kd=0.5):
    base = get_scene("sphere-over-plane", radius=0.5, height=1.0)
    sphere = max(base.objects, key=lambda o: o.mesh.n_vertices)  # the sphere, not the plane
    view = View(eye=(0.0, 1.0, 3.0), target=(0.0, 1.0, 0.0), fov_y=40.0)
    return Scene("furnace-sphere", [SceneObject("sphere", sphere.mesh, Material(kd=(kd, kd, kd)))],
                 trajectory=Trajectory((view,)), exposure=1.0)


def test_furnace_white_light_convex_sphere_is_albedo_within_the_network_error():
    # Unoccluded convex object, L = 1: B = kd/π · T_0 · √(4π) = kd (T_0 = √π/2).
    image, artifact = _render(_sphere_scene(0.5), "white")
    covered = image[..., 0] > 0
    assert covered.sum() > 300
    error = np.abs(image[covered] - 0.5) / 0.5
    # The DC held-out error on the vertices bounds the image error on average.
    dc = artifact.meta["heldout_vertices"]["dc_relative"]
    assert dc < 0.01, artifact.meta["heldout_vertices"]
    assert error.mean() < 2 * dc + 2e-3 and error.max() < 0.03, (error.mean(), error.max(), dc)
    assert np.all(image[~covered] == 0)


def test_shadow_below_a_sphere_matches_the_unoccluded_fraction():
    # Ground point below a sphere of radius r at height h: cosine-weighted unoccluded fraction
    # 1 − (r/h)² (DESIGN §13). With L = 1, B/kd = T_0·√(4π)/π is that fraction.
    scene = get_scene("sphere-over-plane", radius=0.5, height=1.0).with_views(1)
    _, _, artifact = _artifact(scene)
    model = LearntModel.from_arrays(artifact.arrays)
    points = np.array([[0.0, 0.0, 0.0], [3.5, 0.0, 3.5]], np.float32)
    normals = np.array([[0.0, 1.0, 0.0]] * 2, np.float32)
    transfer = model.predict(points, normals, np.zeros(2, int))
    fraction = transfer[:, 0] * math.sqrt(4 * math.pi) / math.pi
    assert fraction[0] == pytest.approx(1 - 0.25, abs=0.03)
    assert fraction[1] == pytest.approx(1.0, abs=0.03)  # far from the sphere: unoccluded


def test_tanh_targets_never_clip_and_heldout_is_reported():
    _, config, artifact = _artifact(_sphere_scene())
    meta = artifact.meta
    assert meta["target_max_abs_mapped"] == pytest.approx(config.target_margin, abs=1e-5)
    assert meta["heldout_max_abs_tanh"] < 1.0
    assert 0.0 <= meta["heldout_unreachable_fraction"] < 0.01
    assert meta["heldout_vertices"]["points"] == 400
    assert meta["glsl_hardcoded_floats"] < config.glsl_weight_limit


@pytest.fixture(scope="module")
def plants_glossy():
    """Plants (glossy) with a 2-cell grid partition: both renderers pick a network per pixel."""
    scene = get_scene("plants", variant="glossy").with_views(1)
    cls, config, artifact = _artifact(scene, partition="grid", grid_cells=(2, 1, 1), epochs=3,
                                      samples=8000, rays_per_point=32, heldout_vertices=200,
                                      heldout_rays=32)
    return scene, cls, config, artifact


@pytest.mark.parametrize("product", ["tpfl", "tp"])
def test_glsl_and_torch_renderers_agree_on_covered_pixels(plants_glossy, product):
    from prtbench.api.config import with_overrides

    scene, cls, config, artifact = plants_glossy
    assert LearntModel.from_arrays(artifact.arrays).partition.n_groups == 2
    images = {}
    for renderer_kind in ("glsl", "torch"):
        cfg = with_overrides(config, {"renderer": renderer_kind, "product": product})
        renderer = cls.renderer(scene, artifact, cfg, width=96, height=72)
        try:
            images[renderer_kind] = renderer.render(scene.trajectory.views[0], get_light("sky"))
            assert renderer.memory_bytes() > 0
        finally:
            renderer.release()
    glsl_image, torch_image = images["glsl"], images["torch"]
    covered = torch_image.max(axis=-1) > 0
    assert covered.sum() > 1000
    assert np.array_equal(glsl_image.max(axis=-1) > 0, covered)
    diff = np.abs(glsl_image - torch_image)[covered]
    assert np.all(diff <= 1e-3 * np.abs(torch_image[covered]) + 1e-6), diff.max()


def test_too_large_network_for_glsl_fails_before_any_work():
    from prtbench.bench.job import Job
    from prtbench.bench.runner import prepare

    with pytest.raises(InvalidInputError) as info:
        prepare(Job(method="learnt", scene="plants", profile="smoke",
                           overrides={"hidden": 256}))
    message = str(info.value)
    assert "glsl_weight_limit" in message and "renderer=torch" in message
    # The torch path takes the same network.
    prepare(Job(method="learnt", scene="plants", profile="smoke",
                       overrides={"hidden": 256, "renderer": "torch"}))


def test_bad_knobs_are_rejected():
    from prtbench.bench.job import Job
    from prtbench.bench.runner import prepare

    for overrides, text in (({"hidden": 30}, "multiples of 4"),
                            ({"loss": "huber"}, "projection"),
                            ({"grid_cells": "2,2"}, "grid_cells")):
        with pytest.raises(InvalidInputError, match=text):
            prepare(Job(method="learnt", scene="plants", profile="smoke",
                               overrides=overrides))


def test_nan_training_data_is_rejected_before_training(monkeypatch):
    import torch

    def no_training(*args, **kwargs):
        raise AssertionError("the optimiser must not be built for bad data")

    monkeypatch.setattr(torch.optim, "Adam", no_training)
    spec = NetworkSpec(2, 8, 1, 0, 0.01)
    points = np.zeros((10, 3), np.float32)
    normals = np.tile(np.float32([0, 0, 1]), (10, 1))
    targets = np.zeros((10, 4), np.float32)
    targets[7, 2] = np.nan
    with pytest.raises(InvalidInputError, match="1 of 10 rows contain NaN"):
        train_network(points, normals, targets, spec=spec, progress=False)


def test_positional_encoding_and_projection_loss_are_what_they_say():
    import torch

    x = torch.tensor([[0.25, 0.0, 0.0, 0.0, 0.0, 1.0]])
    e = encode(torch, x[:, :3], x[:, 3:], 2)[0].numpy()
    assert e.shape == (6 + 24,)
    assert e[6] == pytest.approx(math.sin(math.pi * 0.25))  # f = 0, sin, x
    assert e[6 + 6 + 5] == pytest.approx(math.cos(math.pi))  # f = 0, cos, n.z
    assert e[18] == pytest.approx(math.sin(2 * math.pi * 0.25))  # f = 1, sin, x
    # Projection loss of a DC offset δ: the canvas sees δ·Y_00 = δ/√(4π) everywhere.
    canvas = projection_canvas(8, 3)
    delta = np.zeros(9, np.float32)
    delta[0] = 0.3
    assert np.mean((canvas @ delta) ** 2) == pytest.approx(0.09 / (4 * math.pi), rel=1e-5)


@pytest.mark.parametrize("loss", ["l1", "l2", "projection"])
def test_every_loss_trains(loss):
    rng = np.random.default_rng(0)
    points = rng.uniform(-1, 1, (2048, 3)).astype(np.float32)
    normals = np.tile(np.float32([0, 1, 0]), (2048, 1))
    targets = np.stack([np.sin(2 * points[:, 0]), points[:, 2], 0.5 * points[:, 1] ** 2,
                        np.full(2048, 0.3)], 1).astype(np.float32)
    spec = NetworkSpec(2, 16, 2, 2, 0.01)
    net = train_network(points, normals, targets, spec=spec, loss=loss, batch_size=256,
                        epochs=15, learning_rate=1e-2, progress=False)
    from methods.learnt.network import predict

    error = np.abs(predict(net, spec, points, normals) - targets).mean()
    assert error < 0.25 * np.abs(targets - targets.mean(0)).mean(), (loss, error)
    assert net.stats["loss"] == loss


def test_extremes_stay_finite():
    image, _ = _render(_sphere_scene(), "sun", hidden=4, layers=1, pe_frequencies=0, epochs=1)
    assert np.all(np.isfinite(image))
    image, _ = _render(_sphere_scene(), "sun", pe_frequencies=16, sh_bands=1, epochs=1,
                       renderer="torch")
    assert np.all(np.isfinite(image))


def test_smoke_through_the_runner():
    from prtbench.bench.regress import case_job, gate
    from prtbench.bench.submit import run
    from prtbench.store.results import load

    job = case_job("learnt")  # the regression case, smoke profile
    summary = run(job, store=True, progress=False, echo=False).summary
    assert len(summary.views) == 1
    # Beats the flat, half-bright and unshadowed (visibility=False) images of its reference.
    assert not gate(job, summary.mean_metrics())
    assert summary.memory_bytes > 0 and summary.views[0].frame_ms > 0
    rows = load(method="learnt")
    assert len(rows) >= 1 and rows["run_id"].iloc[-1] == summary.run_id


def test_sample_counts_per_object_follow_the_balance():
    from methods.learnt.data import object_counts

    scene = get_scene("plants")
    areas = np.array([o.mesh.triangle_areas().sum() for o in scene.objects])
    for balance in (0.0, 0.5, 1.0):
        counts = object_counts(scene, 100_000, balance)
        assert counts.sum() == 100_000
        want = areas ** (1 - balance) / np.sum(areas ** (1 - balance)) * 100_000
        assert np.all(np.abs(counts - want) <= 1)


def test_heldout_vertices_are_never_training_points():
    from scipy.spatial import cKDTree

    from methods.learnt.data import heldout_samples, training_samples

    scene = get_scene("sphere-over-plane", radius=0.5, height=1.0)
    for balance in (0.0, 0.5):
        train = training_samples(scene, samples=5000, rays_per_point=4, bands=2, seed=0,
                                 vertex_margin=1e-3, object_balance=balance, progress=False)
        held = heldout_samples(scene, max_vertices=300, rays_per_point=4, bands=2, seed=1,
                               progress=False)
        distance, _ = cKDTree(train.points).query(held.points)
        assert distance.min() > 1e-5
        assert len(held) == 300 and held.transfer.shape == (300, 4)


def test_cached_training_data_follows_the_transfer_code_version(monkeypatch):
    # Training points and networks are cached by geometry; a new core TRANSFER_VERSION must
    # give them new keys too, or a transfer fix would keep serving networks fitted to the bug.
    import prtbench.transport.transfer
    from methods.learnt.data import geometry_key

    scene = get_scene("sphere-over-plane", radius=0.5, height=1.0)
    before = geometry_key(scene)
    version = prtbench.transport.transfer.TRANSFER_VERSION
    monkeypatch.setattr(prtbench.transport.transfer, "TRANSFER_VERSION", version + 1)
    assert geometry_key(scene) != before


#: Plants at half the `quick` training size: enough for the width and encoding effects of
#: table 4.1 and figure 4.13 to stand well clear of training noise (~30 s on 2 cores).
PLANTS_TRAINING = {"samples": 100_000, "rays_per_point": 128, "heldout_vertices": 4000,
                   "heldout_rays": 256, "epochs": 40, "batch_size": 4096, "learning_rate": 3e-3,
                   "object_balance": 0.5, "sh_bands": 4, "layers": 4}


@pytest.mark.slow  # four trainings (~45 s); make test keeps the learnt smoke run and its regression gate
def test_wider_networks_and_positional_encoding_lower_the_heldout_error_on_plants():
    # The thesis's two learning claims on held-out transfer (surface points never trained on):
    # k = 128 beats k = 64 (table 4.1) and 6 encoding frequencies beat raw (p, n) (fig. 4.13).
    # Measured at this size: relative RMS 0.136 (k=64, PE), 0.101 (k=128, PE), 0.235 (k=64,
    # no PE). At 40k points x 12 epochs the encoding's gain shrinks to 8 %: it needs data.
    from methods.learnt.model import train_model

    scene = get_scene("plants")
    cls = METHODS.get("learnt")
    error = {}
    for hidden, frequencies in ((64, 6), (128, 6), (64, 0)):
        config = cls.make_config({**PLANTS_TRAINING, "hidden": hidden,
                                  "pe_frequencies": frequencies}, profile="quick")
        _, stats = train_model(scene, config, progress=False)
        assert stats["target_max_abs_mapped"] < 1.0  # tanh never clips the scaled targets
        error[hidden, frequencies] = stats["heldout_surface"]["relative_rms"]
    assert error[128, 6] < 0.9 * error[64, 6], error
    assert error[64, 6] < 0.75 * error[64, 0], error
