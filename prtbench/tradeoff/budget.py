"""Equal-budget tables: each method's best configuration within a cost budget.

A Pareto front (:mod:`.pareto`) answers "what does each extra millisecond buy?"; an engine team
asks instead "with 64 MiB (or 2 ms a frame, or 2e9 operations a frame), what is each method's
best?". ``prtbench pareto --at memory=64MiB`` answers that from the same points
(:func:`prtbench.tradeoff.front.collect_points`: held-out or in-family rows only, no diagnostic
configuration, PSNR clipped at the reference's noise ceiling) and the same panels (one
reference and one view set):

- per panel and method, the configuration with the best error whose cost is within the budget
  (cost <= budget), ties in error going to the lower cost (:func:`best_within`);
- a method with no configuration within the budget is listed as such with its cheapest
  configuration's cost, never dropped;
- rows ordered by error, best first; ``best`` marks the row better than every other method's
  row beyond the intervals (:func:`prtbench.tradeoff.dominance.better_beyond`); where no row is,
  every row no other row beats beyond the intervals is ``tied`` (:func:`mark_rows`).

The report, ``budget-<scene>-<light>-<kind>-<value>.{md,csv}``, is written atomically like the
Pareto reports; every number in it is a stored row's value or a mean of them.
"""

from __future__ import annotations

import csv
import difflib
import io
import math
import re
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from prtbench.api.cache import atomic_path
from prtbench.api.errors import InvalidInputError
from prtbench.store.results import git_sha
from prtbench.tradeoff import cost as cost_mod
from prtbench.tradeoff.dominance import better_beyond
from prtbench.tradeoff.expressions import COST_UNITS as EXPRESSION_UNITS
from prtbench.tradeoff.front import ERROR_LABELS, ERRORS, Point, knobs_text
from prtbench.tradeoff.pareto import light_points, open_selection
from prtbench.tradeoff.pareto_report import display_path, reference_of

#: Budget kind -> units a value may carry and their factor to the kind's base unit (ms, bytes,
#: s, operations per frame). Time and memory units are the advisor's (``advise --budget``), so
#: both commands read ``64MiB`` alike; an operation count takes decimal suffixes.
BUDGET_UNITS: dict[str, dict[str, float]] = {
    "frame_ms": EXPRESSION_UNITS["frame_ms"][1],
    "memory": EXPRESSION_UNITS["memory"][1],
    "precompute": EXPRESSION_UNITS["precompute"][1],
    "ops": {"k": 1e3, "K": 1e3, "M": 1e6, "G": 1e9},
}
#: What each kind accepts, for messages.
ACCEPTED = {
    "memory": "a number of bytes above 0, plain or with a unit B, KiB, MiB, GiB "
              "(binary; e.g. memory=64MiB)",
    "frame_ms": "a number of milliseconds above 0, plain or with a unit ms, s (e.g. frame_ms=16.7)",
    "precompute": "a number of seconds above 0, plain or with a unit s, ms (e.g. precompute=600)",
    "ops": "a number of operations per frame above 0, plain or with a suffix k, M, G "
           "(e.g. ops=2e9 or ops=2G)",
}
_KINDS_ACCEPTED = ("KIND=VALUE with KIND one of frame_ms, memory, ops, precompute "
                   "(e.g. memory=64MiB, frame_ms=16.7, ops=2e9, precompute=600)")
_VALUE = re.compile(r"^(?P<number>[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(?P<unit>[A-Za-z]*)$")
#: The marks of :func:`mark_rows`.
BEST, TIED = "best", "tied"


@dataclass(frozen=True)
class Budget:
    """A ceiling on one cost kind.

    Attributes
    ----------
    kind : str
        A cost kind of :data:`prtbench.tradeoff.cost.COST_KINDS`.
    value : float
        The ceiling in the kind's base unit (:data:`prtbench.tradeoff.cost.COST_UNITS`).
    text : str
        The value as the user wrote it (``64MiB``), for titles and file names.
    """

    kind: str
    value: float
    text: str

    @property
    def option(self) -> str:
        return f"{self.kind}={self.text}"

    def describe(self) -> str:
        """``memory ≤ 64MiB (67108864 bytes)``: as written and in the base unit."""
        return (f"{self.kind} ≤ {self.text} ({self.value:.10g} "
                f"{cost_mod.COST_UNITS[self.kind]})")


