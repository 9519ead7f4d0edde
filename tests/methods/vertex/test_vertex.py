"""Vertex PRT (Sloan 2002): furnace, convergence towards the path reference, extremes."""

from __future__ import annotations

import numpy as np

from prtbench.api.method import METHODS, load_or_precompute
from prtbench.scene.model import Material, Scene, SceneObject, Trajectory, View
from prtbench.scene.registry import get_scene
from prtbench.transport.lights import get_light


def _render(scene, *, light="sky", width=64, height=48, **overrides):
    cls = METHODS.get("vertex")
    config = cls.make_config(overrides, profile="quick")
    artifact = load_or_precompute(cls, scene, config, progress=False)
    renderer = cls.renderer(scene, artifact, config, width=width, height=height)
    try:
        return renderer.render(scene.trajectory.views[0], get_light(light)), renderer
    finally:
        renderer.release()


def _sphere_scene(kd=0.5):
    base = get_scene("sphere-over-plane", radius=0.5, height=1.0)
    sphere = max(base.objects, key=lambda o: o.mesh.n_vertices)  # the sphere, not the 2-tri plane
    view = View(eye=(0.0, 1.0, 3.0), target=(0.0, 1.0, 0.0), fov_y=40.0)
    return Scene("furnace-sphere", [SceneObject("sphere", sphere.mesh, Material(kd=(kd, kd, kd)))],
                 trajectory=Trajectory((view,)), exposure=1.0)


def test_furnace_white_light_closed_convex_object_is_albedo():
    # Unoccluded convex object, L = 1: B = kd/π · T_0 · √(4π) = kd · (√π/2 · 2√π)/π = kd.
    image, _ = _render(_sphere_scene(0.5), light="white", sh_bands=3, rays_per_point=64)
    covered = image[..., 0] > 0
    assert covered.sum() > 200
    assert np.allclose(image[covered], 0.5, atol=2e-3)
    assert np.all(image[~covered] == 0)


def test_memory_is_the_transfer_buffer():
    scene = _sphere_scene()
    _, renderer = _render(scene, light="white", sh_bands=4, rays_per_point=16)
    assert renderer.memory_bytes() == scene.n_vertices * 16 * 4


def _masked_psnr(image, scene, light, width=96, height=72):
    from prtbench.bench import metrics
    from prtbench.io import imageio
    from prtbench.render.reference import render_reference
    from prtbench.transport.raytrace import geometry_mask

    view = scene.trajectory.views[0]
    ref = render_reference(scene, get_light(light), view, width=width, height=height, spp=256,
                           bounces=0)
    mask = geometry_mask(scene, view, width, height)
    values = metrics.compute_metrics(imageio.display(image, exposure=scene.exposure),
                                     imageio.display(ref.image, exposure=scene.exposure), mask=mask)
    return values["psnr_masked"]


def test_psnr_rises_with_sh_bands_and_tessellation():
    scene = get_scene("sphere-over-plane", plane_subdivisions=48).with_views(1)
    psnr = {b: _masked_psnr(_render(scene, sh_bands=b, rays_per_point=1024, width=96, height=72)[0],
                            scene, "sky") for b in (2, 4, 6)}
    assert psnr[2] + 0.5 < psnr[4] < psnr[6] + 0.25, psnr
    coarse = get_scene("sphere-over-plane", plane_subdivisions=1).with_views(1)
    psnr_coarse = _masked_psnr(_render(coarse, sh_bands=6, rays_per_point=1024, width=96, height=72)[0],
                               coarse, "sky")
    assert psnr_coarse + 1.0 < psnr[6], (psnr_coarse, psnr)


def test_extremes_stay_finite():
    scene = _sphere_scene()
    image, _ = _render(scene, light="sun", sh_bands=8, rays_per_point=16)
    assert np.all(np.isfinite(image))
    image, _ = _render(scene, light="sun", sh_bands=1, rays_per_point=1)
    assert np.all(np.isfinite(image))


def test_bounces_brighten_a_concave_scene():
    scene = get_scene("sphere-over-plane", plane_subdivisions=8).with_views(1)
    direct, _ = _render(scene, sh_bands=3, rays_per_point=64)
    bounced, _ = _render(scene, sh_bands=3, rays_per_point=64, bounces=1)
    assert bounced.mean() > direct.mean() * 1.01
    assert np.all(bounced >= direct - 1e-3)


def test_smoke_run_through_the_runner_beats_the_trivial_images():
    from prtbench.bench.regress import case_job, gate
    from prtbench.bench.submit import run

    job = case_job("vertex")  # plants diffuse, 32×32 ground, sun; smoke profile
    summary = run(job, store=False, progress=False, echo=False).summary
    assert summary.memory_bytes > 0 and summary.config["visibility"] is True
    # Beats the flat, half-bright and unshadowed (visibility=False) images of its reference.
    assert not gate(job, summary.mean_metrics())
