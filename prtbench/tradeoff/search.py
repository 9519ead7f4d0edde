"""The adaptive search of ``prtbench advise`` over one :class:`~.search_space.SearchSpace`.

Within a method, candidates are ordered by their main knobs (more bands, texels, probes:
more accurate *and* more expensive), so one measurement decides others: a candidate that
misses an accuracy bound implies every candidate below it misses it too, one that breaks a
cost ceiling implies every candidate above it does, one that meets everything makes every
candidate above it pointless (it costs more), and so does one that already costs more than
the cheapest feasible candidate of any method. Only measurements decide: a candidate nothing
measured decides is searched, however far from where the scene analysis points.

Each method's search first measures where the analysis points (``MethodSpace.start``), then,
per round, the undecided candidate in the middle of what is left (a binary search along one
knob), so a good analysis saves cells and a wrong one costs a few, never the answer. A search
that refines a screening result starts at the screening optimum and stays in a region around
it, widened only while the region may hide a cheaper feasible candidate (:class:`Region`).
"""

from __future__ import annotations

import dataclasses
import math
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from prtbench.bench.intervals import over_views
from prtbench.tradeoff.expressions import Constraint, row_value
from prtbench.tradeoff.search_space import Candidate, SearchSpace


@dataclass
class CellResult:
    """What one evaluated cell returned: its result rows (one per view) or an error."""

    rows: list[dict[str, Any]]
    error: str = ""


@dataclass
class Evaluation:
    """One candidate measured at one profile, judged against the target and budget.

    Attributes
    ----------
    candidate : Candidate
    profile : str
    row : dict or None
        The cell's rows aggregated (metrics and frame time averaged over views).
    error : str
        Why the cell has no usable row ('' when it has one).
    cost : float
        The ``cost_kind`` value (inf when unmeasured).
    failed : tuple of Constraint
        The constraints it misses.
    shortfall : float
        Sum of the missed constraints' relative shortfalls (inf if a value is missing).
    values : dict of str to float or None
        The measured value of each constrained quantity (metric key or cost kind).
    """

    candidate: Candidate
    profile: str
    row: dict[str, Any] | None
    error: str
    cost: float
    failed: tuple[Constraint, ...]
    shortfall: float
    values: dict[str, float | None] = field(default_factory=dict)

    @property
    def feasible(self) -> bool:
        return self.row is not None and not self.failed

    def key(self) -> tuple:
        """Sort key: feasible by cost, then the rest by shortfall, then cost."""
        return (0, self.cost, 0.0) if self.feasible else (1, self.shortfall, self.cost)


def as_dict(row: Any) -> dict[str, Any]:
    return dataclasses.asdict(row) if dataclasses.is_dataclass(row) else dict(row)


def normalise(result: Any) -> CellResult:
    """A CellResult from what an ``evaluate`` returned for one cell: a CellResult, a
    sweep CellOutcome (``rows``, ``status``, ``error``) or a plain list of rows."""
    if isinstance(result, CellResult):
        return result
    if hasattr(result, "rows"):
        rows = [as_dict(r) for r in (result.rows or [])]
        status = getattr(result, "status", "done")
        error = "" if rows and status != "failed" else (getattr(result, "error", "") or status)
        return CellResult(rows if not error else [], error)
    return CellResult([as_dict(r) for r in (result or [])], "" if result else "no rows")


