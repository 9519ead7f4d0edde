"""neural-wavelet's real-time direct term: importance-sampled shadow rays and a denoiser,
checked against the furnace and the Mitsuba direct-only reference; and its place in the frame."""

from __future__ import annotations

import numpy as np
import pytest

from methods.neural_wavelet.direct import DirectLight, denoise
from methods.neural_wavelet.gbuffer import GBufferPass, pixel_rows
from prtbench.bench.metrics import compute_metrics
from prtbench.io.imageio import display
from prtbench.render.reference import render_reference
from prtbench.scene.registry import get_scene
from prtbench.transport.lights import get_light
from prtbench.transport.raytrace import geometry_mask


def _direct(scene, light, view, *, width, height, samples, seed=3):
    """Per-pixel direct light of ``view`` (H, W, 3), row 0 at the top, and the G-buffer rows."""
    gpass = GBufferPass(scene, width=width, height=height)
    try:
        gpass.draw(view)
        rows = pixel_rows(gpass.read_gl(), view.eye)
    finally:
        gpass.release()
    radiance, variance = DirectLight(scene, light_samples=samples, brdf_samples=samples,
                                     seed=seed).radiance(rows, light)
    image = np.zeros((height * width, 3), np.float32)
    image[rows["pixel"]] = radiance
    return image.reshape(height, width, 3)[::-1], rows, variance


def test_furnace_a_diffuse_plane_under_unit_radiance_reflects_its_albedo():
    # B = kd/π ∫ 1 · cos θ dω = kd over the open upper hemisphere: no occluder, no noise in
    # expectation; the mean over ~1000 pixels of 8+8 samples each lands within 1 %.
    scene = get_scene("plane", variant="diffuse", subdivisions=4).with_views(1)
    kd = np.asarray(scene.objects[0].material.kd, float).reshape(-1)[:3]
    image, rows, _ = _direct(scene, get_light("white"), scene.trajectory.views[0], width=48,
                             height=36, samples=8)
    covered = image.max(axis=-1) > 0
    assert covered.sum() > 500
    assert image[covered].mean(axis=0) == pytest.approx(kd, rel=0.01)


def test_supersampled_direct_matches_mitsubas_direct_only_reference():
    # The estimator is unbiased: shaded at 3×3 points per pixel and box-filtered like the
    # reference, it meets Mitsuba's direct-only render (sphere-over-plane, glossy, the sky's
    # sun) far above what a shadow or a highlight in the wrong place would score.
    scene = get_scene("sphere-over-plane", variant="glossy", sphere_segments=16,
                      plane_subdivisions=4).with_views(1)
    light, view, (w, h), s = get_light("sky"), scene.trajectory.views[0], (40, 30), 3
    fine, _, _ = _direct(scene, light, view, width=w * s, height=h * s, samples=32)
    ours = fine.reshape(h, s, w, s, 3).mean(axis=(1, 3))
    ref = render_reference(scene, light, view, width=w, height=h, spp=512, bounces=0).image
    mask = geometry_mask(scene, view, w, h)
    psnr = compute_metrics(display(ours, exposure=scene.exposure),
                           display(ref, exposure=scene.exposure), mask=mask,
                           names=["psnr"])["psnr_masked"]
    assert psnr > 32.0, psnr
    assert ours[mask].mean() == pytest.approx(ref[mask].mean(), rel=0.02)


def test_denoising_lowers_the_error_and_keeps_the_light():
    scene = get_scene("sphere-over-plane", variant="glossy", sphere_segments=16,
                      plane_subdivisions=4).with_views(1)
    light, view, (w, h) = get_light("sky"), scene.trajectory.views[0], (64, 48)
    noisy, rows, variance = _direct(scene, light, view, width=w, height=h, samples=2)
    clean, _, _ = _direct(scene, light, view, width=w, height=h, samples=128, seed=9)

    def flat(values, width=3):
        out = np.zeros((h * w, width), np.float32)
        out[rows["pixel"]] = np.asarray(values, np.float32).reshape(len(rows["pixel"]), width)
        return out.reshape(h, w, width)[::-1]

    covered = flat(np.ones(len(rows["pixel"])), 1)[..., 0] > 0
    depth = np.linalg.norm(rows["positions"] - np.asarray(view.eye, np.float32), axis=1)
    filtered = denoise(noisy, flat(variance, 1)[..., 0], covered=covered,
                       normals=flat(rows["normals"]), depth=flat(depth, 1)[..., 0])
    def shown(image):  # what the metrics read: exposed, tonemapped, in [0, 1]
        return display(image, exposure=scene.exposure)

    before = float(np.mean((shown(noisy) - shown(clean))[covered] ** 2))
    after = float(np.mean((shown(filtered) - shown(clean))[covered] ** 2))
    assert after < 0.5 * before, (before, after)
    assert filtered[covered].mean() == pytest.approx(noisy[covered].mean(), rel=0.03)
    assert (filtered[~covered] == 0).all()  # nothing leaks onto the background


def test_the_default_frame_holds_the_direct_term_and_no_reference_pixels():
    # The default config renders its own direct light inside the frame; only the named
    # diagnostic takes Mitsuba's, and no ranking may show that one.
    from prtbench.api.method import METHODS

    cls = METHODS.get("neural-wavelet")
    default = cls.make_config({}, profile="smoke")
    assert default.direct == "raytraced" and cls.diagnostic_reason(default) is None
    offline = cls.make_config({"direct": "offline-reference"}, profile="smoke")
    assert "reference renderer" in cls.diagnostic_reason(offline)
    # The direct knobs change the rendering only: one trained model serves all of them.
    assert cls.cache_identity(default) == cls.cache_identity(offline)
    # Its default training lights hold none of the lights the project evaluates.
    assert not {"sky", "sun", "white", "city", "studio"} & set(default.train_lights)
    quick = cls.make_config({}, profile="quick")
    assert not {"sky", "sun", "white", "city", "studio"} & set(quick.train_lights)
