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

The ``ops`` scalar combines three counts with stated weights (:data:`OPS_WEIGHTS`)::

    ops = madds + 4 · fetches + 0.5 · bytes

* ``madds``: multiply-adds (one vec3 madd counts 3); a transcendental (sin, cos, exp2, tanh,
  pow, sqrt, inversesqrt, a division) counts :data:`TRANSCENDENTAL_MADDS` = 4.
* ``fetches``: texture lookups and per-thread buffer loads (SSBO reads, ``texelFetch``).
  One fetch = 4 multiply-adds: a bilinear lookup is four taps and three lerps, and GPUs issue
  about one texture instruction per four ALU instructions at full rate. Uniform-block reads
  (the light's SH, the TPFL matrix, hard-coded weights) are the same address for every thread
  (a broadcast from the constant cache) and count as nothing beyond their multiply-adds.
* ``bytes``: bytes read per frame from resident data (vertex attributes, transfer buffers,
  texels, shadow maps and G-buffers, written render targets). One byte = 0.5 multiply-add:
  most reads of a frame hit the caches; a DRAM-bound byte costs several times more, so this
  weight is a compromise, checked against measured times by the rank correlation.

Fixed-function work every raster method pays is counted by :func:`raster_counts`
(vertex transform, triangle setup, varyings interpolated per covered pixel, the colour write).
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Iterable, Mapping
from functools import lru_cache
from typing import Any

from prtbench.api.errors import PrtbenchError, UnknownNameError

COST_KINDS = ("frame_ms", "memory", "precompute", "ops")
#: Units, for reports and axis labels.
COST_UNITS = {"frame_ms": "ms", "memory": "bytes", "precompute": "s", "ops": "ops/frame"}
#: Weights of the ``ops`` scalar: multiply-adds per fetch and per byte (see the module docstring).
OPS_WEIGHTS = {"madds": 1.0, "fetches": 4.0, "bytes": 0.5}
#: One transcendental (sin, cos, exp2, tanh, pow, sqrt, division) in multiply-adds.
TRANSCENDENTAL_MADDS = 4
#: mat4 × vec4: the clip-space transform of one vertex.
VERTEX_TRANSFORM_MADDS = 16
#: Edge and plane equations of one triangle (set-up before rasterisation).
TRIANGLE_SETUP_MADDS = 24
#: Barycentric interpolation of one float varying at one pixel.
VARYING_MADDS = 2
#: RGBA float32 colour target written per covered pixel.
COLOR_BYTES = 16
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
    from prtbench.api import config as config_mod
    from prtbench.api.method import METHODS

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
    field = {"frame_ms": "frame_ms", "memory": "memory_bytes", "precompute": "precompute_s"}[kind]
    value = _finite(_get(row, field))
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


# -- building blocks of the GLSL the methods share (prtbench/render/shaders) ---------------------------
# Methods' op_counts compose these; each mirrors one function of the core shaders.

def raster_counts(*, vertices: int, triangles: int, pixels: int, varyings: int,
                  vertex_bytes: int, depth_prepass: bool = False) -> dict[str, float]:
    """Fixed-function work of one indexed draw (and its optional depth pre-pass).

    Parameters
    ----------
    vertices, triangles : int
        Vertex shader invocations and triangles set up.
    pixels : int
        Covered pixels shaded (an early depth pre-pass shades each about once).
    varyings : int
        Float varyings interpolated per shaded pixel.
    vertex_bytes : int
        Attribute bytes read per vertex.
    depth_prepass : bool
        A depth-only pass first: a second transform and set-up, one depth test per pixel.
    """
    passes = 2 if depth_prepass else 1
    madds = (passes * (vertices * VERTEX_TRANSFORM_MADDS + triangles * TRIANGLE_SETUP_MADDS)
             + pixels * (varyings * VARYING_MADDS + (1 if depth_prepass else 0)))
    data = passes * vertices * vertex_bytes + pixels * COLOR_BYTES + (4 * pixels if depth_prepass else 0)
    return {"madds": float(madds), "fetches": 0.0, "bytes": float(data)}


def sh_eval_madds(bands: int) -> float:
    """``sh_eval`` (sh.glsl): the Legendre and (x + iy)^m recurrences, ~4 madds per coefficient."""
    return 4.0 * bands * bands + TRANSCENDENTAL_MADDS  # + the normalize


def shade_transferred_madds(bands: int) -> float:
    """``shade_transferred`` (prt_shading.glsl) for one point of a glossy material.

    Phong zonal coefficients (a ratio per band), the mirror direction, ``sh_eval`` at it and the
    RGB dot product with H (3 madds per coefficient), plus the diffuse term.
    """
    zonal = bands * (2 + TRANSCENDENTAL_MADDS)
    mirror = 6 + 2 * TRANSCENDENTAL_MADDS  # reflect and two normalizes
    return zonal + mirror + sh_eval_madds(bands) + 3.0 * bands * bands + 3 * bands + 9


@lru_cache(maxsize=16)
def triple_product_entries(bands: int) -> int:
    """Non-zeros of Γ for ``bands`` (the length of the list ``triple_product`` loops over)."""
    from prtbench.transport.sh import triple_product_sparse

    return int(len(triple_product_sparse(bands)[1]))


def triple_product_counts(bands: int) -> dict[str, float]:
    """``triple_product`` (prt_shading.glsl) at one point: per Γ entry one buffer load, the
    index unpacking (3 integer operations) and ``(Γ·T_i)·L_j`` (1 + 3 madds). Γ itself is read from memory once per
    frame (its 8 bytes per entry are the same for every thread), see :func:`gamma_bytes`."""
    entries = triple_product_entries(bands)
    return {"madds": 4.0 * entries + 3.0 * entries, "fetches": float(entries), "bytes": 0.0}


def gamma_bytes(bands: int) -> float:
    """Bytes of the Γ list, read once per frame by the TP methods."""
    return 8.0 * triple_product_entries(bands)


def tpfl_product_madds(bands: int) -> float:
    """``tpfl_product`` (prt_shading.glsl): H_k += T_i · M_ik, an RGB madd per (i, k)."""
    return 3.0 * bands**4


def add_counts(*parts: Mapping[str, float]) -> dict[str, float]:
    """Sum of count dicts (``madds``, ``fetches``, ``bytes``)."""
    return {key: float(sum(p.get(key, 0.0) for p in parts)) for key in OPS_WEIGHTS}


def scaled(counts: Mapping[str, float], factor: float) -> dict[str, float]:
    """``counts`` times ``factor`` (per-pixel counts × covered pixels, ...)."""
    return {key: float(counts.get(key, 0.0)) * factor for key in OPS_WEIGHTS}
