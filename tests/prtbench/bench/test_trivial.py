"""Trivial images of a reference and the gate that compares a method with them."""

from __future__ import annotations

import math

import numpy as np
import pytest

from prtbench.api.errors import InvalidInputError
from prtbench.bench.trivial import (
    FLIP_MARGIN,
    PSNR_MARGIN_DB,
    beats,
    gate_failures,
    trivial_images,
    trivial_scores,
)
from prtbench.io.imageio import display


def _reference(seed=0):
    rng = np.random.default_rng(seed)
    ref = rng.random((24, 32, 3)) * 0.8
    mask = np.zeros((24, 32), bool)
    mask[4:20, 6:28] = True
    ref[~mask] = 0.0
    return ref, mask


def test_flat_is_the_masked_mean_display_colour_and_half_is_half_the_radiance():
    ref, mask = _reference()
    images = trivial_images(ref, mask, exposure=0.7)
    ref_d = display(ref, exposure=0.7)
    np.testing.assert_allclose(images["flat"][mask], np.broadcast_to(ref_d[mask].mean(0), (mask.sum(), 3)),
                               rtol=1e-6)
    np.testing.assert_array_equal(images["flat"][~mask], ref_d[~mask])  # the reference's background
    np.testing.assert_allclose(images["half"], display(0.5 * ref, exposure=0.7), rtol=1e-6)


def test_scores_are_the_metrics_of_those_images():
    ref, mask = _reference()
    scores = trivial_scores(ref, mask)
    ref_d = display(ref)
    flat = trivial_images(ref, mask)["flat"]
    mse = float(np.mean((flat[mask].astype(np.float64) - ref_d[mask]) ** 2))
    assert scores["flat"]["psnr_masked"] == pytest.approx(-10 * math.log10(mse), rel=1e-6)
    assert 0.0 < scores["half"]["flip_masked"] < 1.0


def test_empty_mask_and_bad_shapes_are_one_line_errors():
    ref, mask = _reference()
    with pytest.raises(InvalidInputError, match="empty"):
        trivial_images(ref, np.zeros_like(mask))
    with pytest.raises(InvalidInputError, match="accepted"):
        trivial_images(ref, mask[:, :5])


def test_beating_needs_both_margins_and_nan_never_beats():
    trivial = {"psnr_masked": 17.0, "flip_masked": 0.4}
    good = {"psnr_masked": 17.0 + PSNR_MARGIN_DB, "flip_masked": 0.4 - FLIP_MARGIN}
    assert beats(good, trivial)
    assert not beats({**good, "psnr_masked": 17.0 + 0.99 * PSNR_MARGIN_DB}, trivial)
    assert not beats({**good, "flip_masked": 0.4 - 0.99 * FLIP_MARGIN}, trivial)
    assert not beats({**good, "psnr_masked": float("nan")}, trivial)
    assert not beats({**good, "flip_masked": float("nan")}, trivial)
    lines = gate_failures({**good, "psnr_masked": 16.0}, {"flat": trivial, "half": {
        "psnr_masked": 10.0, "flip_masked": 0.9}})
    assert len(lines) == 1 and "flat image" in lines[0]
