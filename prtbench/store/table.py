"""``prtbench results``' plain-text table of stored rows."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

from prtbench.api.errors import UnknownNameError
from prtbench.store.results import COLUMNS, ResultRow, _to_json

DEFAULT_COLUMNS = ("method", "scene", "light", "view", "size", "profile", "psnr", "psnr_masked",
                   "ssim_masked", "flip_masked", "frame_ms", "memory_bytes", "status")


def _format_value(value) -> str:
    if value is None:
        return "-"
    if isinstance(value, bool) or isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return f"{value:.0f}" if abs(value) >= 1e5 else f"{value:.4g}"
    if isinstance(value, Mapping):
        return _to_json(value)
    return str(value)


def format_rows(rows: Sequence[ResultRow], *, columns: Sequence[str] | None = None) -> str:
    """A plain-text table of ``rows`` for ``prtbench results``.

    ``columns`` name row fields, ``size`` (``WxH``) or metric keys (``psnr``, ``ssim_masked``);
    a metric a row lacks prints ``-``. Numbers are right-aligned; inf prints as ``inf``.
    """
    columns = list(columns or DEFAULT_COLUMNS)
    metric_keys = {key for row in rows for key in row.metrics}
    known = set(COLUMNS) | {"size"} | metric_keys | set(DEFAULT_COLUMNS)
    for column in columns:
        if column not in known:
            raise UnknownNameError("results column", column, known)
    if not rows:
        return "(no results)"

    def cell(row: ResultRow, column: str):
        if column == "size":
            return f"{row.width}x{row.height}"
        if column in COLUMNS:
            return getattr(row, column)
        value = row.metrics.get(column)
        return float(value) if value is not None else None

    raw = [[cell(row, column) for column in columns] for row in rows]
    numeric = [all(isinstance(r[i], (int, float)) or r[i] is None for r in raw) for i in range(len(columns))]
    text = [[_format_value(v) for v in r] for r in raw]
    widths = [max(len(columns[i]), *(len(r[i]) for r in text)) for i in range(len(columns))]

    def line(cells: Sequence[str]) -> str:
        return "  ".join(c.rjust(w) if num else c.ljust(w)
                         for c, w, num in zip(cells, widths, numeric)).rstrip()

    return "\n".join([line(columns), line(["-" * w for w in widths]), *(line(r) for r in text)])
