"""Transfer textures (PRTT): furnace, TP = TPFL, the tessellation claim, bounces, extremes."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import methods.texture  # noqa: F401 - registers texture-tp / texture-tpfl
from methods.texture.renderer import TextureRenderer
from prtbench.api.errors import InvalidInputError
from prtbench.api.method import METHODS, load_or_precompute
from prtbench.bench import metrics
from prtbench.bench.submit import run
from prtbench.io import imageio
from prtbench.render.reference import render_reference
from prtbench.scene.model import Material, Scene, SceneObject, Trajectory, View
from prtbench.scene.registry import get_scene
from prtbench.transport.lights import get_light
from prtbench.transport.raytrace import Tracer, geometry_mask

QUICK = {"texture_resolution": 256, "rays_per_point": 256}


def _artifact(scene, method="texture-tpfl", **overrides):
    cls = METHODS.get(method)
    config = cls.make_config(overrides, profile="quick")
    return cls, config, load_or_precompute(cls, scene, config, progress=False)


def _render(scene, *, light="sky", width=64, height=48, method="texture-tpfl", view=None,
            **overrides):
    cls, config, artifact = _artifact(scene, method, **overrides)
    renderer = cls.renderer(scene, artifact, config, width=width, height=height)
    try:
        image = renderer.render(view or scene.trajectory.views[0], get_light(light))
        return image, {"memory_bytes": renderer.memory_bytes(),
                       "transfer_layers": getattr(renderer, "transfer_layers", None)}
    finally:
        renderer.release()


def _sphere_scene(material: Material) -> Scene:
    base = get_scene("sphere-over-plane", radius=0.5, height=1.0)
    sphere = max(base.objects, key=lambda o: o.mesh.n_vertices)
    view = View(eye=(0.0, 1.0, 3.0), target=(0.0, 1.0, 0.0), fov_y=40.0)
    return Scene("furnace-sphere", [SceneObject("sphere", sphere.mesh, material)],
                 trajectory=Trajectory((view,)))


def _psnr(image, reference, scene, mask) -> float:
    return metrics.compute_metrics(imageio.display(image, exposure=scene.exposure),
                                   imageio.display(reference, exposure=scene.exposure),
                                   mask=mask)["psnr_masked"]


# --- analytic ----------------------------------------------------------------------------------

@pytest.mark.parametrize(("method", "storage"), [("texture-tpfl", "float32"),
                                                 ("texture-tp", "float16")])
def test_furnace_white_light_convex_diffuse_sphere_is_albedo(method, storage):
    # Unoccluded convex object, L = 1: H_0 = T_0 = √π/2, B = kd/π·√(4π)·T_0 = kd.
    scene = _sphere_scene(Material(kd=(0.5, 0.5, 0.5)))
    image, facts = _render(scene, light="white", method=method, storage=storage,
                              texture_resolution=128, rays_per_point=64, sh_bands=3)
    covered = image[..., 0] > 0
    assert covered.sum() > 300
    assert np.allclose(image[covered], 0.5, atol=2e-3)  # float16: 2^-11 relative on T_0
    assert np.all(image[~covered] == 0)
    # Memory: ceil(9/4) = 3 RGBA layers of 128² texels, 4 or 2 bytes each, plus Γ (TP) or M.
    layer_bytes = 3 * 128 * 128 * 4 * (4 if storage == "float32" else 2)
    extra = 83 * 8 if method == "texture-tp" else 9 * 9 * 4 * 4  # M: std140 vec4 per (i, k)
    assert facts["memory_bytes"] == layer_bytes + extra


def test_tp_and_tpfl_of_one_artifact_agree():
    scene = get_scene("sphere-over-plane", variant="glossy").with_views(1)
    cls, config, artifact = _artifact(scene, texture_resolution=64, rays_per_point=64)
    view, light = scene.trajectory.views[0], get_light("sky")
    images = {}
    for product in ("tp", "tpfl"):
        renderer = TextureRenderer(scene, artifact, config, product=product, width=64, height=48)
        images[product] = renderer.render(view, light)
        renderer.release()
    peak = np.abs(images["tpfl"]).max()
    assert peak > 0.05
    assert np.max(np.abs(images["tp"] - images["tpfl"])) <= 1e-4 * peak


def test_depth_prepass_changes_no_pixel():
    scene = get_scene("plants", variant="glossy").with_views(1)
    cls, config, artifact = _artifact(scene, texture_resolution=128, padding=1, rays_per_point=16,
                                      sh_bands=3)
    images = []
    for prepass in (True, False):
        renderer = TextureRenderer(scene, artifact, dataclasses.replace(config, depth_prepass=prepass),
                                   product="tpfl", width=96, height=72)
        images.append(renderer.render(scene.trajectory.views[0], get_light("sky")))
        renderer.release()
    assert (images[0].max(-1) > 0).sum() > 1000
    assert np.array_equal(images[0], images[1])


# --- convergence: the PRTT claim ----------------------------------------------------------------

def _ground_masks(scene, view, width, height):
    tracer = Tracer.from_scene(scene)
    origins, dirs = view.primary_rays(width, height)
    face = tracer.first_hit(origins.reshape(-1, 3), dirs.reshape(-1, 3)).face.reshape(height, width)
    obj = np.where(face >= 0, tracer.object_of_face[np.maximum(face, 0)], -1)
    return obj >= 0, obj == 0  # geometry, ground (object 0 of plants)


def _plants_psnr(method, ground_subdivisions=1, **overrides):
    scene = get_scene("plants", variant="glossy",
                      ground_subdivisions=ground_subdivisions).with_views(1)
    view, width, height = scene.trajectory.views[0], 128, 96
    ref = render_reference(scene, get_light("sky"), view, width=width, height=height, spp=256)
    image, _ = _render(scene, method=method, width=width, height=height, **overrides)
    geometry, ground = _ground_masks(scene, view, width, height)
    return _psnr(image, ref.image, scene, geometry), _psnr(image, ref.image, scene, ground)


def test_transfer_textures_beat_vertex_tpfl_on_a_two_triangle_ground():
    # PRTT Fig. 4: on the minimal ground, per-vertex transfer cannot hold the leaves' shadows.
    pytest.importorskip("methods.vertex.glossy")
    texture_all, texture_ground = _plants_psnr("texture-tpfl", **QUICK)
    vertex_all, vertex_ground = _plants_psnr("vertex-tpfl", rays_per_point=256)
    # Measured: 25.1 vs 19.5 dB over geometry, 28.5 vs 20.7 dB on the ground.
    assert texture_all >= vertex_all + 5.0, (texture_all, vertex_all)
    assert texture_ground >= vertex_ground + 5.0, (texture_ground, vertex_ground)


@pytest.mark.slow
def test_vertex_tpfl_on_a_dense_ground_closes_the_gap():
    # PRTT Fig. 4, third row: 512² quads (524k ground triangles) bring vertex-tpfl's ground to
    # the texture's quality; the plants themselves stay per-vertex, so only the ground is
    # compared (measured: 28.7 vs 28.5 dB; over all geometry 22.4 vs 25.1 dB).
    pytest.importorskip("methods.vertex.glossy")
    _, texture_ground = _plants_psnr("texture-tpfl", **QUICK)
    _, vertex_ground = _plants_psnr("vertex-tpfl", ground_subdivisions=512, rays_per_point=256)
    assert vertex_ground >= texture_ground - 2.0, (vertex_ground, texture_ground)


# --- interreflections (PRTT §4.2) ------------------------------------------------------------

def test_one_bounce_textures_approach_the_one_bounce_reference():
    scene = get_scene("cornell", variant="diffuse").with_views(1)
    view, light, width, height = scene.trajectory.views[0], get_light("sky"), 64, 48
    mask = geometry_mask(scene, view, width, height)
    refs = [render_reference(scene, light, view, width=width, height=height, spp=256, bounces=b)
            for b in (0, 1)]
    config = {"texture_resolution": 64, "rays_per_point": 128}
    direct, _ = _render(scene, width=width, height=height, **config)
    bounced, facts = _render(scene, width=width, height=height, bounces=1, **config)
    # Measured: 17.5 dB (one bounce) vs 14.0 dB (zero bounces) against the one-bounce reference
    # (SH-truncated light through the skylight bounds both).
    assert _psnr(bounced, refs[1].image, scene, mask) > _psnr(direct, refs[1].image, scene, mask) + 2.0
    # Interreflection adds light (up to SH ringing: where the truncated light makes a surface's
    # direct radiance slightly negative, so is its reflection), about as much as the path
    # tracer's second bounce (measured: +18.0 % against +20.7 %).
    assert (bounced - direct).min() > -2e-3 * direct.max()
    gain = bounced[mask].mean() / direct[mask].mean()
    reference_gain = refs[1].image[mask].mean() / refs[0].image[mask].mean()
    assert abs(gain - reference_gain) < 0.05, (gain, reference_gain)
    # One extra RGB texture array: ceil(3·25/4) = 19 RGBA32F layers per bounce, 7 for T_0.
    assert facts["memory_bytes"] == (7 + 19) * 64 * 64 * 16 + 25 * 25 * 4 * 4  # M: std140 vec4 per (i, k)


def test_bounce_textures_are_baked_for_one_light():
    scene = get_scene("cornell", variant="diffuse").with_views(1)
    cls, config, artifact = _artifact(scene, texture_resolution=64, rays_per_point=16,
                                      sh_bands=2, bounces=1)
    assert artifact.meta["bounce_light"] == "sky"
    renderer = cls.renderer(scene, artifact, config, width=32, height=24)
    try:
        with pytest.raises(InvalidInputError, match="bounce_light=white"):
            renderer.render(scene.trajectory.views[0], get_light("white"))
        assert np.all(np.isfinite(renderer.render(scene.trajectory.views[0], get_light("sky"))))
    finally:
        renderer.release()
    _, _, white = _artifact(scene, texture_resolution=64, rays_per_point=16, sh_bands=2, bounces=1,
                            bounce_light="white")
    assert white.meta["bounce_light"] == "white"
    with pytest.raises(Exception, match="unknown light"):
        cls.validate(scene, dataclasses.replace(config, bounce_light="skyy"))


# --- extremes ---------------------------------------------------------------------------------

@pytest.mark.parametrize("shininess", [1.0, 1.0e4])
def test_phong_exponent_extremes_stay_finite(shininess):
    scene = _sphere_scene(Material(kd=(0.3, 0.3, 0.3), ks=(0.6, 0.6, 0.6), shininess=shininess))
    image, _ = _render(scene, light="sun", texture_resolution=64, rays_per_point=16)
    assert np.all(np.isfinite(image)) and image.max() > 0


@pytest.mark.parametrize("method", ["texture-tp", "texture-tpfl"])
def test_eight_bands_stay_finite(method):
    scene = _sphere_scene(Material(kd=(0.3, 0.3, 0.3), ks=(0.6, 0.6, 0.6), shininess=64.0))
    image, facts = _render(scene, light="sun", method=method, width=32, height=24,
                              texture_resolution=32, padding=1, rays_per_point=16, sh_bands=8)
    assert np.all(np.isfinite(image)) and image.max() > 0
    assert facts["transfer_layers"] == 16


def test_float16_overflow_of_bounce_textures_is_an_error(tmp_path):
    blinding = tmp_path / "blinding.exr"
    imageio.write_exr(blinding, np.full((16, 32, 3), 2.0e6, np.float32))
    scene = get_scene("cornell", variant="diffuse").with_views(1)
    overrides = {"texture_resolution": 64, "rays_per_point": 16, "sh_bands": 2, "bounces": 1,
                 "bounce_light": str(blinding)}
    with pytest.raises(InvalidInputError, match="float16"):
        _artifact(scene, storage="float16", **overrides)
    _, _, artifact = _artifact(scene, storage="float32", **overrides)
    assert artifact.arrays["bounce"].max() > 65504 and np.all(np.isfinite(artifact.arrays["bounce"]))


# --- through the runner -----------------------------------------------------------------------

def test_runner_smoke_profile():
    from prtbench.bench.regress import case_job, gate

    job = case_job("texture-tpfl")  # plants glossy under the sun, smoke profile
    summary = run(job, store=False, progress=False, echo=False).summary
    view = summary.views[0]
    assert summary.config["texture_resolution"] == 128 and summary.memory_bytes > 0
    assert view.frame_ms > 0
    # Beats the flat, half-bright and unshadowed (visibility=False) images of its reference.
    assert not gate(job, summary.mean_metrics())
