"""Pareto fronts: points (one configuration's error and cost), dominance, fronts per panel
and the ops-model correlation, independent of where the rows come from or how they are drawn
(:mod:`prtbench.tradeoff.pareto` reads the store, :mod:`prtbench.tradeoff.pareto_report`
writes the tables and plots)."""

from __future__ import annotations

import json
import math
import re
from collections import defaultdict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from prtbench.api import config as config_mod
from prtbench.api.errors import PrtbenchError, UnknownNameError
from prtbench.api.method import METHODS
from prtbench.bench.intervals import over_views
from prtbench.tradeoff import cost as cost_mod
from prtbench.tradeoff.dominance import better_beyond, non_dominated

#: Error metrics and whether higher is better.
ERRORS = {"psnr_masked": True, "flip_masked": False}
#: Labels for reports and axes.
ERROR_LABELS = {"psnr_masked": "masked PSNR (dB)", "flip_masked": "masked FLIP"}


def check_error_kind(kind: str) -> str:
    """``kind`` if it is an error metric of :data:`ERRORS`, else an UnknownNameError."""
    if kind not in ERRORS:
        raise UnknownNameError("error metric", str(kind), ERRORS)
    return kind


def noise_ceiling_db(reference_noise) -> float | None:
    """PSNR a perfect method would score against a reference with this display noise RMSE."""
    try:
        noise = float(reference_noise)
    except (TypeError, ValueError):
        return None
    if not math.isfinite(noise) or noise <= 0.0:
        return None
    return -20.0 * math.log10(noise)


@dataclass
class Point:
    """One configuration on one scene and light (the mean of its views' rows).

    Attributes
    ----------
    error : float
        Mean over the rows of the error metric, each PSNR clipped at its reference's ceiling.
    error_unclipped : float
        The same mean without clipping.
    clipped : bool
        Some view's PSNR was above its reference's noise ceiling.
    ceiling_db : float or None
        Mean noise ceiling of the rows' references (PSNR only).
    cost : float
        Mean cost of the rows (for ``frame_ms`` only those measured with ``workers == 1`` when
        there are any); NaN when unknown, ``note`` says why.
    dominated : bool or None
        None when the cost is unknown (not placed on a front).
    """

    method: str
    config: dict
    scene: str
    variant: str
    light: str
    profile: str
    width: int
    height: int
    error: float
    error_unclipped: float
    clipped: bool
    ceiling_db: float | None
    cost: float
    views: int
    rows: int
    run_ids: list[str]
    timing_workers: list[int] = field(default_factory=list)
    devices: list[str] = field(default_factory=list)
    renderers: list[str] = field(default_factory=list)
    git_shas: list[str] = field(default_factory=list)
    #: 1-min load averages stored with the timed rows (the machine's state while measuring).
    loads: list[float] = field(default_factory=list)
    note: str = ""
    dominated: bool | None = None
    #: Mean ``madds``, ``fetches``, ``bytes`` of the ops model over the rows (empty if unknown),
    #: whatever the cost kind, so every report shows what the model counts.
    ops_counts: dict = field(default_factory=dict)
    #: The 95 % interval of ``error`` (the reference's noise and the spread over views,
    #: :func:`prtbench.bench.intervals.over_views`).
    error_lo: float = math.nan
    error_hi: float = math.nan
    #: The protocol's panel (same reference and view set), light class and split.
    panel_name: str = ""
    light_class: str = ""
    split: str = ""
    #: Points that would dominate this one were it not for the intervals (shown as ties).
    tied_with: list[str] = field(default_factory=list)
    #: Means over the rows of the frame's parts (ms) and the resident parts (bytes), and of
    #: the per-light work (ms; NaN where no row has it).
    frame_components: dict = field(default_factory=dict)
    memory_breakdown: dict = field(default_factory=dict)
    light_change_ms: float = math.nan
    #: view (its camera as JSON; the index for rows without one) -> (value, lo, hi) of the
    #: error: what paired comparisons use.
    per_view: dict = field(default_factory=dict)

    @property
    def panel(self) -> str:
        return self.panel_name or f"{self.variant} {self.width}x{self.height}"

    @property
    def label(self) -> str:
        return f"{self.method} {self.config_json}"

    @property
    def config_json(self) -> str:
        return json.dumps(self.config, sort_keys=True)


