"""wavelet-texture (Haar transport per atlas texel): furnace, bytes, bad input, gate, and the
decoupling from tessellation it exists for."""

from __future__ import annotations

import numpy as np
import pytest

import methods.wavelet.texture  # noqa: F401  (registers the method without a reinstall)
from prtbench.api.method import METHODS, load_or_precompute
from prtbench.cli import main
from prtbench.scene.model import Material, Scene, SceneObject, Trajectory, View
from prtbench.scene.registry import get_scene
from prtbench.transport.lights import get_light


def _renderer(scene, *, method="wavelet-texture", width=64, height=48, **overrides):
    cls = METHODS.get(method)
    config = cls.make_config(overrides, profile="quick")
    artifact = load_or_precompute(cls, scene, config, progress=False)
    return cls.renderer(scene, artifact, config, width=width, height=height), artifact


def test_furnace_white_light_closed_convex_object_is_albedo():
    base = get_scene("sphere-over-plane", radius=0.5, height=1.0)
    sphere = max(base.objects, key=lambda o: o.mesh.n_vertices)
    view = View(eye=(0.0, 1.0, 3.0), target=(0.0, 1.0, 0.0), fov_y=40.0)
    scene = Scene("furnace-sphere", [SceneObject("sphere", sphere.mesh, Material(kd=(0.5,) * 3))],
                  trajectory=Trajectory((view,)), exposure=1.0)
    # Cubemap 16 with 2×2 rays per texel: the cosine quadrature is within 0.5 % for any normal
    # (at 8 it was 2.3 % off for some).
    renderer, artifact = _renderer(scene, cubemap=16, texel_samples=2, light_terms=6,
                                   texture_resolution=64, padding=1, storage="float32")
    try:
        image = renderer.render(view, get_light("white"))
        t = renderer.transport
        assert renderer.memory_bytes() == (t.nbytes + 4 * 6 * 16 * 16  # transport + area weights
                                           + 64 * 64 * 16)  # RGBA32F incident texture
        assert artifact.meta["stored_bytes"] == t.nbytes
        assert artifact.meta["filled_texels"] > artifact.meta["covered_texels"]  # dilation ring
    finally:
        renderer.release()
    covered = image[..., 0] > 0
    assert covered.sum() > 200
    assert np.allclose(image[covered], 0.5, atol=3e-3), np.abs(image[covered] - 0.5).max()


@pytest.mark.parametrize("sets, fragment", [
    (["cubemap=12"], "cubemap=12; accepted: a power of two"),
    (["cubemap=8", "light_terms=385"], "light_terms=385 exceeds the 384"),
    (["texture_resolution=64", "padding=9"], "padding <= texture_resolution / 8"),
])
def test_bad_input_is_one_line_exit_2_and_caches_nothing(tmp_path, monkeypatch, capsys, sets,
                                                          fragment):
    cache = tmp_path / "cache"
    monkeypatch.setenv("PRTBENCH_CACHE", str(cache))
    argv = ["run", "--method", "wavelet-texture", "--scene", "sphere-over-plane", "--profile",
            "smoke", "--out", str(tmp_path / "out"), "--results", str(tmp_path / "r.sqlite")]
    status = main(argv + [x for s in sets for x in ("--set", s)])
    err = capsys.readouterr().err.strip()
    assert status == 2 and err.startswith("prtbench: error: ") and "\n" not in err, err
    assert fragment in err, err
    assert not cache.exists() or not any(p.is_file() for p in cache.rglob("*"))


def test_smoke_run_through_the_runner_beats_the_trivial_images():
    from prtbench.bench.regress import case_job, gate
    from prtbench.bench.submit import run

    job = case_job("wavelet-texture")  # plants diffuse under sun, smoke profile
    summary = run(job, store=False, progress=False, echo=False).summary
    assert summary.memory_bytes > 0 and summary.config["visibility"] is True
    assert not gate(job, summary.mean_metrics())


def test_sharp_shadows_on_a_two_triangle_ground():
    """The decoupling it exists for: on sphere-over-plane with a 2-triangle ground under `sun`,
    per-vertex wavelet transport has no vertex inside the shadow, the atlas has texels there,
    and SH transfer textures (texture-tpfl, 8 bands) blur the sun.

    Measured at 128×96, 256 spp, atlas 128²: wavelet-texture 35.5 dB, wavelet-vertex 21.9 dB,
    texture-tpfl 28.7 dB masked PSNR.
    """
    import methods.wavelet.vertex  # noqa: F401
    from prtbench.bench import metrics
    from prtbench.io import imageio
    from prtbench.render.reference import render_reference
    from prtbench.transport.raytrace import geometry_mask

    scene = get_scene("sphere-over-plane", plane_subdivisions=1).with_views(1)
    view, light = scene.trajectory.views[0], get_light("sun")
    width, height = 128, 96
    ref = render_reference(scene, light, view, width=width, height=height, spp=256, bounces=0)
    mask = geometry_mask(scene, view, width, height)
    psnr = {}
    for method, overrides in (("wavelet-texture", {"light_terms": 64, "texture_resolution": 128}),
                              ("wavelet-vertex", {"light_terms": 64}),
                              ("texture-tpfl", {"sh_bands": 8})):
        renderer, _ = _renderer(scene, method=method, width=width, height=height, **overrides)
        try:
            image = renderer.render(view, light)
        finally:
            renderer.release()
        psnr[method] = metrics.compute_metrics(
            imageio.display(image, exposure=scene.exposure),
            imageio.display(ref.image, exposure=scene.exposure), mask=mask)["psnr_masked"]
    assert psnr["wavelet-texture"] >= psnr["wavelet-vertex"] + 6.0, psnr
    assert psnr["wavelet-texture"] >= psnr["texture-tpfl"] + 3.0, psnr


def test_dilation_maps_equal_the_transfer_textures_dilation():
    from methods.common.atlas.texels import dilate
    from methods.wavelet.texture import dilation_rings

    rng = np.random.default_rng(1)
    s, r = 2, 40
    covered = rng.random((s, r, r)) < 0.02  # sparse: three rings do not fill the texture
    chart = rng.integers(0, 4, (s, r, r))
    values = rng.random((s, r, r, 3))
    expected, filled, _ = dilate(np.where(covered[..., None], values, 0.0), covered, chart,
                                 rings=3)
    image = np.where(covered[..., None], values, 0.0).reshape(-1, 3)
    rings = dilation_rings(covered, chart, rings=3)
    assert len(rings) == 3
    for targets, entry_target, sources, weights in rings:
        for c in range(3):
            image[targets, c] = np.bincount(entry_target, weights=image[sources, c] * weights,
                                            minlength=len(targets))
    assert np.allclose(image.reshape(expected.shape), expected, rtol=1e-6, atol=1e-7)
    assert covered.sum() < filled.sum() < filled.size
