"""Irradiance volume (Greger 1998): analytic probe visibility and shading, convergence with N
towards the path reference, memory, bad input, and a smoke run through the runner."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import methods.irradiance_volume.method as iv  # registers "irradiance-volume"
from prtbench.api.errors import InvalidInputError
from prtbench.api.method import METHODS, load_or_precompute
from prtbench.scene.model import Material, Scene, SceneObject, Trajectory, View
from prtbench.scene.registry import get_scene
from prtbench.transport.lights import get_light
from prtbench.transport.raytrace import Tracer
from scenes.primitives import box


def _render(scene, view, *, light="sky", width=64, height=48, **overrides):
    cls = METHODS.get("irradiance-volume")
    config = cls.make_config(overrides, profile="quick")
    artifact = load_or_precompute(cls, scene, config, progress=False)
    renderer = cls.renderer(scene, artifact, config, width=width, height=height)
    try:
        return renderer.render(view, get_light(light)), renderer.memory_bytes(), artifact
    finally:
        renderer.release()


def _plane_scene():
    scene = get_scene("plane", size=4.0)  # kd 0.5, normal +Y
    view = View(eye=(0.0, 2.5, 0.01), target=(0.0, 0.0, 0.0), fov_y=30.0)
    return dataclasses.replace(scene, trajectory=Trajectory((view,))), view


# --- analytic ---------------------------------------------------------------------------------

@pytest.mark.parametrize("bands, expected", [(1, 0.25), (2, 0.5), (3, 0.5)])
def test_white_light_over_a_ground_plane(bands, expected):
    # Probes above the ground see the upper hemisphere: V = step(ω·y). With white light R = V,
    # and Σ_i V_i C_i(+Y) against the clamped cosine C is exact once l = 1 is kept (V has no
    # even l > 0, C no odd l > 1): E = π/2 + π/2 = π, B = kd. One band keeps only π/2: B = kd/2.
    scene, view = _plane_scene()
    # Probes also see a strip of sky below the plane's rim, (padding × diagonal)/(distance to
    # the rim) radians wide: a small padding keeps that bias below the 1 % tolerance.
    image, _, artifact = _render(scene, view, light="white", sh_bands=bands, resolution=8,
                                 rays_per_probe=4096, padding=0.002)
    covered = image[..., 0] > 0
    assert covered.mean() > 0.5
    assert np.allclose(image[covered], expected, rtol=0.01), (image[covered].min(), image[covered].max())
    assert np.all(image[~covered] == 0)
    # Probes under the one-sided ground see its back side: flagged invalid.
    valid = artifact.arrays["valid"].reshape(8, 8, 8).astype(bool)
    assert not valid[2:6, :4, 2:6].any() and valid[:, 4:, :].all()


def test_probe_with_nothing_around_sees_the_whole_sphere():
    tracer = Tracer(box().positions, box().faces)
    v, back = iv.probe_visibility(tracer, np.array([[1e4, 0.0, 0.0], [0.0, -1e4, 3e3]]),
                                  bands=4, rays_per_probe=256, seed=3)
    assert np.allclose(v[:, 0], math.sqrt(4 * math.pi), rtol=1e-12)  # every ray escapes
    # Higher coefficients of a constant vanish up to the lattice's quadrature error.
    assert np.abs(v[:, 1:]).max() < 0.05
    assert np.all(back == 0)


def test_probe_over_a_plane_sees_the_upper_hemisphere():
    plane = get_scene("plane", size=2000.0).objects[0].mesh
    v, back = iv.probe_visibility(Tracer(plane.positions, plane.faces), np.array([[0.0, 0.01, 0.0]]),
                                  bands=2, rays_per_probe=1024, seed=1)
    # ∫_{y>0} Y_00 = √π; Y_1,-1 = √(3/4π)·y integrates to √(3π)/2; the others vanish.
    assert v[0, 0] == pytest.approx(math.sqrt(math.pi), rel=0.01)
    assert v[0, 1] == pytest.approx(math.sqrt(3 * math.pi) / 2, rel=0.02)
    assert abs(v[0, 2]) < 0.03 and abs(v[0, 3]) < 0.03
    assert back[0] == 0


def test_probes_inside_a_closed_box_are_black_and_flagged():
    tracer = Tracer(box().positions, box().faces)
    v, back = iv.probe_visibility(tracer, np.array([[0.0, 0.0, 0.0], [0.3, -0.2, 0.1]]),
                                  bands=3, rays_per_probe=128)
    assert np.all(v == 0) and np.all(back == 1)
    scene = Scene("box", [SceneObject("box", box(), Material(kd=(0.5, 0.5, 0.5)))])
    cls = METHODS.get("irradiance-volume")
    artifact = load_or_precompute(cls, scene, cls.make_config({"resolution": 4, "rays_per_probe": 64}),
                                  progress=False)
    valid = artifact.arrays["valid"].reshape(4, 4, 4).astype(bool)
    # The 2×2×2 inner probes are inside the box, the shell of 56 outside it.
    assert not valid[1:3, 1:3, 1:3].any() and valid.sum() == 56
    inner = artifact.arrays["visibility"].reshape(4, 4, 4, -1)[1:3, 1:3, 1:3]
    assert np.all(inner == 0)


# --- memory and layout ------------------------------------------------------------------------

@pytest.mark.parametrize("resolution, bands, precision", [(3, 2, "float32"), (5, 3, "float16"),
                                                          (4, 4, "float32")])
def test_memory_is_the_closed_form(resolution, bands, precision):
    scene, view = _plane_scene()
    _, memory, _ = _render(scene, view, light="white", resolution=resolution, sh_bands=bands,
                           precision=precision, rays_per_probe=16)
    expected = resolution**3 * bands**2 * 3 * {"float32": 4, "float16": 2}[precision] + resolution**3
    assert memory == expected == iv.memory_closed_form(resolution=resolution, sh_bands=bands,
                                                       precision=precision)


def test_float16_matches_float32():
    scene = get_scene("sphere-over-plane").with_views(1)
    view = scene.trajectory.views[0]
    full, _, _ = _render(scene, view, resolution=6, sh_bands=3, rays_per_probe=64)
    half, _, _ = _render(scene, view, resolution=6, sh_bands=3, rays_per_probe=64, precision="float16")
    assert full.max() > 0.1
    assert np.allclose(half, full, rtol=4e-3, atol=2e-3)


def test_texture_layout_places_each_coefficient():
    res, n = 3, 2
    radiance = np.arange(res**3 * n * n * 3, dtype=np.float32).reshape(res**3, n * n, 3)
    tex = iv.radiance_texture_layout(radiance, res, n)
    assert tex.shape == (n * res, res, n * res, 3)
    for x, y, z, i in [(0, 0, 0, 0), (2, 1, 0, 1), (1, 2, 2, 3), (0, 2, 1, 2)]:
        a, b = divmod(i, n)
        probe = (x * res + y) * res + z
        assert np.array_equal(tex[z + b * res, y, x + a * res], radiance[probe, i])


# --- convergence towards the path reference ---------------------------------------------------

def test_psnr_rises_with_grid_resolution():
    from prtbench.bench import metrics
    from prtbench.io import imageio
    from prtbench.render.reference import render_reference
    from prtbench.transport.raytrace import geometry_mask

    scene = get_scene("sphere-over-plane").with_views(1)
    view, light, width, height = scene.trajectory.views[0], get_light("sky"), 96, 72
    ref = render_reference(scene, light, view, width=width, height=height, spp=256)
    mask = geometry_mask(scene, view, width, height)
    psnr = {}
    for n in (4, 8, 16):
        image, _, _ = _render(scene, view, width=width, height=height, resolution=n, sh_bands=6,
                              rays_per_probe=256)
        psnr[n] = metrics.compute_metrics(imageio.display(image, exposure=scene.exposure),
                                          imageio.display(ref.image, exposure=scene.exposure),
                                          mask=mask)["psnr_masked"]
    # Measured: 28.3, 31.0, 31.6 dB (6 bands; the SH truncation bounds the gain past N = 8).
    assert psnr[4] + 1.5 < psnr[8] < psnr[16], psnr


def test_extremes_stay_finite():
    scene = get_scene("sphere-over-plane").with_views(1)
    view = scene.trajectory.views[0]
    for overrides in ({"sh_bands": 8, "resolution": 2, "rays_per_probe": 1},
                      {"sh_bands": 1, "resolution": 2, "rays_per_probe": 1, "normal_bias": 4.0}):
        image, _, _ = _render(scene, view, light="sun", **overrides)
        assert np.all(np.isfinite(image)) and image.max() > 0


# --- bad input and the runner -----------------------------------------------------------------

def test_glossy_scene_is_rejected_with_one_line():
    from prtbench.bench.job import Job
    from prtbench.bench.runner import prepare

    with pytest.raises(InvalidInputError) as info:
        prepare(Job(method="irradiance-volume", scene="sphere-over-plane", variant="glossy",
                    profile="smoke"), store=False)
    message = str(info.value)
    assert "glossy" in message and "diffuse" in message and "\n" not in message


@pytest.mark.parametrize("resolution", [1, 65, 0])
def test_resolution_outside_2_to_64_is_rejected(resolution):
    with pytest.raises(InvalidInputError, match="resolution"):
        METHODS.get("irradiance-volume").make_config({"resolution": resolution})


def test_smoke_run_through_the_runner():
    from prtbench.bench.regress import case_job, gate
    from prtbench.bench.submit import run

    job = case_job("irradiance-volume")  # plants diffuse under sky, smoke profile
    summary = run(job, store=False, progress=False, echo=False).summary
    assert len(summary.views) == 1
    # Beats the flat, half-bright and unshadowed (visibility=False) images of its reference.
    assert not gate(job, summary.mean_metrics())
    assert summary.memory_bytes == iv.memory_closed_form(resolution=8, sh_bands=3,
                                                         precision="float32")
    assert summary.config["rays_per_probe"] == 64  # the smoke profile's override


def test_random_rotations_are_proper_and_uniform():
    r = iv.random_rotations(20000, np.random.default_rng(0))
    assert np.allclose(r @ r.transpose(0, 2, 1), np.eye(3), atol=1e-12)
    assert np.allclose(np.linalg.det(r), 1.0)
    # Uniform (Haar) rotations have zero mean matrix; 20k samples: entries within ~4σ = 0.016.
    assert np.abs(r.mean(axis=0)).max() < 0.016