def parse_budget(text: str, *, cost: str | None = None) -> Budget:
    """Parse ``--at KIND=VALUE`` strictly, before any work.

    Parameters
    ----------
    text : str
        ``memory=64MiB``, ``frame_ms=16.7``, ``precompute=600``, ``ops=2e9``; units as
        :data:`BUDGET_UNITS` (sizes and times in any case, the ops suffixes as written).
    cost : str, optional
        ``--cost`` if the user gave it: it must be the budget's kind.

    Returns
    -------
    Budget

    Raises
    ------
    InvalidInputError
        One line naming the bad value and what is accepted: no ``=``, an unknown kind, an empty
        value, a value that is not a number, an unknown unit, a value that is not finite and
        above 0, or a ``--cost`` other than the budget's kind.
    """
    if not isinstance(text, str) or "=" not in text:
        raise InvalidInputError(f"--at '{text}': expected {_KINDS_ACCEPTED}")
    kind, value = (part.strip() for part in text.split("=", 1))
    if kind not in BUDGET_UNITS:
        close = difflib.get_close_matches(kind, list(BUDGET_UNITS), n=1, cutoff=0.6)
        hint = f"; did you mean '{close[0]}'?" if close else ""
        raise InvalidInputError(f"--at '{text}': unknown budget kind '{kind}'{hint}; accepted: "
                                f"{_KINDS_ACCEPTED}")
    if not value:
        raise InvalidInputError(f"--at '{text}': no {kind} value after '='; accepted: "
                                f"{ACCEPTED[kind]}")
    match = _VALUE.match(value)
    if match is None:
        raise InvalidInputError(f"--at '{text}': '{value}' is not a {kind} budget; accepted: "
                                f"{ACCEPTED[kind]}")
    unit, factor = match["unit"], 1.0
    if unit:
        # Sizes and times read as the advisor reads them (any case); the ops suffixes are
        # matched as written, so an 'm' is never taken for mega.
        if kind == "ops":
            factor = BUDGET_UNITS[kind].get(unit)
        else:
            factor = {u.lower(): f for u, f in BUDGET_UNITS[kind].items()}.get(unit.lower())
        if factor is None:
            raise InvalidInputError(f"--at '{text}': unit '{unit}' is not one {kind} takes; "
                                    f"accepted: {ACCEPTED[kind]}")
    ceiling = float(match["number"]) * factor
    if not math.isfinite(ceiling) or ceiling <= 0.0:
        raise InvalidInputError(f"--at '{text}': a {kind} budget must be finite and above 0, "
                                f"not '{value}'; accepted: {ACCEPTED[kind]}")
    if cost is not None:
        cost_mod.check_cost_kind(cost)
        if cost != kind:
            raise InvalidInputError(f"--at '{text}' budgets {kind} but --cost is '{cost}'; "
                                    f"accepted: --cost {kind}, or no --cost (--at sets it)")
    return Budget(kind=kind, value=ceiling, text=value)


@dataclass
class BudgetRow:
    """One method in one panel: its best configuration within the budget, or none.

    Attributes
    ----------
    method, panel : str
    point : Point or None
        The configuration chosen; None when none is within the budget.
    cheapest : Point or None
        Without a ``point``: the method's cheapest configuration of known cost (None when no
        configuration's cost is known).
    note : str
        Why no configuration's cost is known (the points' notes), else empty.
    mark : str
        :data:`BEST`, :data:`TIED` or ``""`` (:func:`mark_rows`).
    """

    method: str
    panel: str
    point: Point | None
    cheapest: Point | None = None
    note: str = ""
    mark: str = ""

    @property
    def within(self) -> bool:
        return self.point is not None


def _sign(error: str) -> float:
    return 1.0 if ERRORS[error] else -1.0


