"""Reading a report's stored rows into the numbers claims decide on.

Means carry the protocol's intervals (:mod:`prtbench.bench.intervals`): a masked PSNR the
reference noise's interval (``psnr_masked_lo``/``_hi``) widened by the spread over views;
differences of two configurations are paired over the views (and lights) both were measured
on. Timings say which device measured them, and the operation-count model
(:func:`prtbench.tradeoff.cost.ops_counts`) gives what it predicts for the same rows.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence

import numpy as np

from prtbench.bench.claims import Estimate, Missing
from prtbench.bench.intervals import over_views, t95
from prtbench.tradeoff import cost

#: Renderer strings of CPU devices: their timings cannot test a GPU claim.
CPU_RENDERERS = ("llvmpipe", "softpipe", "swrast", "cpu")
PSNR = "metric_psnr_masked"


def rows_of(frame, what: str, **labels):
    """The rows whose ``label_<key>`` equal ``labels``; :class:`Missing` names ``what`` if none."""
    part = frame
    for key, value in labels.items():
        column = f"label_{key}"
        if column not in part.columns:
            raise Missing(f"no stored rows for {what} (no '{key}' label)")
        part = part[part[column] == value]
    if not len(part):
        raise Missing(f"no stored rows for {what}")
    return part


def records(table, what: str) -> list[dict]:
    """A measurement table's rows as dicts; :class:`Missing` if it is empty."""
    if not len(table):
        raise Missing(f"measurement table of {what} is empty")
    return [{k: v for k, v in row.items()} for row in table.to_dict("records")]


def present(value) -> bool:
    """Not None and not NaN (how the store's nulls read back)."""
    return value is not None and not (isinstance(value, float) and math.isnan(value))


def finite(values) -> list[float]:
    return [float(v) for v in values if present(v) and math.isfinite(float(v))]


def config_of(part) -> dict:
    """The stored config of the first row (JSON text in the store)."""
    value = part["config"].iloc[0]
    return json.loads(value) if isinstance(value, str) else dict(value)


def mean_estimate(part, column: str, *, label: str = "", detail: str = "") -> Estimate:
    """Mean over the rows (views) with its interval: the rows' own ``_lo``/``_hi`` for the
    masked PSNR, widened by the spread over views (:func:`prtbench.bench.intervals.over_views`)."""
    if column not in part.columns:
        raise Missing(f"no '{column}' stored for {label or 'these rows'}")
    keep = [i for i, v in enumerate(part[column]) if present(v)]
    if not keep:
        raise Missing(f"no finite '{column}' stored for {label or 'these rows'}")
    values = [float(part[column].iloc[i]) for i in keep]
    los = his = [None] * len(values)
    if column == PSNR and "psnr_masked_lo" in part.columns:
        los = [_maybe(part["psnr_masked_lo"].iloc[i]) for i in keep]
        his = [_maybe(part["psnr_masked_hi"].iloc[i]) for i in keep]
    mean, lo, hi = over_views(values, los, his)
    bounded = len(values) >= 2 or any(v is not None for v in los)
    return Estimate(mean, lo if bounded else None, hi if bounded else None, label, detail)


def _maybe(value) -> float | None:
    return float(value) if present(value) else None


def _per_view(part, column: str, keys: Sequence[str]) -> dict:
    out = {}
    for _, row in part.iterrows():
        value = row.get(column)
        if not present(value):
            continue
        lo = _maybe(row.get("psnr_masked_lo")) if column == PSNR else None
        hi = _maybe(row.get("psnr_masked_hi")) if column == PSNR else None
        out[tuple(row[k] for k in keys)] = (float(value), lo, hi)
    return out


def paired_difference(a, b, column: str = PSNR, *, label: str = "",
                      keys: Sequence[str] = ("view", "light")) -> Estimate:
    """a − b of ``column``, paired over the (view, light) both rows share.

    The interval is the mean difference ± Student's t · its standard error, widened by both
    reference-noise half-widths (as :func:`prtbench.tradeoff.dominance.better_beyond`); without
    shared views, the difference of the two means with their whole intervals.
    """
    pa, pb = _per_view(a, column, keys), _per_view(b, column, keys)
    shared = sorted(set(pa) & set(pb), key=str)
    if not shared:
        return difference(mean_estimate(a, column), mean_estimate(b, column), label=label)
    diffs = [pa[k][0] - pb[k][0] for k in shared]
    down = [(pa[k][0] - (pa[k][1] if pa[k][1] is not None else pa[k][0]))
            + ((pb[k][2] if pb[k][2] is not None else pb[k][0]) - pb[k][0]) for k in shared]
    up = [((pa[k][2] if pa[k][2] is not None else pa[k][0]) - pa[k][0])
          + (pb[k][0] - (pb[k][1] if pb[k][1] is not None else pb[k][0])) for k in shared]
    n, mean = len(diffs), float(np.mean(diffs))
    spread = t95(n - 1) * float(np.std(diffs, ddof=1)) / math.sqrt(n) if n >= 2 else 0.0
    bounded = n >= 2 or any(d > 0 for d in down + up)
    lo = mean - spread - float(np.mean(down))
    hi = mean + spread + float(np.mean(up))
    return Estimate(mean, lo if bounded else None, hi if bounded else None, label,
                    f"paired over {n} view{'s' if n != 1 else ''}")


