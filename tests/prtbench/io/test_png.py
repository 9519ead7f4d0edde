"""PNG output through Pillow: the stored pixels are exactly the documented 8-bit quantisation."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from prtbench.api.errors import InvalidInputError
from prtbench.io import imageio


def _expected(image: np.ndarray) -> np.ndarray:
    # The quantisation metrics and goldens were measured with: clip, scale, round half to even.
    return np.round(np.clip(image.astype(np.float64), 0.0, 1.0) * 255.0).astype(np.uint8)


def test_round_trip_equals_the_8bit_quantisation(tmp_path):
    rng = np.random.default_rng(3)
    image = rng.uniform(-0.2, 1.2, size=(13, 21, 3)).astype(np.float32)  # W != H, odd sizes
    image[0, :4, 0] = [0.5, 0.25, 1.0, 0.0]  # 127.5 rounds to 128 (even), 63.75 to 64
    path = tmp_path / "out.png"
    imageio.write_png(path, image)
    with Image.open(path) as png:
        assert png.format == "PNG" and png.mode == "RGB" and png.size == (21, 13)
        stored = np.asarray(png)
    np.testing.assert_array_equal(stored, _expected(image))
    assert stored[0, :4, 0].tolist() == [128, 64, 255, 0]
    assert stored.min() == 0 and stored.max() == 255  # the out-of-range values were clipped
    back = imageio.read_png(path)
    assert back.dtype == np.float32 and back.shape == (13, 21, 3)
    np.testing.assert_array_equal(back, _expected(image).astype(np.float32) / 255.0)
    assert [p.name for p in tmp_path.iterdir()] == ["out.png"]  # no temporary file left


def test_grey_and_rgba_inputs(tmp_path):
    grey = np.linspace(0.0, 1.0, 12, dtype=np.float32).reshape(3, 4)
    imageio.write_png(tmp_path / "grey.png", grey)
    with Image.open(tmp_path / "grey.png") as png:
        assert png.mode == "RGB" and png.size == (4, 3)
        stored = np.asarray(png)
    np.testing.assert_array_equal(stored, np.repeat(_expected(grey)[..., None], 3, axis=-1))
    rgba = np.zeros((2, 2, 4), dtype=np.float32)
    rgba[..., 1], rgba[..., 3] = 0.6, 0.1  # alpha is dropped, not premultiplied
    imageio.write_png(tmp_path / "rgba.png", rgba)
    assert imageio.read_png(tmp_path / "rgba.png")[0, 0].tolist() == pytest.approx(
        [0.0, 153 / 255, 0.0])


def test_png_errors_are_one_line(tmp_path):
    with pytest.raises(InvalidInputError, match=r"expects \(H, W\), \(H, W, 3\)"):
        imageio.write_png(tmp_path / "bad.png", np.zeros((2, 2, 2)))
    assert not list(tmp_path.iterdir())
    with pytest.raises(InvalidInputError, match="cannot read PNG"):
        imageio.read_png(tmp_path / "missing.png")
    (tmp_path / "junk.png").write_bytes(b"not a png")
    with pytest.raises(InvalidInputError, match="cannot read PNG"):
        imageio.read_png(tmp_path / "junk.png")