def knobs_text(point: Point) -> str:
    """The knobs that differ from the method's config in the point's profile, ``k=v`` (the
    whole config when the method is not registered in this build)."""
    try:
        defaults = config_mod.to_dict(METHODS.get(point.method).make_config(
            {}, profile=point.profile))
    except Exception:  # a method no longer registered, or a profile it refuses: show all
        defaults = {}
    changed = {k: v for k, v in sorted(point.config.items()) if defaults.get(k, object()) != v}
    return ", ".join(f"{k}={v}" for k, v in changed.items()) or "(profile defaults)"


def _metric(row, name: str) -> float | None:
    value = (row.metrics or {}).get(name)
    try:
        value = float(value)
    except (TypeError, ValueError):
        return None
    return value if math.isfinite(value) else None


#: The view-set part of a panel's name (``views=4:1a2b3c4d``).
_VIEWS_TOKEN = re.compile(r" views=\S+")


def _legacy_panel(row) -> str:
    """The panel of a row stored before the protocol's ``panel`` column (schema < 6)."""
    return (f"{row.scene}/{row.scene_variant} {row.light} {row.width}x{row.height} "
            f"ref=path/{row.reference_spp}spp")


def _view_id(row) -> str:
    return json.dumps(row.view_json or {}, sort_keys=True)


def panel_memberships(rows: Sequence) -> list[tuple]:
    """(row, panel) pairs: each row in its own panel, and also in every fixed-view panel.

    A fixed-view panel is one whose rows were all measured on one view (a per-pixel method
    precomputes its transport for exactly that view). It takes, besides its own rows,
    every other row on that same view against the same reference (same scene, variant, light
    and resolution), so the fixed-view method is ranked against every method *on its view*
    and never beside means over other views (docs/PROTOCOL.md).
    """
    own = [(row, row.panel or _legacy_panel(row)) for row in rows]
    views_of: dict[str, set[str]] = defaultdict(set)
    for row, panel in own:
        views_of[panel].add(_view_id(row))
    fixed = {panel: next(iter(views)) for panel, views in views_of.items()
             if len(views) == 1 and "views=" in panel}
    out = list(own)
    for panel, view in fixed.items():
        prefix = _VIEWS_TOKEN.sub("", panel)
        out += [(row, panel) for row, home in own
                if home != panel and "views=" in home and _VIEWS_TOKEN.sub("", home) == prefix
                and _view_id(row) == view]
    return out


