"""Learnt transfer on SDF scenes (thesis §4.2.2): furnace, renderer agreement, convergence,
bad input and a runner smoke test."""

from __future__ import annotations

import math

import numpy as np
import pytest

import methods.learnt.sdf as learnt_sdf  # registers "learnt-sdf"
from prtbench.api.config import with_overrides
from prtbench.api.errors import InvalidInputError
from prtbench.api.method import METHODS, load_or_precompute
from prtbench.scene.model import Material, Scene, Trajectory, View
from prtbench.transport.lights import get_light
from prtbench.transport.sdf import Plane, SdfSurface, Sphere, sdf_scene_objects, union

#: Tiny training runs (seconds on one core).
TINY = {"samples": 3000, "rays_per_point": 64, "heldout_points": 400, "heldout_rays": 256,
        "hidden": 16, "layers": 2, "pe_frequencies": 3, "epochs": 20, "batch_size": 512,
        "learning_rate": 5e-3}

RADIUS, CENTRE_Y = 0.5, 1.0


@pytest.fixture(scope="module", autouse=True)
def _one_torch_thread():
    # The 2 cores are shared: one torch thread trains these tiny networks ~4x faster than two.
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


def _sdf_scene(*, ground: bool, kd: float = 0.5, glossy: bool = False) -> Scene:
    """A sphere of radius 0.5 centred at y = 1, alone (convex) or over a ground plane."""
    sphere_id = 1 if ground else 0
    sphere = Sphere(RADIUS, material=sphere_id).translate(0.0, CENTRE_Y, 0.0)
    sphere_material = (Material(kd=(kd, kd, kd), ks=(0.3, 0.3, 0.3), shininess=32.0, name="ball")
                       if glossy else Material(kd=(kd, kd, kd), name="ball"))
    if ground:
        root = union(Plane((0.0, 1.0, 0.0), 0.0, material=0), sphere)
        bounds = ((-2.0, -0.05, -2.0), (2.0, 1.6, 2.0))
        materials = (Material(kd=(0.5, 0.45, 0.4), name="ground"), sphere_material)
    else:
        root, bounds, materials = sphere, ((-0.6, 0.4, -0.6), (0.6, 1.6, 0.6)), (sphere_material,)
    surface = SdfSurface(root, bounds, materials, name="test-sdf-sphere")
    view = View(eye=(0.0, 1.6, 3.2), target=(0.0, 0.8, 0.0), fov_y=40.0)
    scene = Scene("test-sdf-sphere", sdf_scene_objects(surface, resolution=40),
                  trajectory=Trajectory((view,)), exposure=1.0)
    scene.sdf = surface
    return scene


def _artifact(scene, **overrides):
    cls = METHODS.get("learnt-sdf")
    config = cls.make_config({**TINY, **overrides}, profile="smoke")
    cls.validate(scene, config)
    return cls, config, load_or_precompute(cls, scene, config, progress=False)


def _render(cls, scene, artifact, config, light, *, width=80, height=60):
    renderer = cls.renderer(scene, artifact, config, width=width, height=height)
    try:
        return renderer.render(scene.trajectory.views[0], get_light(light)), renderer.memory_bytes()
    finally:
        renderer.release()


def test_furnace_white_light_convex_sdf_is_albedo():
    # Convex sphere, L = 1: B = kd/π · √(4π) · T_0 with T_0 = √π/2 everywhere, so B = kd. T_0 is
    # a constant target, which the output map reproduces exactly (half-range 1e-6).
    scene = _sdf_scene(ground=False, kd=0.5)
    cls, config, artifact = _artifact(scene, hidden=8, layers=1, pe_frequencies=0, epochs=2,
                                      samples=1000)
    dc = artifact.meta["heldout"]["dc_relative"]
    assert dc < 1e-5, artifact.meta["heldout"]
    image, memory = _render(cls, scene, artifact, config, "white")
    covered = image.max(axis=-1) > 0
    error = np.abs(image[covered] - 0.5) / 0.5
    assert error.max() < 2 * dc + 1e-5, (error.max(), dc)
    assert np.all(image[~covered] == 0)
    assert memory > 0
    # Silhouette: the sphere's angular radius asin(r/d) against the pixel count it covers.
    view = scene.trajectory.views[0]
    offset = np.asarray(view.eye) - [0.0, CENTRE_Y, 0.0]
    d = float(np.linalg.norm(offset))
    half = math.asin(RADIUS / d)
    # Area of the projected disc on the image plane (z = 1) is about π·tan²(half) (the sphere is
    # near the image centre, where the perspective stretch is < 1%).
    pixel = 2 * math.tan(math.radians(view.fov_y) / 2) / 60
    expected = math.pi * math.tan(half) ** 2 / pixel**2
    assert covered.sum() == pytest.approx(expected, rel=0.05)


