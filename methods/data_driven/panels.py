"""Figure helpers for the data-driven reproductions: labelled image grids and a line plot.

Drawn with Pillow (a dependency of scikit-image) so no plotting library is needed. Images are
display images (float in [0, 1], (H, W, 3)); the output is uint8 RGB.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

LABEL_HEIGHT = 14
COLOURS = ((31, 119, 180), (214, 39, 40), (44, 160, 44), (148, 103, 189), (255, 127, 14),
           (23, 190, 207))


def _font():
    from PIL import ImageFont

    return ImageFont.load_default()


def grid(images: Sequence[np.ndarray], labels: Sequence[str], *, columns: int,
         gap: int = 4) -> np.ndarray:
    """Images in a grid, each with a label strip above it; (H, W, 3) uint8."""
    from PIL import Image, ImageDraw

    h = max(im.shape[0] for im in images)
    w = max(im.shape[1] for im in images)
    rows = int(math.ceil(len(images) / columns))
    canvas = Image.new("RGB", (columns * (w + gap) + gap, rows * (h + LABEL_HEIGHT + gap) + gap),
                       (255, 255, 255))
    draw = ImageDraw.Draw(canvas)
    for k, (im, label) in enumerate(zip(images, labels)):
        r, c = divmod(k, columns)
        x = gap + c * (w + gap)
        y = gap + r * (h + LABEL_HEIGHT + gap)
        draw.text((x + 2, y + 1), label, fill=(0, 0, 0), font=_font())
        tile = (np.clip(im, 0.0, 1.0) * 255 + 0.5).astype(np.uint8)
        canvas.paste(Image.fromarray(tile), (x, y + LABEL_HEIGHT))
    return np.asarray(canvas)


def error_image(test: np.ndarray, reference: np.ndarray, *, scale: float) -> np.ndarray:
    """|test − reference| (linear, summed over RGB) × ``scale``, as a grey display image."""
    e = np.abs(np.asarray(test) - np.asarray(reference)).sum(axis=-1) * scale
    return np.repeat(np.clip(e, 0.0, 1.0)[..., None], 3, axis=-1)


def line_plot(series: Mapping[str, tuple[Sequence[float], Sequence[float], bool]], *,
              title: str, xlabel: str, ylabel: str, log_x: bool = True, log_y: bool = True,
              size: tuple[int, int] = (640, 420)) -> np.ndarray:
    """A line plot: ``series`` maps a label to (xs, ys, dashed). Returns (H, W, 3) uint8."""
    from PIL import Image, ImageDraw

    width, height = size
    left, right, top, bottom = 70, 170, 34, 50
    canvas = Image.new("RGB", size, (255, 255, 255))
    draw = ImageDraw.Draw(canvas)
    font = _font()
    xs_all = np.concatenate([np.asarray(s[0], float) for s in series.values()])
    ys_all = np.concatenate([np.asarray(s[1], float) for s in series.values()])
    ys_all = ys_all[np.isfinite(ys_all) & (ys_all > 0 if log_y else True)]
    fx = np.log10 if log_x else (lambda v: np.asarray(v, float))
    fy = np.log10 if log_y else (lambda v: np.asarray(v, float))
    x0, x1 = float(fx(xs_all.min())), float(fx(xs_all.max()))
    y0, y1 = float(fy(ys_all.min())), float(fy(ys_all.max()))
    pad = 0.05 * (y1 - y0 or 1.0)
    y0, y1 = y0 - pad, y1 + pad
    if x1 == x0:
        x1 = x0 + 1.0

    def px(v):
        return left + (float(fx(v)) - x0) / (x1 - x0) * (width - left - right)

    def py(v):
        return height - bottom - (float(fy(v)) - y0) / (y1 - y0) * (height - top - bottom)

    draw.rectangle([left, top, width - right, height - bottom], outline=(0, 0, 0))
    for v in sorted(set(float(x) for x in xs_all)):
        draw.line([px(v), height - bottom, px(v), height - bottom + 4], fill=(0, 0, 0))
        draw.text((px(v) - 6, height - bottom + 6), f"{v:g}", fill=(0, 0, 0), font=font)
    for k in range(5):
        t = y0 + (y1 - y0) * k / 4
        v = 10 ** t if log_y else t
        y = py(v)
        draw.line([left - 4, y, left, y], fill=(0, 0, 0))
        draw.text((4, y - 6), f"{v:.3g}", fill=(0, 0, 0), font=font)
    draw.text((max(left, width // 2 - 3 * len(title)), 4), title, fill=(0, 0, 0), font=font)
    draw.text(((left + width - right) // 2 - 30, height - 18), xlabel, fill=(0, 0, 0), font=font)
    draw.text((4, top - 12), ylabel, fill=(0, 0, 0), font=font)
    for k, (label, (xs, ys, dashed)) in enumerate(series.items()):
        colour = COLOURS[k % len(COLOURS)]
        pts = [(px(x), py(y)) for x, y in zip(xs, ys) if np.isfinite(y) and (y > 0 or not log_y)]
        for a, b in zip(pts, pts[1:]):
            if dashed:
                for t in np.linspace(0, 1, 9)[::2]:
                    s, e = t, min(t + 1 / 8, 1)
                    draw.line([a[0] + (b[0] - a[0]) * s, a[1] + (b[1] - a[1]) * s,
                               a[0] + (b[0] - a[0]) * e, a[1] + (b[1] - a[1]) * e],
                              fill=colour, width=2)
            else:
                draw.line([a, b], fill=colour, width=2)
        for p in pts:
            draw.ellipse([p[0] - 3, p[1] - 3, p[0] + 3, p[1] + 3], outline=colour)
        ly = top + 14 * k
        draw.line([width - right + 8, ly + 6, width - right + 28, ly + 6], fill=colour, width=2)
        if dashed:
            draw.line([width - right + 14, ly + 6, width - right + 20, ly + 6], fill=(255, 255, 255),
                      width=2)
        draw.text((width - right + 32, ly), label, fill=(0, 0, 0), font=font)
    return np.asarray(canvas)


def write_png(path, image: np.ndarray) -> None:
    """Write a uint8 or [0, 1] float RGB image."""
    from prtbench.imageio import write_png as _write

    im = np.asarray(image)
    if im.dtype == np.uint8:
        im = im.astype(np.float32) / 255.0
    _write(path, im)
