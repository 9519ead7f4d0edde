"""Shared pieces of the PRTT reproductions: running cells, image panels, labels, wireframes.

Figures run their cells through the ordinary runner (:func:`run_cells`), so every number a
figure prints is a stored result row, and the panels are the very images the runner measured
(written as EXR/PNG into a scratch folder). Panels are assembled into labelled grids with
numpy; text is drawn with Pillow (a dependency of scikit-image), wireframes with a small GL
pass (``methods/shaders/wireframe.{vert,frag}``).
"""

from __future__ import annotations

import json
import sys
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from prtbench.reproduction import Cell

#: Panel background and label colours (display space, RGB in [0, 1]).
BACKGROUND = (1.0, 1.0, 1.0)
TEXT = (0.0, 0.0, 0.0)
INSET_BORDER = (1.0, 1.0, 1.0)
WIRE = (1.0, 0.85, 0.1)


# --- running cells ----------------------------------------------------------------------------

@dataclass
class CellRun:
    """One cell run by :func:`run_cells`.

    Attributes
    ----------
    cell : Cell
    run_id : str
        The results-store run id of its rows.
    image : ndarray, shape (H, W, 3), float32
        The method's linear HDR render of the first view.
    reference : ndarray, shape (H, W, 3), float32 or None
        Display image of the runner's reference for that view (None for a method reference).
    rows : pandas.DataFrame
        Its result rows, read back from the store.
    scene : Scene
        The prepared scene (views already selected).
    """

    cell: Cell
    run_id: str
    image: np.ndarray
    reference: np.ndarray | None
    rows: Any
    scene: Any


def run_cells(cells: Sequence[Cell], *, profile: str, results_path: Path | None,
              progress: bool = True, tag: str = "figure") -> list[CellRun]:
    """Validate every cell, then run each through the runner, keeping its first view's images.

    Parameters
    ----------
    cells : sequence of Cell
        ``views`` of each cell is honoured (figures use 1).
    profile : str
    results_path : Path or None
        Results store (default: :func:`prtbench.results.default_path`).
    progress : bool
    tag : str
        Prefix of the progress lines on stderr.

    Returns
    -------
    list of CellRun, in cell order.
    """
    from prtbench import imageio
    from prtbench.results import load
    from prtbench.runner import RunRequest, execute, prepare

    with tempfile.TemporaryDirectory(prefix="prtbench-figure-") as tmp:
        requests = [RunRequest(
            method=c.method, scene=c.scene, variant=c.variant, light=c.light, views=c.views,
            profile=profile, reference=c.reference, overrides=dict(c.overrides),
            scene_params=dict(c.scene_params), out_dir=Path(tmp) / f"cell{i:02d}",
            results_path=results_path, write_images=True) for i, c in enumerate(cells)]
        prepared = [prepare(r) for r in requests]  # a bad cell fails before any work
        runs = []
        for i, (cell, job) in enumerate(zip(cells, prepared)):
            print(f"[{tag}] cell {i + 1}/{len(cells)}: {dict(cell.label)}", file=sys.stderr,
                  flush=True)
            summary = execute(job, progress=progress)
            files = summary.views[0].files
            image = imageio.read_exr(files["exr"])[..., :3].astype(np.float32)
            reference = imageio.read_png(files["reference"]) if cell.reference == "path" else None
            runs.append(CellRun(cell, summary.run_id, image, reference, None, job.scene))
    frame = load(results_path)
    for run in runs:
        run.rows = frame[frame["run_id"] == run.run_id].copy()
    return runs


def records(frame) -> list[dict]:
    """Rows of a DataFrame as dicts of plain Python values (NaN stays a float NaN)."""
    out = []
    for record in frame.to_dict("records"):
        out.append({k: (v.item() if hasattr(v, "item") else v) for k, v in record.items()})
    return out


def error_image(test: np.ndarray, reference: np.ndarray, *, scale: float) -> np.ndarray:
    """|test − reference| (linear, summed over RGB) × ``scale``, as a grey display image."""
    e = np.abs(np.asarray(test) - np.asarray(reference)).sum(axis=-1) * scale
    return np.repeat(np.clip(e, 0.0, 1.0)[..., None], 3, axis=-1).astype(np.float32)


def fps(rows) -> float:
    """1000 / median over the rows' per-view median frame times (ms)."""
    return 1000.0 / float(np.median(rows["frame_ms"]))


def row_config(rows) -> dict:
    """The stored method config of a run (its first row)."""
    return json.loads(rows["config"].iloc[0])


# --- text -------------------------------------------------------------------------------------

def _font(size: int):
    from PIL import ImageFont

    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # Pillow < 10.1: the fixed bitmap font
        return ImageFont.load_default()