def best_within(points: Sequence[Point], *, budget: Budget, error: str) -> list[BudgetRow]:
    """Each method's best configuration within ``budget``, per panel, marked and ordered.

    Parameters
    ----------
    points : sequence of Point
        From :func:`prtbench.tradeoff.front.collect_points` with ``cost=budget.kind``.
    budget : Budget
    error : str
        The :data:`prtbench.tradeoff.front.ERRORS` key the points carry.

    Returns
    -------
    list of BudgetRow
        By panel; within a panel the rows within budget by error (best first; then cost,
        then method), then the methods with none within budget by their cheapest cost.
    """
    sign = _sign(error)
    by_panel: dict[str, dict[str, list[Point]]] = defaultdict(lambda: defaultdict(list))
    for p in points:
        by_panel[p.panel][p.method].append(p)
    out: list[BudgetRow] = []
    for panel in sorted(by_panel):
        rows = []
        for method, mine in sorted(by_panel[panel].items()):
            priced = [p for p in mine if math.isfinite(p.cost)]
            within = [p for p in priced if p.cost <= budget.value]
            if within:
                best = min(within, key=lambda p: (-sign * p.error, p.cost, p.config_json))
                rows.append(BudgetRow(method=method, panel=panel, point=best))
            elif priced:
                rows.append(BudgetRow(method=method, panel=panel, point=None,
                                      cheapest=min(priced, key=lambda p: (p.cost, p.config_json))))
            else:
                notes = sorted({p.note for p in mine if p.note})
                rows.append(BudgetRow(method=method, panel=panel, point=None,
                                      note="; ".join(notes) or f"no {budget.kind} stored"))
        rows.sort(key=lambda r: (0, -sign * r.point.error, r.point.cost, r.method) if r.within
                  else (1, r.cheapest.cost if r.cheapest else math.inf, 0.0, r.method))
        mark_rows(rows, error=error)
        out += rows
    return out


def mark_rows(rows: Sequence[BudgetRow], *, error: str) -> None:
    """Set ``mark`` on one panel's rows within budget.

    ``best``: the row better than every other method's row beyond the intervals (paired over
    the views both were measured on, :func:`~prtbench.tradeoff.dominance.better_beyond`); a panel
    where one method alone fits the budget has that one as ``best``. Where no row is best,
    every row that no other row beats beyond the intervals is ``tied``: the measurements
    cannot tell which of them is best. The others stay unmarked.
    """
    higher = ERRORS[error]
    chosen = [r for r in rows if r.within]
    for r in chosen:
        r.mark = ""
    for r in chosen:
        if all(better_beyond(r.point, q.point, higher_is_better=higher)
               for q in chosen if q is not r):
            r.mark = BEST
            return
    for r in chosen:
        if not any(better_beyond(q.point, r.point, higher_is_better=higher)
                   for q in chosen if q is not r):
            r.mark = TIED


@dataclass
class BudgetResult:
    """What :func:`budget_tables` computed and wrote for one scene and light."""

    scene: str
    light: str
    error: str
    profile: str
    budget: Budget
    rows: list[BudgetRow]
    skipped: list[str]
    paths: list[Path] = field(default_factory=list)


def _safe(text: str) -> str:
    """Letters, digits, ``.`` and ``_`` kept, anything else ``_`` (as the Pareto reports)."""
    return re.sub(r"[^A-Za-z0-9._]+", "_", Path(text).stem if "/" in text else text)


def report_stem(scene: str, light: str, budget: Budget) -> str:
    """``budget-<scene>-<light>-<kind>-<value>``, the value as written, filename-safe."""
    return f"budget-{_safe(scene)}-{_safe(light)}-{budget.kind}-{_safe(budget.text)}"


def _number(value: float | None, digits: int = 4) -> str:
    if value is None or not math.isfinite(value):
        return "—"
    if abs(value) >= 1e5 or (value != 0 and abs(value) < 1e-3):
        return f"{value:.{digits - 1}e}"
    return f"{value:.{digits}g}"


