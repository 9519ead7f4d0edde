"""Pareto fronts: points (one configuration's error and cost), dominance, fronts per panel
and the ops-model correlation, independent of where the rows come from or how they are drawn
(:mod:`prtbench.tradeoff.pareto` reads the store, :mod:`prtbench.tradeoff.pareto_report`
writes the tables and plots)."""

from __future__ import annotations

import json
import math
from collections import defaultdict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from prtbench.api.errors import UnknownNameError
from prtbench.tradeoff import cost as cost_mod

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

    @property
    def panel(self) -> tuple[str, int, int]:
        return (self.variant, self.width, self.height)

    @property
    def config_json(self) -> str:
        return json.dumps(self.config, sort_keys=True)


def _metric(row, name: str) -> float | None:
    value = (row.metrics or {}).get(name)
    try:
        value = float(value)
    except (TypeError, ValueError):
        return None
    return value if math.isfinite(value) else None


def collect_points(rows: Iterable, *, error: str, cost: str) -> tuple[list[Point], list[str]]:
    """Group ok rows against the path reference into configurations.

    Parameters
    ----------
    rows : iterable of ResultRow
        Usually one scene, light and profile.
    error, cost : str
        :data:`ERRORS` key and :data:`prtbench.tradeoff.cost.COST_KINDS` entry.

    Returns
    -------
    points : list of Point
        Sorted by panel, method and config; ``dominated`` not yet set.
    skipped : list of str
        One line per configuration left out (no finite error in any of its rows).
    """
    check_error_kind(error)
    cost_mod.check_cost_kind(cost)
    groups: dict[tuple, list] = defaultdict(list)
    for row in rows:
        if row.status != "ok" or row.reference_kind != "path":
            continue
        key = (row.method, json.dumps(row.config, sort_keys=True), row.scene, row.scene_variant,
               row.light, row.profile, int(row.width), int(row.height))
        groups[key].append(row)
    points, skipped = [], []
    for key in sorted(groups):
        method, config_json, scene, variant, light, profile, width, height = key
        group = groups[key]
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
        points.append(Point(
            method=method, config=json.loads(config_json), scene=scene, variant=variant,
            light=light, profile=profile, width=width, height=height,
            error=sum(values) / len(values), error_unclipped=sum(raw) / len(raw), clipped=clipped,
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
            ops_counts=ops_counts))
    return points, skipped


def non_dominated(errors: Sequence[float], costs: Sequence[float], *,
                  higher_is_better: bool) -> list[bool]:
    """Which (error, cost) pairs no other pair dominates.

    ``a`` dominates ``b`` when ``a``'s error is at least as good and its cost at most ``b``'s,
    and one of the two strictly. Equal pairs do not dominate each other. Pairs with a NaN
    error or cost are neither dominated nor dominating: they are ``False`` here (the callers
    leave them off the front).

    Returns
    -------
    list of bool, len(errors)
    """
    sign = 1.0 if higher_is_better else -1.0
    good = [sign * float(e) for e in errors]  # larger is better
    costs = [float(c) for c in costs]
    valid = [math.isfinite(g) and math.isfinite(c) for g, c in zip(good, costs)]
    out = []
    for i in range(len(good)):
        if not valid[i]:
            out.append(False)
            continue
        dominated = any(valid[j] and good[j] >= good[i] and costs[j] <= costs[i]
                        and (good[j] > good[i] or costs[j] < costs[i]) for j in range(len(good)))
        out.append(not dominated)
    return out


def mark_fronts(points: list[Point], *, error: str) -> list[Point]:
    """Set ``dominated`` on every point, one front per panel (variant, resolution)."""
    panels: dict[tuple, list[Point]] = defaultdict(list)
    for p in points:
        panels[p.panel].append(p)
    for members in panels.values():
        front = non_dominated([p.error for p in members], [p.cost for p in members],
                              higher_is_better=ERRORS[error])
        for p, on in zip(members, front):
            p.dominated = None if not math.isfinite(p.cost) else not on
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