def text_size(text: str, *, size: int = 14) -> tuple[int, int]:
    """(width, height) in pixels of ``text`` (may hold newlines) at font ``size``."""
    from PIL import Image, ImageDraw

    draw = ImageDraw.Draw(Image.new("RGB", (1, 1)))
    left, top, right, bottom = draw.multiline_textbbox((0, 0), text, font=_font(size), spacing=2)
    return int(np.ceil(right)), int(np.ceil(bottom))


def draw_text(image: np.ndarray, text: str, *, xy: tuple[int, int], size: int = 14,
              color: Sequence[float] = TEXT, box: Sequence[float] | None = None,
              pad: int = 2) -> np.ndarray:
    """Draw ``text`` on a float image at pixel ``xy`` (top-left), optionally on a filled box.

    Parameters
    ----------
    image : ndarray, shape (H, W, 3), float in [0, 1]
    text : str
    xy : (int, int)
        Column, row of the text's top-left corner.
    size : int
        Font size in pixels.
    color, box : RGB in [0, 1]
        Text colour and, if given, the colour of a box behind the text.

    Returns
    -------
    ndarray, shape (H, W, 3), float32
        A new image.
    """
    from PIL import Image, ImageDraw

    rgb = (np.clip(image, 0, 1) * 255 + 0.5).astype(np.uint8)
    canvas = Image.fromarray(rgb, "RGB")
    draw = ImageDraw.Draw(canvas)
    font = _font(size)
    to8 = lambda c: tuple(int(round(255 * v)) for v in c)  # noqa: E731
    if box is not None:
        left, top, right, bottom = draw.multiline_textbbox(xy, text, font=font, spacing=2)
        draw.rectangle((left - pad, top - pad, right + pad, bottom + pad), fill=to8(box))
    draw.multiline_text(xy, text, font=font, fill=to8(color), spacing=2)
    return np.asarray(canvas, dtype=np.float32) / 255.0


# --- grids ------------------------------------------------------------------------------------

