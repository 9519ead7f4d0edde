"""Thesis figures 4.11 and 4.13 regenerate from our renders (smoke profile, procedural scenes)."""

from __future__ import annotations

import numpy as np
import pytest

from prtbench.io import imageio


@pytest.mark.slow
def test_figure_4_11_points_and_panels(tmp_path):
    from reproductions.figure_4_11 import CANVAS, Figure411

    png, caption = Figure411(scene="plants").make(profile="smoke", reports_dir=tmp_path,
                                                  progress=False)
    image = imageio.read_png(png)
    assert image.shape[0] > 2 * CANVAS[0] and image.shape[1] > 4 * CANVAS[1]
    text = caption.read_text()
    assert "| A |" in text and "| B |" in text and "held-out" in text.lower()


@pytest.mark.slow
def test_figure_4_13_with_and_without_encoding(tmp_path):
    from reproductions.figure_4_13 import Figure413

    png, caption = Figure413().make(profile="smoke", reports_dir=tmp_path, progress=False)
    assert imageio.read_png(png).ndim == 3
    text = caption.read_text()
    assert "| no PE | 0 |" in text and "| PE | 6 |" in text


def test_white_scene_keeps_geometry_and_drops_albedo():
    from methods.learnt.data import geometry_key
    from prtbench.scene.registry import get_scene
    from reproductions.figure_4_13 import ALBEDO, white_scene

    scene = get_scene("plants", variant="glossy")
    white = white_scene(scene)
    # Same geometry key: the figure reuses the networks trained for the coloured scene.
    assert geometry_key(white) == geometry_key(scene)
    assert all(o.material.kd == ALBEDO and not o.material.is_glossy for o in white.objects)
    assert white.content_hash() != scene.content_hash()


def test_colour_map_is_monotone_in_brightness():
    from reproductions.figure_4_11 import colour_map

    values = colour_map(np.linspace(-0.5, 1.5, 50)[None, :], top=1.0)[0]
    brightness = values.sum(axis=1)
    assert np.all(np.diff(brightness) >= -1e-9)
    assert np.allclose(values[0], values[10]) and np.allclose(values[-1], values[-10])
