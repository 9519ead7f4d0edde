"""Plots and labelled image grids for the reproductions, drawn with matplotlib (Agg).

Output is reproducible: fixed DPI, the Agg backend, no timestamp or software version in the PNG
metadata, so one stored run always gives the same bytes. Image panels are drawn at their own
pixel size (one image pixel = one output pixel) with titles and captions as matplotlib text.
"""

from __future__ import annotations

import io
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from prtbench.api.cache import atomic_path

DPI = 100
FONT_SIZE = 9  # points: 12.5 px at DPI 100
_LINE_PX = 1.45 * FONT_SIZE * DPI / 72  # line height of the labels, in pixels
_CHAR_PX = 0.62 * FONT_SIZE * DPI / 72  # average glyph width (DejaVu Sans), in pixels
GAP = 6
#: Panels narrower than this are magnified by a whole factor (nearest neighbour).
MIN_PANEL_PX = 160
#: PNG text chunks that would change from run to run or machine to machine: left out.
METADATA = {"Software": None}


def _pyplot():
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    plt.rcParams.update({"font.size": FONT_SIZE, "font.family": "DejaVu Sans",
                         "savefig.dpi": DPI, "figure.dpi": DPI})
    return plt


def save(figure, path: Path) -> Path:
    """Write ``figure`` as a PNG at :data:`DPI` atomically, then close it."""

    plt = _pyplot()
    buf = io.BytesIO()
    try:
        figure.savefig(buf, format="png", dpi=DPI, metadata=METADATA, facecolor="white")
    finally:
        plt.close(figure)
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_bytes(buf.getvalue())
    return path


def _text_px(text: str) -> tuple[float, float]:
    lines = text.split("\n") if text else []
    return (max((len(line) for line in lines), default=0) * _CHAR_PX, len(lines) * _LINE_PX)


def panel_grid(path: Path, panels: Sequence[Sequence[np.ndarray | None]], *,
               titles: Sequence[Sequence[str]] | None = None, column_labels: Sequence[str] = (),
               row_labels: Sequence[str] = (), captions: Sequence[Sequence[str]] | None = None,
               title: str = "") -> Path:
    """Write a grid of image panels with labels as a PNG.

    Parameters
    ----------
    path : Path
    panels : list of rows of ndarray, shape (H, W, 3), float in [0, 1], or None (left blank)
        All panels share one shape; each is drawn at its own pixel size (magnified by a whole
        factor when narrower than :data:`MIN_PANEL_PX`).
    titles : list of rows of str, optional
        A title above each panel (may hold newlines).
    column_labels, row_labels : sequence of str
        One per column (above the first row) / row (at the left); may hold newlines.
    captions : list of rows of str, optional
        Text in a white box at each panel's bottom-left corner ("" for none).
    title : str
        One line above everything.
    """
    plt = _pyplot()
    shapes = {p.shape[:2] for row in panels for p in row if p is not None}
    if len(shapes) != 1:
        raise ValueError(f"panels must share one shape; got {sorted(shapes)}")
    h, w = shapes.pop()
    zoom = max(1, int(np.ceil(MIN_PANEL_PX / w)))  # small (smoke) panels: whole-pixel zoom
    h, w = h * zoom, w * zoom
    n_rows, n_cols = len(panels), max(len(r) for r in panels)
    title_h = _text_px(title)[1] + GAP if title else 0
    col_h = max((_text_px(t)[1] for t in column_labels), default=0)
    col_h = col_h + GAP if col_h else 0
    cell_title_h = max((_text_px(t)[1] for row in (titles or ()) for t in row), default=0)
    cell_title_h = cell_title_h + GAP / 2 if cell_title_h else 0
    left = max((_text_px(t)[0] for t in row_labels), default=0)
    left = left + 2 * GAP if left else GAP
    # Each column is as wide as its panel or its widest label, so labels never run together.
    label_w = max([_text_px(t)[0] for row in (titles or ()) for t in row]
                  + [_text_px(t)[0] for t in column_labels] + [0])
    cell_w = max(w, label_w + GAP)
    width = max(left + n_cols * (cell_w + GAP), _text_px(title)[0] + 2 * GAP)
    row_h = cell_title_h + h + GAP
    height = title_h + col_h + n_rows * row_h + GAP
    fig = plt.figure(figsize=(width / DPI, height / DPI), dpi=DPI)
    if title:
        fig.text(GAP / width, 1 - GAP / 2 / height, title, ha="left", va="top",
                 fontsize=FONT_SIZE + 1, fontweight="bold")
    top = title_h + col_h
    for c, text in enumerate(column_labels):
        x = left + c * (cell_w + GAP) + cell_w / 2
        fig.text(x / width, 1 - (top - GAP / 2) / height, text, ha="center", va="bottom")
    for r, row in enumerate(panels):
        y0 = top + r * row_h
        if r < len(row_labels):
            fig.text((left - GAP) / width, 1 - (y0 + cell_title_h + h / 2) / height,
                     row_labels[r], ha="right", va="center")
        for c, panel in enumerate(row):
            x0 = left + c * (cell_w + GAP) + (cell_w - w) / 2
            if titles is not None and r < len(titles) and c < len(titles[r]) and titles[r][c]:
                fig.text((x0 + w / 2) / width, 1 - (y0 + cell_title_h - GAP / 4) / height,
                         titles[r][c], ha="center", va="bottom")
            if panel is None:
                continue
            ax = fig.add_axes((x0 / width, 1 - (y0 + cell_title_h + h) / height, w / width,
                               h / height))
            ax.imshow(np.clip(np.asarray(panel, np.float32)[..., :3], 0, 1),
                      interpolation="nearest", aspect="auto")
            ax.set_axis_off()
            text = captions[r][c] if captions is not None and r < len(captions) and \
                c < len(captions[r]) else ""
            if text:
                ax.text(0.02, 0.02, text, transform=ax.transAxes, ha="left", va="bottom",
                        fontsize=FONT_SIZE - 1,
                        bbox={"facecolor": "white", "edgecolor": "none", "pad": 1.5})
    return save(fig, path)


