"""prtbench.bench.metrics: analytic values, masking, flags and input checks."""

from __future__ import annotations

import math

import numpy as np
import pytest

from prtbench.api.errors import InvalidInputError, UnknownNameError
from prtbench.bench import metrics


def _image(seed=0, shape=(48, 64), low=0.1, high=0.8) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.uniform(low, high, size=shape + (3,))


def test_identical_images_are_perfect():
    image = _image()
    mask = np.zeros(image.shape[:2], bool)
    mask[10:30, 20:50] = True
    values = metrics.compute_metrics(image, image, mask=mask)
    for key in ("", "_masked"):
        assert values[f"mae{key}"] == 0.0
        assert values[f"rmse{key}"] == 0.0
        assert values[f"psnr{key}"] == math.inf
        assert values[f"ssim{key}"] == pytest.approx(1.0, abs=1e-12)
        assert values[f"flip{key}"] == 0.0
    assert "flip_hdr" not in values  # only with linear images


@pytest.mark.parametrize("delta", [0.05, 0.125, 0.001])
def test_constant_offset_gives_analytic_errors(delta):
    reference = _image(1)
    test = reference + delta
    values = metrics.compute_metrics(test, reference, names=["mae", "rmse", "psnr"])
    assert values["mae"] == pytest.approx(delta, abs=1e-12)
    assert values["rmse"] == pytest.approx(delta, abs=1e-12)
    assert abs(values["psnr"] - (-20.0 * math.log10(delta))) < 1e-9


def test_known_noise_level_gives_analytic_psnr():
    sigma = 0.01
    rng = np.random.default_rng(5)
    reference = np.full((256, 256, 3), 0.5)
    test = reference + rng.normal(0.0, sigma, reference.shape)  # 50 σ from the clip limits
    psnr = metrics.compute_metrics(test, reference, names=["psnr"])["psnr"]
    assert abs(psnr - 40.0) < 0.1
    assert metrics.psnr_ceiling(sigma) == pytest.approx(40.0, abs=1e-12)


def test_full_frame_values_are_the_libraries_values():
    import flip_evaluator
    from skimage.metrics import structural_similarity

    reference = _image(2)
    test = np.clip(reference + np.random.default_rng(3).normal(0, 0.05, reference.shape), 0, 1)
    values = metrics.compute_metrics(test, reference, names=["ssim", "flip"])
    ssim = structural_similarity(test, reference, channel_axis=-1, data_range=1.0)
    _, flip_mean, _ = flip_evaluator.evaluate(reference.astype(np.float32), test.astype(np.float32), "LDR")
    assert values["ssim"] == pytest.approx(ssim, abs=1e-12)
    assert values["flip"] == pytest.approx(flip_mean, rel=1e-5)
    assert 0.0 < values["flip"] < 1.0 and 0.0 < values["ssim"] < 1.0


def test_masked_metrics_ignore_pixels_outside_the_mask():
    shape = (96, 96)
    reference = _image(4, shape)
    test = np.clip(reference + np.random.default_rng(6).normal(0, 0.03, reference.shape), 0, 1)
    mask = np.zeros(shape, bool)
    mask[36:60, 30:66] = True
    # Garbage outside the mask, kept 20 px from it: SSIM's 7x7 window and FLIP's filters
    # (< 10 px at 67 ppd) read neighbours, so only per-pixel metrics could take adjacent garbage.
    garbage = np.random.default_rng(8).random(reference.shape)
    far = np.ones(shape, bool)
    far[16:80, 10:86] = False
    test_garbage, reference_garbage = test.copy(), reference.copy()
    test_garbage[far], reference_garbage[far] = garbage[far], 1 - garbage[far]
    clean = metrics.compute_metrics(test, reference, mask=mask)
    dirty = metrics.compute_metrics(test_garbage, reference_garbage, mask=mask)
    for name in metrics.LDR_METRICS:
        assert dirty[f"{name}_masked"] == pytest.approx(clean[f"{name}_masked"], rel=1e-9, abs=1e-12), name
        assert dirty[name] != pytest.approx(clean[name], rel=1e-3), name  # full frame does see it
    # Per-pixel metrics ignore even garbage right next to the mask.
    adjacent = ~mask
    test_adjacent = test.copy()
    test_adjacent[adjacent] = garbage[adjacent]
    near = metrics.compute_metrics(test_adjacent, reference, mask=mask, names=["mae", "rmse", "psnr"])
    for name in ("mae", "rmse", "psnr"):
        assert near[f"{name}_masked"] == pytest.approx(clean[f"{name}_masked"], rel=1e-12)