def grid(panels: Sequence[Sequence[np.ndarray | None]], *, column_labels: Sequence[str] = (),
         row_labels: Sequence[str] = (), gap: int = 4, font_size: int = 14,
         title: str = "") -> np.ndarray:
    """Lay out equally sized panels in rows and columns with labels above and at the left.

    Parameters
    ----------
    panels : list of rows of (H, W, 3) float images in [0, 1], or None (left blank)
    column_labels, row_labels : sequence of str
        One per column / row (may hold newlines); empty for none.
    gap : int
        Pixels between panels.
    font_size : int
    title : str
        One line above everything.

    Returns
    -------
    ndarray, shape (H_total, W_total, 3), float32
        ``H_total = top + rows·H + (rows−1)·gap`` etc., white background.
    """
    shapes = {p.shape for row in panels for p in row if p is not None}
    if len(shapes) != 1:
        raise ValueError(f"panels must share one shape; got {sorted(shapes)}")
    h, w, _ = shapes.pop()
    n_rows, n_cols = len(panels), max(len(r) for r in panels)
    label_w = max((text_size(t, size=font_size)[0] for t in row_labels), default=0)
    left = label_w + 2 * gap if label_w else 0
    label_h = max((text_size(t, size=font_size)[1] for t in column_labels), default=0)
    title_h = text_size(title, size=font_size + 2)[1] + gap if title else 0
    top = title_h + (label_h + 2 * gap if label_h else 0)
    height = top + n_rows * h + (n_rows - 1) * gap + gap
    width = left + n_cols * w + (n_cols - 1) * gap + gap
    out = np.empty((height, width, 3), np.float32)
    out[...] = BACKGROUND
    for r, row in enumerate(panels):
        for c, panel in enumerate(row):
            if panel is None:
                continue
            y, x = top + r * (h + gap), left + c * (w + gap)
            out[y:y + h, x:x + w] = np.clip(panel[..., :3], 0, 1)
    if title:
        out = draw_text(out, title, xy=(gap, gap // 2), size=font_size + 2)
    for c, text in enumerate(column_labels):
        tw, _ = text_size(text, size=font_size)
        out = draw_text(out, text, xy=(left + c * (w + gap) + max(0, (w - tw) // 2), title_h + gap),
                        size=font_size)
    for r, text in enumerate(row_labels):
        _, th = text_size(text, size=font_size)
        out = draw_text(out, text, xy=(gap, top + r * (h + gap) + max(0, (h - th) // 2)),
                        size=font_size)
    return out


def caption(panel: np.ndarray, text: str, *, size: int = 13, corner: str = "bottom-left"
            ) -> np.ndarray:
    """``panel`` with ``text`` in a white box at a corner (FPS / PSNR labels)."""
    tw, th = text_size(text, size=size)
    h, w = panel.shape[:2]
    x = 4 if corner.endswith("left") else max(4, w - tw - 6)
    y = 4 if corner.startswith("top") else max(4, h - th - 6)
    return draw_text(panel, text, xy=(x, y), size=size, box=(1.0, 1.0, 1.0))


# --- wireframes and insets ------------------------------------------------------------------

def render_wireframe(scene, view, *, width: int, height: int, line_width: float = 1.0
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Visible mesh edges of ``scene`` seen from ``view`` (depth-tested barycentric edges).

    Parameters
    ----------
    scene : Scene
    view : View
    width, height : int
    line_width : float
        Line width in pixels.

    Returns
    -------
    edges : ndarray, shape (height, width), float32
        Edge coverage in [0, 1] (row 0 at the top).
    geometry : ndarray, shape (height, width), bool
        Pixels covered by any triangle.
    """
    from methods._raster import clip_planes
    from prtbench import gl

    ctx = gl.create_context()
    program = gl.load_program(ctx, "wireframe.vert", "wireframe.frag")
    positions, _, faces, _ = scene.merged()
    corners = np.asarray(positions, np.float32)[np.asarray(faces).reshape(-1)]  # (3F, 3)
    bary = np.tile(np.eye(3, dtype=np.float32), (len(faces), 1))  # (3F, 3)
    vao = gl.upload_mesh(ctx, program, corners, np.arange(len(corners)).reshape(-1, 3),
                         attributes={"in_barycentric": bary})
    target = gl.RenderTarget(ctx, width, height)
    try:
        near, far = clip_planes(scene, view)
        clip_from_world = view.clip_from_camera(width / height, near, far) @ view.camera_from_world()
        program["clip_from_world"].write(clip_from_world.T.astype(np.float32).tobytes())
        program["line_width"].value = float(line_width)
        target.use()
        target.clear()
        ctx.enable(gl.moderngl.DEPTH_TEST)
        ctx.disable(gl.moderngl.CULL_FACE)
        vao.render()
        image = target.read()
    finally:
        for obj in [vao, *vao.extra["buffers"], program]:
            obj.release()
        target.release()
    return image[..., 0].astype(np.float32), image[..., 3] > 0.5


def crop_box(shape: tuple[int, int], fraction: tuple[float, float, float, float]
             ) -> tuple[int, int, int, int]:
    """Pixel box (row0, row1, col0, col1) of a fractional box (top, bottom, left, right)."""
    h, w = shape
    t, b, l, r = fraction
    return int(round(t * h)), int(round(b * h)), int(round(l * w)), int(round(r * w))


def wireframe_overlay(panel: np.ndarray, edges: np.ndarray, *,
                      crop: tuple[float, float, float, float], opacity: float = 0.9
                      ) -> np.ndarray:
    """``panel`` with the mesh edges drawn inside an outlined crop box (the wireframe "inset").

    The edges are drawn in place rather than in a magnified copy, so no part of the render is
    hidden; the box marks where to look (a ground region with shadows, chosen per scene).

    Parameters
    ----------
    panel : ndarray, shape (H, W, 3)
        Display image in [0, 1].
    edges : ndarray, shape (s·H, s·W)
        :func:`render_wireframe` coverage at an integer multiple s of the panel's resolution
        (s > 1 gives thin antialiased lines: s×s blocks are averaged).
    crop : (top, bottom, left, right)
        Fractions of the panel.
    opacity : float
        Opacity of a fully covered edge pixel.

    Returns
    -------
    ndarray, shape (H, W, 3), float32
    """
    h, w = panel.shape[:2]
    scale = edges.shape[0] // h
    if scale < 1 or edges.shape != (scale * h, scale * w):
        raise ValueError(f"edges shape {edges.shape}; expected an integer multiple of {(h, w)}")
    coverage = edges.reshape(h, scale, w, scale).mean(axis=(1, 3))
    r0, r1, c0, c1 = crop_box((h, w), crop)
    out = np.array(panel[..., :3], dtype=np.float32, copy=True)
    alpha = (opacity * coverage[r0:r1, c0:c1])[..., None]
    out[r0:r1, c0:c1] = out[r0:r1, c0:c1] * (1 - alpha) + np.asarray(WIRE, np.float32) * alpha
    border = np.asarray(INSET_BORDER, np.float32)
    out[r0, c0:c1] = out[r1 - 1, c0:c1] = border
    out[r0:r1, c0] = out[r0:r1, c1 - 1] = border
    return out


def format_value(value: Any) -> str:
    """Table cell text: floats to 4 significant digits, NaN/inf as an em dash."""
    if isinstance(value, float):
        return "—" if not np.isfinite(value) else f"{value:.4g}"
    return str(value)


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> list[str]:
    """Lines of a markdown table."""
    return (["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
            + ["| " + " | ".join(format_value(v) for v in row) + " |" for row in rows])


def write_caption(path: Path, lines: Sequence[str]) -> Path:
    """Atomically write a caption markdown file."""
    from prtbench.cache import atomic_path

    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(lines) + "\n")
    return path