def titled_grid(path: Path, images: Mapping[str, np.ndarray], *, columns: int) -> Path:
    """:func:`panel_grid` of named panels in reading order, ``columns`` to a row, each titled
    with its name (the stored panels of a figure, in the order they were measured)."""
    keys = list(images)
    rows = [keys[i:i + columns] for i in range(0, len(keys), columns)]
    return panel_grid(path, [[images[k] for k in row] for row in rows], titles=rows)


def line_plot(path: Path, series: Mapping[str, tuple[Sequence[float], Sequence[float], bool]], *,
              title: str, xlabel: str, ylabel: str, log_x: bool = True, log_y: bool = True,
              size: tuple[float, float] = (7.5, 4.6)) -> Path:
    """Write a line plot: ``series`` maps a label to (xs, ys, dashed); markers on the points.

    The legend sits outside the axes on the right, one entry per line, so labels never overlap.
    """
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=size, dpi=DPI)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    # A family's lines share a colour (ours plain, its projection dashed) when labels say so.
    families = list(dict.fromkeys(label.split(" ")[0] for label in series))
    styles = ("-", "-.", ":")
    seen: dict[str, int] = {}
    for label, (xs, ys, dashed) in series.items():
        family = label.split(" ")[0]
        k = seen.get(family, 0)
        if not dashed:
            seen[family] = k + 1
        ax.plot(xs, ys, linestyle="--" if dashed else styles[k % len(styles)], marker="o",
                markersize=3.5, linewidth=1.5, label=label,
                color=colours[families.index(family) % len(colours)],
                alpha=1.0 if dashed or k == 0 else 0.75)
    if log_x:
        ax.set_xscale("log", base=2)
        xs_all = sorted({float(x) for xs, _, _ in series.values() for x in xs})
        ax.set_xticks(xs_all, [f"{x:g}" for x in xs_all])
    if log_y:
        ax.set_yscale("log")
    ax.set_title(title)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), frameon=False)
    fig.tight_layout()
    return save(fig, path)