def collect_points(rows: Iterable, *, error: str, cost: str,
                   splits: Sequence[str] = ("held-out", "in-family")
                   ) -> tuple[list[Point], list[str]]:
    """Group ok rows against the path reference into configurations, under the protocol.

    Parameters
    ----------
    rows : iterable of ResultRow
        Usually one scene, light and profile.
    error, cost : str
        :data:`ERRORS` key and :data:`prtbench.tradeoff.cost.COST_KINDS` entry.
    splits : sequence of str
        The rows' splits a ranking takes (docs/PROTOCOL.md): held-out and in-family by
        default; a learnt or fitted method's ``trained`` rows are left out, and said so.

    Returns
    -------
    points : list of Point
        Sorted by panel, method and config; ``dominated`` not yet set. A configuration
        measured on two view sets or against two references is two points, in two panels.
    skipped : list of str
        One line per configuration left out (a diagnostic configuration, rows of a split the
        ranking does not take, or no finite error in any of its rows).
    """
    check_error_kind(error)
    cost_mod.check_cost_kind(cost)
    groups: dict[tuple, list] = defaultdict(list)
    usable = [r for r in rows if r.status == "ok" and r.reference_kind == "path"]
    for row, panel in panel_memberships(usable):
        key = (row.method, json.dumps(row.config, sort_keys=True), row.scene, row.scene_variant,
               row.light, row.profile, int(row.width), int(row.height), panel)
        groups[key].append(row)
    points, skipped = [], []
    for key in sorted(groups):
        method, config_json, scene, variant, light, profile, width, height, panel = key
        group = groups[key]
        why = diagnostic_reason(method, json.loads(config_json))
        if why:
            skipped.append(f"{method} {config_json}: a diagnostic configuration ({why}), "
                           "never ranked")
            continue
        row_splits = sorted({r.split or "unknown" for r in group})
        if not set(row_splits) & set(splits) and "unknown" not in row_splits:
            skipped.append(f"{method} {config_json}: measured on lights or views it was "
                           f"{'/'.join(row_splits)} on, not ranked (docs/PROTOCOL.md)")
            continue
        group = [r for r in group if (r.split or "unknown") in (*splits, "unknown")]
        values, raw, ceilings, clipped = [], [], [], False
        for row in group:
            value = _metric(row, error)
            if value is None:
                continue
            raw.append(value)
            ceiling = noise_ceiling_db(row.reference_noise) if error == "psnr_masked" else None
            if ceiling is not None:
                ceilings.append(ceiling)
                if value > ceiling:
                    value, clipped = ceiling, True
            values.append(value)
        if not values:
            skipped.append(f"{method} {config_json} ({variant}, {width}x{height}): no finite "
                           f"{error} in its {len(group)} row(s)")
            continue
        timed = group
        note = ""
        if cost == "frame_ms":
            alone = [r for r in group if r.workers == 1]
            if alone:
                timed = alone
            else:
                note = f"frame_ms measured with {sorted({r.workers for r in group})} concurrent workers"
        costs = [c for c in (cost_mod.cost_value(r, cost) for r in timed) if math.isfinite(c)]
        if not costs:
            note = cost_mod.cost_unavailable_reason(timed[0], cost) or f"no {cost}"
        ops_counts = {}
        try:
            counts = [cost_mod.ops_counts(r) for r in group]
            ops_counts = {k: sum(c[k] for c in counts) / len(counts) for k in cost_mod.OPS_WEIGHTS}
        except cost_mod.CostUnavailable:
            pass
        mean, lo, hi = interval_of(group, error, values)
        per_view = {}
        for r in group:
            v = _metric(r, error)
            if v is not None:
                ceiling = noise_ceiling_db(r.reference_noise) if error == "psnr_masked" else None
                v = min(v, ceiling) if ceiling is not None else v
                lo_v = getattr(r, "psnr_masked_lo", None) if error == "psnr_masked" else None
                hi_v = getattr(r, "psnr_masked_hi", None) if error == "psnr_masked" else None
                per_view[_view_id(r) if r.view_json else int(r.view)] = (v, v if lo_v is None else min(lo_v, v),
                                         v if hi_v is None else max(hi_v, v))
        points.append(Point(
            method=method, config=json.loads(config_json), scene=scene, variant=variant,
            light=light, profile=profile, width=width, height=height,
            error=mean, error_unclipped=sum(raw) / len(raw), clipped=clipped,
            ceiling_db=sum(ceilings) / len(ceilings) if ceilings else None,
            cost=sum(costs) / len(costs) if costs else math.nan,
            views=len({r.view for r in group}), rows=len(group),
            run_ids=sorted({r.run_id for r in group if r.run_id}),
            timing_workers=sorted({r.workers for r in timed}),
            devices=sorted({r.device for r in timed if r.device}),
            renderers=sorted({r.renderer for r in timed if r.renderer}),
            git_shas=sorted({r.git_sha for r in group if r.git_sha}),
            loads=[float(r.load_average) for r in timed
                   if r.load_average is not None and math.isfinite(r.load_average)], note=note,
            ops_counts=ops_counts, error_lo=lo, error_hi=hi, panel_name=panel,
            light_class=_one(r.light_class for r in group),
            split=_one(r.split for r in group),
            frame_components=_mean_parts(r.frame_components for r in timed),
            memory_breakdown=_mean_parts(r.memory_breakdown for r in group),
            light_change_ms=_mean([r.light_change_ms for r in group]), per_view=per_view))
    return points, skipped


def _mean_parts(parts: Iterable[dict]) -> dict:
    """The mean of each key over the dicts that have it."""
    sums: dict[str, list[float]] = defaultdict(list)
    for part in parts:
        for key, value in (part or {}).items():
            sums[key].append(float(value))
    return {k: sum(v) / len(v) for k, v in sorted(sums.items())}


def _mean(values: Sequence[float | None]) -> float:
    finite = [float(v) for v in values if v is not None and math.isfinite(float(v))]
    return sum(finite) / len(finite) if finite else math.nan


def _one(values: Iterable[str]) -> str:
    distinct = sorted({v for v in values if v})
    return "/".join(distinct) if distinct else "unknown"


def diagnostic_reason(method: str, config: dict) -> str | None:
    """The method's :meth:`~prtbench.api.method.Method.diagnostic_reason` for a stored config
    (None for a method this build does not know)."""
    if method not in METHODS:
        return None
    cls = METHODS.get(method)
    try:
        parsed = config_mod.from_dict(cls.Config, config)
    except PrtbenchError:
        return None  # a config of another code version: nothing to ask
    return cls.diagnostic_reason(parsed)