def test_masked_psnr_is_from_masked_mse_and_full_mask_equals_full_frame():
    reference = np.zeros((32, 32, 3))
    test = reference.copy()
    mask = np.zeros((32, 32), bool)
    mask[:8] = True  # a quarter of the pixels, each off by 0.1
    test[mask] = 0.1
    values = metrics.compute_metrics(test, reference, mask=mask, names=["psnr", "mae"])
    assert values["psnr_masked"] == pytest.approx(20.0, abs=1e-9)
    assert values["psnr"] == pytest.approx(20.0 + 10 * math.log10(4), abs=1e-9)
    assert values["mae_masked"] == pytest.approx(0.1, abs=1e-12)
    everything = metrics.compute_metrics(test + 0.2, reference + 0.3, mask=np.ones((32, 32), bool))
    for name in metrics.LDR_METRICS:
        assert everything[f"{name}_masked"] == pytest.approx(everything[name], rel=1e-12), name


def test_empty_mask_gives_nan_not_a_perfect_score():
    image = _image()
    values = metrics.compute_metrics(image, image * 0.5, mask=np.zeros(image.shape[:2], bool),
                                     names=["psnr", "ssim"])
    assert math.isnan(values["psnr_masked"]) and math.isnan(values["ssim_masked"])
    assert math.isfinite(values["psnr"])


def test_higher_is_better_flags():
    expected = {"mae": False, "rmse": False, "psnr": True, "ssim": True, "flip": False, "flip_hdr": False}
    assert {name: spec.higher_is_better for name, spec in metrics.METRICS.items()} == expected
    assert metrics.higher_is_better("psnr_masked") is True
    assert metrics.higher_is_better("flip_masked") is False
    with pytest.raises(UnknownNameError):
        metrics.higher_is_better("pnsr")


def test_bad_inputs_raise_invalid_input():
    image = _image()
    with pytest.raises(InvalidInputError, match="must both be"):
        metrics.compute_metrics(image, image[:, :-1])
    with pytest.raises(InvalidInputError, match="must both be"):
        metrics.compute_metrics(image[..., 0], image[..., 0])
    with pytest.raises(InvalidInputError, match="mask shape"):
        metrics.compute_metrics(image, image, mask=np.ones((3, 3), bool))
    with pytest.raises(InvalidInputError, match="spans"):
        metrics.compute_metrics(image * 4, image)
    with pytest.raises(InvalidInputError, match="non-finite"):
        bad = image.copy()
        bad[0, 0, 0] = np.nan
        metrics.compute_metrics(bad, image)
    with pytest.raises(UnknownNameError, match="did you mean 'psnr'"):
        metrics.compute_metrics(image, image, names=["pnsr"])
    with pytest.raises(InvalidInputError, match="flip_hdr needs"):
        metrics.compute_metrics(image, image, names=["flip_hdr"])
    with pytest.raises(InvalidInputError):
        metrics.psnr_ceiling(-0.1)


def test_flip_hdr_on_linear_images():
    reference_hdr = _image(9, (32, 32), 0.0, 4.0)
    kwargs = dict(reference_hdr=reference_hdr, names=["flip_hdr"])
    display = np.zeros((32, 32, 3))
    same = metrics.compute_metrics(display, display, test_hdr=reference_hdr, **kwargs)
    assert same["flip_hdr"] == 0.0
    worse = metrics.compute_metrics(display, display, test_hdr=reference_hdr * 1.5, **kwargs)
    much_worse = metrics.compute_metrics(display, display, test_hdr=reference_hdr * 4, **kwargs)
    assert 0.0 < worse["flip_hdr"] < much_worse["flip_hdr"] <= 1.0
    # A black reference must not reach FLIP's exposure-range check (it ends the process).
    black = metrics.compute_metrics(display, display, test_hdr=reference_hdr,
                                    reference_hdr=np.zeros_like(reference_hdr), names=["flip_hdr"])
    assert 0.0 < black["flip_hdr"] <= 1.0
    all_black = metrics.compute_metrics(display, display, test_hdr=0 * reference_hdr,
                                        reference_hdr=0 * reference_hdr, names=["flip_hdr"])
    assert all_black["flip_hdr"] == 0.0


def test_error_map_is_a_colour_image_that_grows_with_error():
    reference = _image(10)
    identical = metrics.error_map(reference, reference)
    assert identical.shape == reference.shape and identical.dtype == np.float32
    np.testing.assert_array_equal(identical, np.broadcast_to(identical[0, 0], identical.shape))  # magma(0)
    noisy = np.clip(reference + np.random.default_rng(1).normal(0, 0.2, reference.shape), 0, 1)
    coloured = metrics.error_map(noisy, reference)
    assert 0.0 <= coloured.min() and coloured.max() <= 1.0
    assert coloured.sum(-1).mean() > identical.sum(-1).mean() + 0.2


def test_psnr_ceiling_values():
    assert metrics.psnr_ceiling(0.0) == math.inf
    assert metrics.psnr_ceiling(0.1) == pytest.approx(20.0, abs=1e-12)
    assert metrics.psnr_ceiling(1e-3) == pytest.approx(60.0, abs=1e-9)