def test_one_band_renders_glossy_materials_diffusely():
    # Issue #15 (stability, sh_bands=1): with one band the Phong lobe's only coefficient g_0 is
    # independent of s, the shader compiles material_shininess out, and writing it raised
    # KeyError. With one band the convex sphere's H is its constant H_0 under the white light, and
    # the specular term reduces to its band-0 constant: one colour, brighter than kd alone.
    scene = _sdf_scene(ground=False, kd=0.5, glossy=True)
    cls, config, artifact = _artifact(scene, sh_bands=1, hidden=8, layers=1, pe_frequencies=0,
                                      epochs=2, samples=1000)
    image, _ = _render(cls, scene, artifact, config, "white")
    covered = image.max(axis=-1) > 0
    assert np.isfinite(image).all() and covered.sum() > 100
    values = image[covered]
    assert np.ptp(values, axis=0).max() < 1e-3 * values.max()  # constant over the sphere
    assert values.mean() > 0.5  # kd = 0.5 plus the specular band-0 term


@pytest.fixture
def glossy_ground():
    # Function-scoped so that it runs inside the per-test cache isolation of conftest.py; the
    # second parametrisation loads the trained artifact from that session cache.
    scene = _sdf_scene(ground=True, glossy=True)
    cls, config, artifact = _artifact(scene, epochs=4)
    return scene, cls, config, artifact


@pytest.mark.parametrize("product", ["tpfl", "tp"])
def test_glsl_and_torch_renderers_agree_on_covered_pixels(glossy_ground, product):
    scene, cls, config, artifact = glossy_ground
    images = {}
    for kind in ("glsl", "torch"):
        cfg = with_overrides(config, {"renderer": kind, "product": product})
        images[kind], memory = _render(cls, scene, artifact, cfg, "sky", width=96, height=72)
        assert memory > 0
    glsl_image, torch_image = images["glsl"], images["torch"]
    covered = torch_image.max(axis=-1) > 0
    assert covered.sum() > 2000  # ground and sphere
    assert np.array_equal(glsl_image.max(axis=-1) > 0, covered)
    diff = np.abs(glsl_image - torch_image)[covered]
    assert np.all(diff <= 1e-3 * np.abs(torch_image[covered]) + 1e-6), diff.max()


def test_more_samples_and_a_wider_network_lower_the_heldout_error():
    # The shadowed transfer of a sphere over a plane (held-out points, another seed).
    scene = _sdf_scene(ground=True)
    cls = METHODS.get("learnt-sdf")

    def heldout(**overrides):
        config = cls.make_config({**TINY, "pe_frequencies": 2, "epochs": 15, **overrides},
                                 profile="smoke")
        return learnt_sdf.train_sdf_model(scene, config, progress=False)[2]["heldout"]["mae"]

    small = heldout(samples=300, hidden=8)
    more_samples = heldout(samples=3000, hidden=8)
    wider = heldout(samples=3000, hidden=32)
    assert more_samples < 0.8 * small, (small, more_samples)
    assert wider < 0.8 * more_samples, (more_samples, wider)


def test_mesh_scenes_and_bad_knobs_are_rejected_before_any_work():
    from prtbench.bench.job import Job
    from prtbench.bench.runner import prepare

    with pytest.raises(InvalidInputError) as info:
        prepare(Job(method="learnt-sdf", scene="plane", profile="smoke"))
    message = str(info.value)
    assert "'plane'" in message and "SDF scene" in message and "'learnt'" in message
    assert "sdf-rabbit" in message
    scene = _sdf_scene(ground=False)
    cls = METHODS.get("learnt-sdf")
    with pytest.raises(InvalidInputError, match="multiples of 4"):
        cls.validate(scene, cls.make_config({"hidden": 30}, profile="smoke"))
    with pytest.raises(InvalidInputError, match="glsl_weight_limit"):
        cls.validate(scene, cls.make_config({"hidden": 256, "layers": 4}, profile="smoke"))
    cls.validate(scene, cls.make_config({"hidden": 256, "renderer": "torch"}, profile="smoke"))
    with pytest.raises(Exception, match="partition"):
        cls.make_config({"partition": "grid"}, profile="smoke")  # a mesh-only knob


def test_smoke_through_the_runner_beats_the_trivial_images():
    from prtbench.bench.regress import case_job, gate
    from prtbench.bench.submit import run
    from prtbench.store.results import load

    job = case_job("learnt-sdf")  # sdf-car glossy, smoke
    summary = run(job, store=True, progress=False, echo=False).summary
    assert len(summary.views) == 1
    # Beats the flat, half-bright and unshadowed (visibility=False) images of its reference.
    assert not gate(job, summary.mean_metrics())
    assert summary.memory_bytes > 0 and summary.views[0].frame_ms > 0
    rows = load(method="learnt-sdf")
    assert len(rows) >= 1 and rows["run_id"].iloc[-1] == summary.run_id


def test_cached_training_data_follows_the_sdf_transfer_code_version(monkeypatch):
    # A fix in SDF transfer (a new SDF_TRANSFER_VERSION) must retire the cached training data
    # and networks built on the old transfer, not only the transfer cache itself.
    import prtbench.transport.sdf.trace as sdf_trace

    # The method's artifact (network + meta) is keyed by precompute_version, which names it.
    version = sdf_trace.SDF_TRANSFER_VERSION
    assert learnt_sdf.LearntSdf.precompute_version.endswith(f"sdf-transfer-{version}")
    scene = _sdf_scene(ground=False)
    before = learnt_sdf.geometry_key(scene)
    monkeypatch.setattr(sdf_trace, "SDF_TRANSFER_VERSION", version + 1)
    assert learnt_sdf.geometry_key(scene) != before