def interval_of(group: Sequence, error: str, values: Sequence[float]
                ) -> tuple[float, float, float]:
    """(mean, lo, hi) of the error over a configuration's views: each row's interval from the
    reference's noise (PSNR), widened by the spread over views."""
    if error == "psnr_masked":
        los = [getattr(r, "psnr_masked_lo", None) for r in group if _metric(r, error) is not None]
        his = [getattr(r, "psnr_masked_hi", None) for r in group if _metric(r, error) is not None]
    else:
        los = his = [None] * len(values)
    return over_views(list(values), los, his)


def mark_fronts(points: list[Point], *, error: str) -> list[Point]:
    """Set ``dominated`` on every point, one front per panel (one reference, one view set).

    ``a`` dominates ``b`` when it costs no more and its error is better beyond the intervals
    (:func:`better_beyond`), or it costs less for exactly the same error (e.g. both at the
    reference's noise ceiling). A point that only the intervals keep on the front records
    whom it ties with: its cost buys an error that may be better, as far as the measurements
    can tell.
    """
    panels: dict[str, list[Point]] = defaultdict(list)
    for p in points:
        panels[p.panel].append(p)
    higher = ERRORS[error]
    for members in panels.values():
        bare = non_dominated([p.error for p in members], [p.cost for p in members],
                             higher_is_better=higher)
        for i, p in enumerate(members):
            if not math.isfinite(p.cost):
                p.dominated = None
                continue
            rivals = [q for q in members if q is not p and math.isfinite(q.cost)
                      and q.cost <= p.cost]
            p.dominated = any(better_beyond(q, p, higher_is_better=higher)
                              or (q.cost < p.cost and q.error == p.error) for q in rivals)
            if not p.dominated and not bare[i]:  # the values alone would put it off
                p.tied_with = [q.label for q in rivals
                               if (q.error >= p.error if higher else q.error <= p.error)]
    return points


@dataclass
class ParetoResult:
    """What :func:`pareto` computed and wrote for one scene and light."""

    scene: str
    light: str
    error: str
    cost: str
    profile: str
    points: list[Point]
    skipped: list[str]
    correlation: dict
    paths: list[Path]


def ops_correlations(rows: Sequence) -> dict[str, dict]:
    """Spearman ρ of ``ops`` against measured ``frame_ms`` per renderer (device).

    Over the ok rows given (one scene and light), and over configurations (the mean frame
    time of each configuration's rows against its ops). Rows measured alone (``workers == 1``)
    are used when there are any. Timings of different renderers are never mixed.

    Returns
    -------
    dict
        renderer -> ``{"rows": (rho, p, n), "configs": (rho, p, n), "devices": [...]}``.
    """
    ok = [r for r in rows if r.status == "ok"]
    alone = [r for r in ok if r.workers == 1] or ok
    by_renderer: dict[str, list] = defaultdict(list)
    for r in alone:
        by_renderer[r.renderer or "unknown renderer"].append(r)
    out = {}
    for renderer, timed in sorted(by_renderer.items()):
        by_config: dict[tuple, list] = defaultdict(list)
        for r in timed:
            by_config[(r.method, json.dumps(r.config, sort_keys=True), r.scene_variant, r.width,
                       r.height)].append(r)
        ops_means, ms_means = [], []
        for group in by_config.values():
            ops = [v for v in (cost_mod.cost_value(r, "ops") for r in group) if math.isfinite(v)]
            ms = [v for v in (cost_mod.cost_value(r, "frame_ms") for r in group) if math.isfinite(v)]
            if ops and ms:
                ops_means.append(sum(ops) / len(ops))
                ms_means.append(sum(ms) / len(ms))
        out[renderer] = {"rows": cost_mod.ops_rank_correlation(timed),
                         "configs": _spearman(ops_means, ms_means),
                         "devices": sorted({r.device for r in timed if r.device})}
    return out


def _spearman(x: Sequence[float], y: Sequence[float]) -> tuple[float, float, int]:
    from scipy import stats

    if len(x) < 3 or len(set(x)) < 2 or len(set(y)) < 2:
        return math.nan, math.nan, len(x)
    result = stats.spearmanr(x, y)
    return float(result.statistic), float(result.pvalue), len(x)