def aggregate(rows: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """One row for a cell: metrics, frame time and pixel counts averaged over its views,
    memory and precompute their maximum, anything else from the first view."""
    first = dict(rows[0])
    metrics = {}
    for key in first.get("metrics") or {}:
        values = [float(v) for r in rows if (v := (r.get("metrics") or {}).get(key)) is not None]
        metrics[key] = float(np.mean(values)) if values else None
    first["metrics"] = metrics
    for key in ("frame_ms", "frame_ms_p95", "covered_pixels"):
        values = [float(r[key]) for r in rows if r.get(key) is not None]
        first[key] = float(np.mean(values)) if values else None
    for key in ("memory_bytes", "precompute_s"):  # max keeps bytes an int
        values = [r[key] for r in rows if r.get(key) is not None]
        first[key] = max(values) if values else None
    # The 95 % interval of each masked metric over the views (the reference's noise and the
    # spread over views, docs/PROTOCOL.md): a target is met only by its pessimistic end.
    intervals = {}
    for key in ("psnr_masked", "flip_masked"):
        values, los, his = [], [], []
        for r in rows:
            value = (r.get("metrics") or {}).get(key)
            if value is None or not math.isfinite(float(value)):
                continue
            values.append(float(value))
            los.append(r.get(f"{key}_lo"))
            his.append(r.get(f"{key}_hi"))
        if values:
            _, lo, hi = over_views(values, los, his)
            intervals[key] = (lo, hi)
    first["metric_intervals"] = intervals
    bad = [r for r in rows if r.get("status", "ok") != "ok"]
    if bad:
        first["status"], first["status_reason"] = bad[0].get("status"), bad[0].get("status_reason", "")
    return first


def pessimistic(row: Mapping[str, Any], constraint: Constraint, value: float | None
                ) -> float | None:
    """The end of a metric's interval that must still meet ``constraint``: the lower bound for
    ``psnr_masked >= 30``, the upper one for ``flip_masked <= 0.1`` (docs/PROTOCOL.md: a target
    is met beyond the intervals); the value itself for costs and metrics without one."""
    if constraint.kind != "metric" or value is None:
        return value
    lo, hi = (row.get("metric_intervals") or {}).get(constraint.name, (None, None))
    bound = lo if constraint.op in (">=", ">") else hi
    return value if bound is None or not math.isfinite(bound) else bound


#: Relative shortfall below which a missed accuracy bound is a near miss (3 %: 0.5 dB at
#: 17 dB, 0.9 dB at 30 dB), which does not rule out the candidates below (:func:`clear_miss`).
NEAR_MISS = 0.03


class Judge:
    """Turns a cell's result into an :class:`Evaluation` against target and budget."""

    def __init__(self, constraints: Sequence[Constraint], cost_kind: str, cost_fn):
        self.constraints, self.cost_kind, self.cost_fn = list(constraints), cost_kind, cost_fn

    def __call__(self, candidate: Candidate, profile: str, result: CellResult) -> Evaluation:
        if not result.rows:
            return Evaluation(candidate, profile, None, result.error or "no rows", math.inf,
                              tuple(self.constraints), math.inf)
        row = aggregate(result.rows)
        cost = row_value(row, Constraint(self.cost_kind, "<=", 0, "", "cost"), self.cost_fn)
        cost = math.inf if cost is None or not math.isfinite(cost) else cost
        values = {c: row_value(row, c, self.cost_fn) for c in self.constraints}
        failed = tuple(c for c in self.constraints if not c.holds(pessimistic(row, c, values[c])))
        shortfall = sum(c.shortfall(pessimistic(row, c, values[c])) for c in failed)
        named = {c.name: v for c, v in values.items()}
        if row.get("status", "ok") != "ok":  # degenerate: its numbers are not measurements
            return Evaluation(candidate, profile, row, f"{row['status']}: "
                              f"{row.get('status_reason', '')}", cost,
                              failed or tuple(self.constraints), math.inf, named)
        return Evaluation(candidate, profile, row, "", cost, failed, shortfall, named)


def clear_miss(e: Evaluation, constraint: Constraint) -> bool:
    """Whether ``e`` misses the accuracy bound ``constraint`` by more than :data:`NEAR_MISS`.

    Accuracy grows with the model only on average: measured, one more SH band can lose a few
    tenths of a dB (ringing, the noise of the transfer and of the reference; dining-table
    under sun at smoke: 17.2 dB at 4 bands, 16.9 at 5 to 8). So only a clear miss says that
    every candidate below misses too; a near miss decides nothing below it.
    """
    value = e.values.get(constraint.name)
    return (constraint.grows_with_model is True and constraint in e.failed
            and constraint.shortfall(value) > NEAR_MISS)


def _decided(c: Candidate, done: Mapping[Candidate, Evaluation], incumbent: float) -> bool:
    """Whether the measured candidates already decide ``c`` (see the module docstring).

    ``incumbent`` is the cost of the cheapest feasible candidate found so far, any method:
    a candidate above one that already costs as much cannot beat it.
    """
    for d, e in done.items():
        if e.row is None or e.error:  # a failed or degenerate cell implies nothing
            continue
        if c.below(d) and any(clear_miss(e, k) for k in e.failed):
            return True  # models less than one that clearly misses an accuracy bound
        if d.below(c) and (e.feasible or e.cost >= incumbent
                           or any(k.grows_with_model is False for k in e.failed)):
            return True  # models more than one that meets all, costs too much, or breaks a cost
    return False


def _next(space_candidates: Sequence[Candidate], done: Mapping[Candidate, Evaluation],
          start: Candidate | None, incumbent: float = math.inf) -> Candidate | None:
    """The next candidate of one method: ``start`` first, then the middle of the undecided."""
    undecided = [c for c in space_candidates if c not in done and not _decided(c, done, incumbent)]
    if not undecided:
        return None
    if start in undecided:
        return start
    undecided.sort(key=lambda c: (sum(c.ranks), c.ranks))
    return undecided[len(undecided) // 2]  # the upper middle: an unreachable top ends it at once


class Region:
    """The candidates one method's search may visit: all of them, or (refining a screening
    result) those within ``radius`` ladder steps of ``start``, widened while the best found
    sits on the region's lower edge or nothing in it is feasible."""

    def __init__(self, candidates: Sequence[Candidate], start: Candidate | None):
        self.all, self.start = list(candidates), start
        self.radius = 1 if start is not None and start in self.all else None

    def _distance(self, c: Candidate) -> int:
        steps = [abs(a - b) for a, b in zip(c.ranks, self.start.ranks)]
        return max(steps, default=0) + (c.unordered != self.start.unordered)

    def candidates(self) -> list[Candidate]:
        if self.radius is None:
            return self.all
        return [c for c in self.all if self._distance(c) <= self.radius]

    def widen(self, done: Mapping[Candidate, Evaluation]) -> bool:
        """Widen by one step if the region may hide a cheaper feasible candidate: nothing in
        it is feasible, or a candidate on its lower edge meets the accuracy bounds (one below
        it might too, for less)."""
        if self.radius is None or len(self.candidates()) == len(self.all):
            return False
        if not any(e.feasible for e in done.values()):
            self.radius += 1
            return True
        for c, e in done.items():
            on_edge = any(r == s - self.radius and r > 0 for r, s in zip(c.ranks, self.start.ranks))
            accurate = e.row is not None and not e.error and not any(
                k.grows_with_model is True for k in e.failed)
            if on_edge and accurate and self._distance(c) <= self.radius:
                self.radius += 1
                return True
        return False


def search(space: SearchSpace, methods: Sequence[str], *, profile: str, judge: Judge,
           run_batch=None, pool=None, starts: Mapping[str, Candidate] | None = None,
           echo: bool = False) -> list[Evaluation]:
    """Search the candidates of ``methods`` at one profile; returns every evaluation made.

    Each method's search is a chain (its next candidate follows from its results); the chains
    of different methods are independent, so they run side by side:

    * ``run_batch(candidates, profile) -> results``: in rounds, one candidate per undecided
      method per round, evaluated as one batch;
    * ``pool`` (``submit(candidate, profile)`` and ``next_result() -> (candidate, result)``):
      without rounds, a method's next candidate is sent as soon as its last one came back, so
      parallel workers never wait for the slowest method of a round.

    A method with a start (its screening optimum) is searched in a region around it
    (:class:`Region`); one without starts where the analysis points (``MethodSpace.start``)
    and may go anywhere in its space.
    """
    if (run_batch is None) == (pool is None):
        raise ValueError("search needs one of run_batch and pool")
    starts = dict(starts or {})
    firsts = {m: starts.get(m) or space.space_of(m).start for m in methods}
    done: dict[str, dict[Candidate, Evaluation]] = {m: {} for m in methods}
    regions = {m: Region(space.space_of(m).candidates, starts.get(m)) for m in methods}
    history: list[Evaluation] = []
    in_flight: dict[str, list[Candidate]] = {m: [] for m in methods}
    finished: set[str] = set()

    def next_of(m: str, incumbent: float) -> Candidate | None:
        while (c := _next(regions[m].candidates(), done[m], firsts[m], incumbent)) is None:
            if not regions[m].widen(done[m]):
                return None
        return c

    def record(candidate: Candidate, result) -> None:
        e = judge(candidate, profile, result)
        done[candidate.method][candidate] = e
        history.append(e)
        if echo:
            print(f"[advise] {profile}: {candidate.method} {candidate.label()}: "
                  f"{brief(e, judge)}", file=sys.stderr, flush=True)

    while True:
        incumbent = min((e.cost for e in history if e.feasible), default=math.inf)
        batch = []
        for m in methods:
            if in_flight[m] or m in finished:
                continue
            c = next_of(m, incumbent)
            if c is None:
                finished.add(m)
            else:
                batch.append(c)
        if pool is None:
            if not batch:
                return history
            for candidate, result in zip(batch, run_batch(batch, profile)):
                record(candidate, result)
            continue
        for candidate in batch:
            pool.submit(candidate, profile)
            in_flight[candidate.method].append(candidate)
        if not any(in_flight.values()):
            return history
        candidate, result = pool.next_result()
        in_flight[candidate.method].remove(candidate)
        record(candidate, result)


def brief(e: Evaluation, judge: Judge) -> str:
    if e.row is None:
        return f"failed ({e.error})"
    parts = []
    for c in judge.constraints:
        text = f"{c.name}={fmt(e.values.get(c.name))}"
        lo, hi = (e.row.get("metric_intervals") or {}).get(c.name, (None, None))
        if c.kind == "metric" and lo is not None and hi is not None:
            text += f" [{fmt(lo)}, {fmt(hi)}]"
        parts.append(text)
    return (", ".join(parts) + f", {judge.cost_kind}={fmt(e.cost)} "
            + ("meets all" if e.feasible else f"misses {', '.join(c.text for c in e.failed)}"))


def fmt(x: Any) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    return f"{x:.4g}" if isinstance(x, float) else str(x)


def best_per_method(history: Sequence[Evaluation]) -> dict[str, Evaluation]:
    best: dict[str, Evaluation] = {}
    for e in history:
        if e.candidate.method not in best or e.key() < best[e.candidate.method].key():
            best[e.candidate.method] = e
    return best