def format_cost(value: float, kind: str) -> str:
    """A cost with its unit: ``48.5 MiB`` (binary units for bytes), ``2.5 ms``, ``2.00e+09 ops``."""
    if not math.isfinite(value):
        return "—"
    if kind == "memory":
        for unit, size in (("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)):
            if value >= size:
                return f"{value / size:.4g} {unit}"
        return f"{value:.4g} B"
    return f"{_number(value)} {cost_mod.COST_UNITS[kind].split('/')[0]}"


def interval_text(point: Point) -> str:
    if not (math.isfinite(point.error_lo) and math.isfinite(point.error_hi)):
        return "—"
    return f"{_number(point.error_lo)}–{_number(point.error_hi)}"


def none_text(row: BudgetRow, kind: str) -> str:
    """``none within budget (cheapest: 80 MiB)``, or why no cost is known."""
    if row.cheapest is not None:
        return f"none within budget (cheapest: {format_cost(row.cheapest.cost, kind)})"
    return f"none within budget ({kind} unknown: {row.note})"


def _panels(rows: Sequence[BudgetRow]) -> dict[str, list[BudgetRow]]:
    panels: dict[str, list[BudgetRow]] = defaultdict(list)
    for r in rows:
        panels[r.panel].append(r)
    return dict(panels)


def csv_text(result: BudgetResult) -> str:
    """One line per panel and method (full float precision; empty where not applicable)."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(("scene", "light", "panel", "reference", "profile", "method", "within_budget",
                     "mark", "config", "knobs", "error_kind", "error", "error_lo", "error_hi",
                     "clipped", "cost_kind", "cost", "budget", "budget_as_written",
                     "light_class", "split", "views", "rows", "run_ids", "cheapest_config",
                     "cheapest_cost", "note"))
    finite = lambda v: repr(v) if v is not None and math.isfinite(v) else ""  # noqa: E731
    for r in result.rows:
        p, c = r.point, r.cheapest
        writer.writerow([
            result.scene, result.light, r.panel, reference_of(r.panel), result.profile, r.method,
            int(r.within), r.mark, p.config_json if p else "", knobs_text(p) if p else "",
            result.error, finite(p.error) if p else "", finite(p.error_lo) if p else "",
            finite(p.error_hi) if p else "", int(p.clipped) if p else "", result.budget.kind,
            finite(p.cost) if p else "", repr(result.budget.value), result.budget.text,
            p.light_class if p else "", p.split if p else "", p.views if p else "",
            p.rows if p else "", ";".join(p.run_ids) if p else "",
            c.config_json if c else "", finite(c.cost) if c else "",
            "" if p else none_text(r, result.budget.kind)])
    return out.getvalue()


def _table_lines(rows: Sequence[BudgetRow], *, error: str, kind: str) -> list[str]:
    lines = [f"| mark | method | knobs | {error} | interval | {kind} | light class | split "
             "| views |", "|---|---|---|---:|---|---:|---|---|---:|"]
    for r in rows:
        p = r.point
        if p is None:
            lines.append(f"| | {r.method} | {none_text(r, kind)} | | | | | | |")
            continue
        clipped = " (at ceiling)" if p.clipped else ""
        lines.append(f"| {r.mark} | {r.method} | {knobs_text(p)} | {_number(p.error)}{clipped} "
                     f"| {interval_text(p)} | {format_cost(p.cost, kind)} | {p.light_class} "
                     f"| {p.split} | {p.views} |")
    return lines


def markdown_text(result: BudgetResult, *, results_path: Path) -> str:
    """The report: provenance, what the budget and the marks mean, one table per panel."""
    error, budget = result.error, result.budget
    chosen = [r.point for r in result.rows if r.point is not None]
    renderers = sorted({x for p in chosen for x in p.renderers})
    devices = sorted({x for p in chosen for x in p.devices})
    shas = sorted({x for p in chosen for x in p.git_shas})
    better = "higher" if ERRORS[error] else "lower"
    lines = [
        f"# Equal budget: {result.scene} under {result.light}, {budget.kind} ≤ {budget.text} "
        f"({error})", "",
        f"Generated by `prtbench pareto --scene {result.scene} --light {result.light} "
        f"--error {error} --at {budget.option} --profile {result.profile}` from "
        f"`{display_path(results_path)}` (read-only) with prtbench {git_sha()}, under the "
        "protocol of docs/PROTOCOL.md.", "",
        f"- Budget: {budget.describe()}. Per method, the configuration with the best error whose "
        "cost is within the budget (ties in error go to the lower cost); a method with none is "
        "listed with its cheapest configuration's cost.",
        f"- Error: {ERROR_LABELS[error]} against the path-traced reference, mean over a "
        f"configuration's views ({better} is better), with its 95 % interval (the reference's "
        "Monte Carlo noise and the spread over views); PSNR above the reference's noise ceiling "
        "is clipped to it ('at ceiling').",
        "- Mark: 'best' is better than every other method's row beyond the intervals (paired "
        "over shared views), or the only method within budget; where no row is, 'tied' marks "
        "every row no other row beats beyond the intervals.",
        f"- Profile: {result.profile}. Rows measured by code version(s): "
        f"{', '.join(shas) or 'unknown'}.",
    ]
    if budget.kind == "frame_ms":
        lines.append(f"- Frame times are device-specific: renderer(s) "
                     f"{'; '.join(renderers) or 'unknown'}, device(s) "
                     f"{'; '.join(devices) or 'unknown'}.")
    lines.append("")
    for panel, rows in _panels(result.rows).items():
        fits = sum(r.within for r in rows)
        lines += [f"## {panel}", "",
                  f"{fits} of {len(rows)} methods have a configuration within the budget; "
                  f"reference {reference_of(panel) or 'unknown'}.", "",
                  *_table_lines(rows, error=error, kind=budget.kind), ""]
    if result.skipped:
        lines += ["Left out:", *[f"- {s}" for s in result.skipped], ""]
    return "\n".join(lines)


def summary_text(result: BudgetResult) -> str:
    """What the CLI prints: each panel's table and where the files went."""
    budget = result.budget
    lines = [f"budget {result.scene}/{result.light}: best {result.error} with "
             f"{budget.describe()} ({result.profile})"]
    for panel, rows in _panels(result.rows).items():
        lines.append(f"  {panel}")
        for r in rows:
            p = r.point
            if p is None:
                lines.append(f"    {'':5s} {r.method:22s} {none_text(r, budget.kind)}")
                continue
            lines.append(f"    {r.mark:5s} {r.method:22s} {knobs_text(p):36s} {result.error}="
                         f"{_number(p.error)} [{interval_text(p)}]"
                         f"{' (at ceiling)' if p.clipped else ''}  {budget.kind}="
                         f"{format_cost(p.cost, budget.kind)}  {p.light_class} {p.split} "
                         f"{p.views} views")
    lines += [f"wrote {path}" for path in result.paths]
    return "\n".join(lines)


def write_reports(result: BudgetResult, *, reports_dir: Path, results_path: Path) -> list[Path]:
    """``budget-<scene>-<light>-<kind>-<value>.{md,csv}`` in ``reports_dir``, each atomically."""
    stem = report_stem(result.scene, result.light, result.budget)
    md, csv_path = reports_dir / f"{stem}.md", reports_dir / f"{stem}.csv"
    with atomic_path(csv_path) as tmp:
        tmp.write_text(csv_text(result))
    with atomic_path(md) as tmp:
        tmp.write_text(markdown_text(result, results_path=results_path) + "\n")
    return [md, csv_path]


def budget_tables(*, scene: str, budget: Budget, light: str | None = None,
                  error: str = "psnr_masked", profile: str = "quick",
                  results_path: str | Path | None = None, reports_dir: str | Path = "reports",
                  scene_params: dict | None = None) -> list[BudgetResult]:
    """The equal-budget table of ``scene`` (every stored light, or ``light``) and its reports.

    Checks every option and reads the store (read-only) as :func:`.pareto.pareto` does; the
    reports are written only once every light's table is computed, so an error leaves nothing
    behind. Raises PrtbenchError (one line) for bad names and an empty selection.
    """
    selection = open_selection(scene=scene, light=light, error=error, cost=budget.kind,
                               profile=profile, results_path=results_path,
                               reports_dir=reports_dir, scene_params=scene_params)
    results = []
    for name in selection.rows_by_light:
        points, skipped = light_points(selection, name, error=error, cost=budget.kind)
        results.append(BudgetResult(scene=selection.scene, light=name, error=error,
                                    profile=profile, budget=budget,
                                    rows=best_within(points, budget=budget, error=error),
                                    skipped=skipped))
    for result in results:
        result.paths = write_reports(result, reports_dir=Path(reports_dir),
                                     results_path=selection.path)
    return results