def difference(a: Estimate, b: Estimate, *, label: str = "") -> Estimate:
    """a − b with the conservative interval [a.lo − b.hi, a.hi − b.lo] (None if either lacks one)."""
    bounded = None not in (a.lo, a.hi, b.lo, b.hi)
    return Estimate(a.value - b.value, a.lo - b.hi if bounded else None,
                    a.hi - b.lo if bounded else None, label)


def log_ratio(a: float, b: float, *, label: str = "", floor: float = 0.0) -> Estimate:
    """ln(a / b), each at least ``floor`` (a zero error against a non-zero one stays finite)."""
    a, b = max(float(a), floor), max(float(b), floor)
    if not (a > 0 and b > 0):
        raise Missing(f"{label or 'ratio'}: {a} / {b} is not a ratio of positive numbers")
    return Estimate(math.log(a / b), label=label, detail=f"ratio {a / b:.3g}")


def versus_paper(ours: float, paper: float, *, label: str = "ours/paper",
                 detail: str = "") -> Estimate:
    """ln(ours / paper): a magnitude claim's case (:func:`reproductions.claims.rules.near_ratio`)."""
    if not (ours > 0 and paper > 0):
        raise Missing(f"{label}: {ours} / {paper} is not a ratio of positive numbers")
    ratio = ours / paper
    return Estimate(math.log(ratio), label=label,
                    detail=f"ratio {ratio:.3g}" + (f", {detail}" if detail else ""))


def median_ms(part, column: str = "frame_ms") -> float:
    values = finite(part[column]) if column in part.columns else []
    if not values:
        raise Missing(f"no stored '{column}'")
    return float(np.median(values))


def fps(part) -> float:
    """1000 / the median frame time of the rows (the tables' FPS)."""
    return 1000.0 / median_ms(part)


def is_gpu(part) -> bool:
    """Every row timed on a GPU: GL timer queries, or a renderer that is not a CPU's."""
    sources = [str(s) for s in part["timing_source"]] if "timing_source" in part.columns else []
    renderers = [str(r).lower() for r in part["renderer"]]
    if not renderers:
        return False
    return all(src == "timer-query" or not any(c in r for c in CPU_RENDERERS)
               for src, r in zip(sources or [""] * len(renderers), renderers))


def device_text(parts: Sequence) -> str:
    """The renderers and timing sources of ``parts`` (DataFrames), for the verdict."""
    renderers = sorted({str(r) for p in parts for r in p["renderer"] if str(r)})
    sources = sorted({str(s) for p in parts if "timing_source" in p.columns
                      for s in p["timing_source"] if str(s)})
    return "; ".join(renderers) + (f" ({', '.join(sources)})" if sources else "")


def ops(part) -> float:
    """The operation-count model's ops per frame for these rows (their median)."""
    values = []
    for _, row in part.iterrows():
        try:
            values.append(cost.ops_counts(row)["ops"])
        except cost.CostUnavailable as exc:
            raise Missing(f"no operation count: {exc}") from None
    if not values:
        raise Missing("no rows to count operations of")
    return float(np.median(values))


def ratio_lines(pairs: Sequence[tuple[str, float, float | None]]) -> str:
    """``label ours (paper p)`` for (label, ours, paper) triples."""
    return ", ".join(f"{label} {ours:.3g}" + (f" (paper {paper:.3g})" if paper is not None else "")
                     for label, ours, paper in pairs)


def cases_text(cases: Sequence[Estimate], *, unit: str = "", digits: int = 3) -> str:
    return "; ".join(f"{c.label} {c.value:.{digits}g}{unit}" + (f" ({c.detail})" if c.detail
                                                              else "") for c in cases)
