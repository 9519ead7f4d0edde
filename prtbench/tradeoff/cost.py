"""Cost of a measured configuration: frame time, memory, precompute, or an operation count.

:func:`cost_value` reads one result row (DESIGN.md §10) and returns its cost of one kind:

``frame_ms``
    The row's median frame time in milliseconds, measured on the row's ``device`` /
    ``renderer`` (device-specific: every report says which). Concurrent workers distort it, so
    :mod:`prtbench.tradeoff.pareto` averages only the rows measured with ``workers == 1`` when
    a configuration has any (and says when it had to fall back to concurrent ones).
``memory``
    ``memory_bytes``: what the method keeps resident to render.
``precompute``
    ``precompute_s``: wall time of the artifact's precompute.
``ops``
    A device-independent operation count of one frame (:func:`ops_counts`), from the method's
    own model (:meth:`prtbench.api.method.Method.op_counts`, declared beside the method's code from
    what its shaders do per vertex, per covered pixel and per frame) and the row's stored
    facts (config, vertex and triangle counts, covered pixels, resolution, resident bytes).
    It needs only the store, so it ranks configurations on a machine without a GPU; its rank
    correlation with measured frame times is :func:`ops_rank_correlation`.

The ``ops`` scalar and the counts it combines are defined in :mod:`prtbench.render.ops`.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Iterable, Mapping
from typing import Any

from prtbench.api import config as config_mod
from prtbench.api.errors import PrtbenchError, UnknownNameError
from prtbench.api.method import METHODS
from prtbench.render.ops import OPS_WEIGHTS

COST_KINDS = ("frame_ms", "memory", "precompute", "ops")
#: Units, for reports and axis labels.
COST_UNITS = {"frame_ms": "ms", "memory": "bytes", "precompute": "s", "ops": "ops/frame"}
#: Stored row fields the ``ops`` model reads.
OPS_FIELDS = ("scene_vertices", "scene_triangles", "covered_pixels", "width", "height", "memory_bytes")


class CostUnavailable(PrtbenchError):
    """A row has no cost of the asked kind (not measured, or the method declares no ops model)."""


def _get(row: Any, name: str) -> Any:
    if dataclasses.is_dataclass(row) and not isinstance(row, type):
        return getattr(row, name, None)
    try:
        value = row[name]
    except (KeyError, IndexError, TypeError):
        return None
    return value


def _finite(value: Any) -> float | None:
    if value is None:
        return None
    try:
        value = float(value)
    except (TypeError, ValueError):
        return None
    return value if math.isfinite(value) else None


def row_config(row: Any) -> dict:
    """The row's method config as a dict (rows from :func:`prtbench.store.results.load` hold JSON)."""
    config = _get(row, "config")
    if isinstance(config, str):
        config = json.loads(config) if config else {}
    return dict(config or {})


def ops_counts(row: Any) -> dict[str, float]:
    """The method's operation counts of one frame for this row.

    Parameters
    ----------
    row : Mapping, pandas Series or ResultRow
        A stored result row: ``method``, ``config`` and :data:`OPS_FIELDS`.

    Returns
    -------
    dict
        ``madds``, ``fetches``, ``bytes`` (floats, non-negative) and ``ops``, their weighted sum.

    Raises
    ------
    CostUnavailable
        The method declares no model (``op_counts`` returns NotImplemented), the row lacks a
        field the model needs (rows stored before schema 4 have no covered-pixel count), or the
        stored config no longer fits the method's Config.
    """

    method = str(_get(row, "method"))
    facts = {}
    for name in OPS_FIELDS:
        value = _finite(_get(row, name))
        if value is None:
            raise CostUnavailable(f"ops cost of a '{method}' row: '{name}' is not stored")
        facts[name] = int(value)
    try:
        cls = METHODS.get(method)
        config = config_mod.from_dict(cls.Config, row_config(row))
    except PrtbenchError as exc:
        raise CostUnavailable(f"ops cost of a '{method}' row: {exc}") from None
    counts = cls.op_counts(config, **facts)
    if counts is NotImplemented:
        raise CostUnavailable(f"method '{method}' declares no operation-count model (op_counts)")
    out = {key: float(counts[key]) for key in OPS_WEIGHTS}
    out["ops"] = sum(OPS_WEIGHTS[key] * out[key] for key in OPS_WEIGHTS)
    return out


def cost_value(row: Mapping, kind: str) -> float:
    """The cost of one result row; NaN where the row has none of this kind.

    Parameters
    ----------
    row : Mapping or pandas Series (or ResultRow)
        A stored result row.
    kind : str
        One of :data:`COST_KINDS`.

    Returns
    -------
    float
        ``frame_ms`` in ms, ``memory`` in bytes, ``precompute`` in s, ``ops`` in weighted
        operations per frame (:func:`ops_counts`); NaN when not measured or not modelled
        (:func:`cost_unavailable_reason` says why).
    """
    check_cost_kind(kind)
    if kind == "ops":
        try:
            return ops_counts(row)["ops"]
        except CostUnavailable:
            return math.nan
    if kind == "memory":
        return resident_bytes(row)
    field = {"frame_ms": "frame_ms", "precompute": "precompute_s"}[kind]
    value = _finite(_get(row, field))
    return math.nan if value is None else value


def resident_bytes(row: Any) -> float:
    """Every byte the renderer held to draw the next frame: the sum of the row's
    ``memory_breakdown`` (docs/PROTOCOL.md), else (rows from before the protocol) its
    ``memory_bytes``; NaN when neither is known."""
    breakdown = _get(row, "memory_breakdown")
    if isinstance(breakdown, str):
        breakdown = json.loads(breakdown) if breakdown else {}
    if isinstance(breakdown, Mapping) and breakdown:
        return float(sum(float(v) for v in breakdown.values()))
    value = _finite(_get(row, "memory_bytes"))
    return math.nan if value is None else value


def cost_unavailable_reason(row: Any, kind: str) -> str | None:
    """Why :func:`cost_value` is NaN for ``row`` (None when it is not)."""
    check_cost_kind(kind)
    if kind == "ops":
        try:
            ops_counts(row)
        except CostUnavailable as exc:
            return str(exc)
        return None
    if math.isnan(cost_value(row, kind)):
        return f"'{kind}' not stored for a '{_get(row, 'method')}' row"
    return None


def check_cost_kind(kind: str) -> str:
    """``kind`` if it is a cost kind, else an :class:`UnknownNameError` listing them."""
    if kind not in COST_KINDS:
        raise UnknownNameError("cost", str(kind), COST_KINDS)
    return kind


def ops_rank_correlation(rows: Iterable[Any]) -> tuple[float, float, int]:
    """Spearman rank correlation between the ``ops`` model and measured ``frame_ms``.

    Parameters
    ----------
    rows : iterable of rows
        Typically every ok row of one scene (and device); rows without either value are
        left out.

    Returns
    -------
    rho, p_value : float
        :func:`scipy.stats.spearmanr` over the rows (NaN with fewer than 3 rows or a constant
        column).
    n : int
        Rows used.
    """
    from scipy import stats

    pairs = []
    for row in rows:
        ops, ms = cost_value(row, "ops"), cost_value(row, "frame_ms")
        if math.isfinite(ops) and math.isfinite(ms):
            pairs.append((ops, ms))
    if len(pairs) < 3 or len({p[0] for p in pairs}) < 2 or len({p[1] for p in pairs}) < 2:
        return math.nan, math.nan, len(pairs)
    result = stats.spearmanr([p[0] for p in pairs], [p[1] for p in pairs])
    return float(result.statistic), float(result.pvalue), len(pairs)
