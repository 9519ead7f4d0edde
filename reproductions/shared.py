"""Shared pieces of the reproductions: running cells, panel images, wireframes, captions.

Figures run their cells through the ordinary runner (:func:`run_cells`), so every number a
figure prints is a stored result row, and the panels are the very images the runner measured
(written as EXR/PNG into a scratch folder), stored with the figure's report run. Wireframes
come from a small GL pass (``prtbench/render/shaders/wireframe.{vert,frag}``); labelled grids and plots
are drawn with matplotlib in :mod:`reproductions.plots`.
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

from prtbench.api.cache import atomic_path
from prtbench.bench.job import Job, Outputs
from prtbench.bench.runner import load_average
from prtbench.bench.submit import JobResult, submit
from prtbench.io import imageio
from prtbench.render import gl
from prtbench.render.raster import clip_planes
from prtbench.store.results import load

#: Inset outline and wireframe colours (display space, RGB in [0, 1]).
INSET_BORDER = (1.0, 1.0, 1.0)
WIRE = (1.0, 0.85, 0.1)


# --- running cells ----------------------------------------------------------------------------

@dataclass
class CellRun:
    """One cell run by :func:`run_cells`.

    Attributes
    ----------
    cell : Job
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

    cell: Job
    run_id: str
    image: np.ndarray
    reference: np.ndarray | None
    rows: Any
    scene: Any


def run_cells(cells: Sequence[Job], *, profile: str, results_path: Path | None,
              progress: bool = True, tag: str = "figure") -> list[CellRun]:
    """Validate every cell, then run each through the runner, keeping its first view's images.

    Parameters
    ----------
    cells : sequence of Job
        ``views`` of each cell is honoured (figures use 1).
    profile : str
    results_path : Path or None
        Results store (default: :func:`prtbench.store.results.default_path`).
    progress : bool
    tag : str
        Prefix of the progress lines on stderr.

    Returns
    -------
    list of CellRun, in cell order.
    """

    with tempfile.TemporaryDirectory(prefix="prtbench-figure-") as tmp:
        outputs = [Outputs(out_dir=Path(tmp) / f"cell{i:02d}") for i in range(len(cells))]
        total = len(cells)

        def announce(result: JobResult) -> None:
            print(f"[{tag}] {result.job.describe()} ({total} cells): {result.status}",
                  file=sys.stderr, flush=True)

        # Every cell is validated before any runs; a failing cell is an error of the figure.
        submission = submit(cells, profile=profile, outputs=outputs, results_path=results_path,
                            progress=False, run_progress=progress, echo=progress,
                            raise_errors=True, on_result=announce, desc=tag)
        runs = []
        for cell, result in zip(cells, submission.per_job):
            summary = result.summary
            files = summary.views[0].files
            image = imageio.read_exr(files["exr"])[..., :3].astype(np.float32)
            reference = imageio.read_png(files["reference"]) if cell.reference == "path" else None
            runs.append(CellRun(cell, summary.run_id, image, reference, None, result.scene))
    frame = load(results_path)
    for run in runs:
        run.rows = frame[frame["run_id"] == run.run_id].copy()
    return runs


def with_load(rows: Sequence[dict]) -> list[dict]:
    """``rows`` each with the 1-minute load average now, as ``load_average``, for storing.

    A figure that stores measurement rows of its own (not the runner's, which carry it)
    stamps them as it stores them, right after measuring, so that its caption
    (:func:`prtbench.bench.reproduction.provenance_line`) says how busy the machine was and
    ``tests/test_reports_provenance.py`` can check it. A row's own value is kept.
    """
    load = load_average()
    return [{"load_average": load, **row} for row in rows]


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

    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(lines) + "\n")
    return path
