"""``prtbench advise``: the cheapest configuration that meets a target, verified by a real run.

1. **Prune** (:mod:`.search_space`): from the scene analysis, drop the methods and knob
   ranges that cannot model what the scene requires or model more than it needs; every
   pruned method is reported with its reason.
2. **Search adaptively** (:mod:`.search`), never the whole grid: a monotone lattice search
   per method (a measurement that misses an accuracy bound rules out everything below it,
   one that meets all rules out everything above it), about O(log n) runs per knob. Over
   fidelity this is **successive halving**: when the requested profile is larger than
   ``smoke`` and more than two methods remain, all are first searched at ``smoke``, the
   better ``keep_fraction`` of them (at least two; by target shortfall, then cost) go on to
   the requested profile, where each search starts from its ``smoke`` optimum and stays
   near it unless a cheaper feasible candidate may lie further out.
3. **Verify**: the winner is run again in the requested profile with its rows stored in the
   results store, and the answer reports that run's numbers; the advisor never answers from
   a model or a screening run alone. If the verified run misses, the runner-up is verified.

A target nothing reaches is not an error: :class:`Advice` holds the closest configuration
(least relative shortfall) and ``hint`` says what would be needed, from the knobs that sat at
the limit of their range and the analysis; the CLI exits 1.

``analysis``, ``evaluate`` and ``cost_fn`` are injected (tests pass synthetic ones); the
defaults are :func:`prtbench.tradeoff.analyze.analyze_scene` and
:func:`prtbench.tradeoff.cost.cost_value`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from prtbench.api.errors import InvalidInputError, PrtbenchError, UnknownNameError
from prtbench.api.method import METHODS
from prtbench.api.profiles import get_profile
from prtbench.bench import outputs
from prtbench.bench.cluster import one_line
from prtbench.bench.executors import Executor, make_executor
from prtbench.bench.job import Job
from prtbench.bench.runner import prepare
from prtbench.bench.submit import JobPool, rows_as_dicts, submit
from prtbench.scene.registry import SCENES, get_scene
from prtbench.store.results import default_path
from prtbench.tradeoff.analyze import analyze_scene
from prtbench.tradeoff.cost import cost_value
from prtbench.tradeoff.expressions import COSTS, Constraint, parse_constraints
from prtbench.tradeoff.search import (
    CellResult,
    Evaluation,
    Judge,
    best_per_method,
    brief,
    fmt,
    normalise,
    search,
)
from prtbench.tradeoff.search_space import Candidate, SearchSpace, analysis_json, build_space
from prtbench.transport.lights import get_light


@dataclass
class Advice:
    """The advisor's answer (``to_json`` is the ``--json`` document)."""

    choice: Evaluation
    met: bool
    hint: str
    cost_kind: str
    evaluated: int
    grid_size: int
    runner_up: Evaluation | None
    pruned: list[dict[str, str]]
    analysis: dict[str, Any]
    constraints: list[Constraint]
    history: list[Evaluation] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        """``{"method", "config", "metrics", "frame_ms", "memory_bytes", "precompute_s",
        "cost_kind", "evaluated", "grid_size", "runner_up", "pruned", "analysis"}``."""
        out = _evaluation_json(self.choice)
        out.pop("cost")
        return {**out, "cost_kind": self.cost_kind, "evaluated": self.evaluated,
                "grid_size": self.grid_size,
                "runner_up": _evaluation_json(self.runner_up) if self.runner_up else None,
                "pruned": list(self.pruned), "analysis": self.analysis}


def _evaluation_json(e: Evaluation) -> dict[str, Any]:
    row = e.row or {}
    return {"method": e.candidate.method, "config": dict(row.get("config") or e.candidate.overrides),
            "metrics": dict(row.get("metrics") or {}), "frame_ms": row.get("frame_ms"),
            "memory_bytes": row.get("memory_bytes"), "precompute_s": row.get("precompute_s"),
            "cost": e.cost}


def evaluate_jobs(cells: Sequence[Job], *, profile: str, executor: Executor | None = None,
                  results_path: Path | None = None, store: bool = False) -> list[CellResult]:
    """Measure ``cells`` through the one submit path, one result per cell, in order.

    Parameters
    ----------
    cells : sequence of Job
    profile : str
    executor : Executor, optional
        Where they run (default: serially in this process); ``advise`` screens its candidates
        on Dask workers.
    results_path : Path, optional
        The store the rows go to when ``store``.
    store : bool
        Append the rows to the results store (the verification run does; screening does not).

    Returns
    -------
    list of CellResult
        One per cell; a cell that is refused or fails has its one-line error and no rows
        (one failing cell never aborts the search).
    """
    out: list[CellResult | None] = [None] * len(cells)
    valid = []
    for i, cell in enumerate(cells):
        try:  # a candidate the method refuses is a failed cell, not an error of the search
            prepare(cell, profile=profile, results_path=results_path, store=store)
            valid.append(i)
        except PrtbenchError as exc:
            out[i] = CellResult([], one_line(exc))
    if valid:
        submission = submit([cells[i] for i in valid], profile=profile, executor=executor,
                            results_path=results_path, store=store, progress=False)
        for i, result in zip(valid, submission.per_job):
            out[i] = (CellResult(rows_as_dicts(result.rows)) if result.status == "done"
                      else CellResult([], result.error))
    return out


class _CandidatePool:
    """The search's pool (:func:`prtbench.tradeoff.search.search`) over a :class:`JobPool`:
    candidates in, their cell results out, as they finish."""

    def __init__(self, jobs: JobPool, cell: Callable[[Candidate], Job]):
        self.jobs, self.cell = jobs, cell

    def submit(self, candidate: Candidate, profile: str) -> None:
        self.jobs.submit(self.cell(candidate), profile=profile, token=candidate)

    def next_result(self) -> tuple[Candidate, CellResult]:
        candidate, result = self.jobs.next_finished()
        return candidate, (CellResult(rows_as_dicts(result.rows)) if result.status == "done"
                           else CellResult([], result.error))


def _hint(choice: Evaluation, space: SearchSpace, judge: Judge,
          history: Sequence[Evaluation]) -> str:
    """What would be needed to reach the target, from the knobs at their limit and the analysis."""
    if choice.row is None:
        return f"no configuration could be measured (e.g. {choice.error})"
    missed = [f"{c.name} {fmt(choice.values.get(c.name))} (wanted {c.describe()})"
              for c in choice.failed]
    parts = [f"closest: {choice.candidate.method} {choice.candidate.label()} misses "
             + "; ".join(missed)]
    accurate = [e for e in history if e.row is not None and not e.error
                and e.profile == choice.profile and all(c.kind == "cost" for c in e.failed)]
    if accurate:  # the target is reachable, the budget is what is missed
        e = min(accurate, key=lambda e: (e.shortfall, e.cost))
        over = "; ".join(f"{c.name} {fmt(e.values.get(c.name))} > {c.describe()}" for c in e.failed)
        parts.append(f"the target is met by {e.candidate.method} {e.candidate.label()}, but it "
                     f"breaks the budget ({over}): raise the budget or lower the target")
        return "; ".join(parts)
    method_space = space.space_of(choice.candidate.method)
    values = choice.candidate.overrides
    # Past the SH band limit: spatial detail (texels) or an all-frequency basis.
    instead = ("; use wavelets" if "texture_resolution" in values
               else "; use texture methods or wavelets")
    for knob, why in method_space.shortfalls.items():
        parts.append(f"{why}: needs > {values.get(knob)} {knob.replace('sh_', '')}"
                     + (instead if knob == "sh_bands" else ""))
    for knob in method_space.at_top(choice.candidate):
        high = method_space.highs.get(knob)
        if high is not None and values[knob] >= high:
            parts.append(f"needs {knob} > {values[knob]}, the top of its range"
                         + (instead if knob == "sh_bands" else ""))
        else:
            parts.append(f"{knob} was searched up to {values[knob]}"
                         f"{f' of a range up to {high:g}' if high is not None else ''}"
                         + (" (raise --band-margin)" if knob == "sh_bands" else ""))
    return "; ".join(parts)


def parse_cost_kind(kind: str) -> str:
    if kind not in COSTS:
        raise UnknownNameError("cost kind", kind, COSTS)
    return kind


def advise(scene: str, light: str | None = None, *, target: str | Sequence[Constraint],
           budget: str | Sequence[Constraint] | None = None, cost: str = "frame_ms",
           profile: str = "quick", variant: str = "diffuse", light_changes: str = "none",
           scene_params: Mapping[str, Any] | None = None, analysis: Any = None,
           evaluate: Callable | None = None,
           cost_fn: Callable[[Mapping, str], float] | None = None,
           verify: Callable | None = None, methods: Sequence[str] | None = None,
           results_path: Path | None = None, band_margin: int = 2, keep_fraction: float = 0.5,
           workers: int | None = None, echo: bool = False) -> Advice:
    """Recommend the cheapest configuration of any method that meets ``target`` within ``budget``.

    Parameters
    ----------
    scene, light : str
        Scene name and light name (None: the scene's default light).
    target, budget : str or list of Constraint
        ``"psnr_masked>=28"``; ``"frame_ms<=33,memory<=256MiB"`` (see :mod:`.expressions`).
    cost : str
        What "cheapest" means: ``frame_ms``, ``memory``, ``precompute`` or ``ops``.
    profile : str
        The profile of the answer (searches start at ``smoke`` when it is larger).
    variant, light_changes : str
        Material variant; how the lights will change (passed to the analysis).
    scene_params : mapping, optional
        Scene builder parameters (``--scene-param``; a file scene's ``scale``/``up``/``ground``),
        checked when the scene is built and passed to every evaluated cell.
    analysis : SceneAnalysis-like, optional
        Default: :func:`prtbench.tradeoff.analyze.analyze_scene`.
    evaluate : callable ``(cells, *, profile) -> list``, optional
        Measures cells, one result per cell (a CellResult, a JobResult or rows); default
        :func:`evaluate_jobs` on Dask workers (``workers``), without storing.
    cost_fn : callable ``(row, kind) -> float``, optional
        Default: :func:`prtbench.tradeoff.cost.cost_value`.
    verify : callable ``(cells, *, profile) -> list``, optional
        The final, stored run; default :func:`evaluate_jobs` in this process, stored.
    methods : sequence of str, optional
        Search only these registered methods (default: all).
    results_path : Path, optional
        Results store of the verification rows.
    band_margin : int
        SH bands searched above the analysis' required count.
    keep_fraction : float
        Fraction of methods kept after the ``smoke`` screening (at least two).
    workers : int, optional
        Dask workers the search's candidates run on (default: one per core; 0: serially in
        this process). A search ranked or bounded by ``frame_ms`` always runs serially:
        frame times measured side by side are not the machine's.

    Returns
    -------
    Advice

    Raises
    ------
    PrtbenchError
        Bad scene, scene parameter, light, variant, profile, expressions, cost kind or results
        store (all checked before any work).
    """

    # Everything a user can get wrong, before any work.
    get_profile(profile)
    constraints = (parse_constraints(target, option="--target", kinds=("metric",))
                   if isinstance(target, str) else list(target))
    constraints += (parse_constraints(budget, option="--budget", kinds=("cost",))
                    if isinstance(budget, str) and budget.strip() else list(budget or []))
    cost = parse_cost_kind(cost)
    if not 0 < keep_fraction <= 1:
        raise InvalidInputError(f"keep_fraction {keep_fraction}; accepted: (0, 1]")
    if band_margin < 0:
        raise InvalidInputError(f"--band-margin {band_margin}; accepted: 0 or more")
    SCENES.check(scene)
    for name in methods or ():
        METHODS.check(name)
    scene_params = dict(scene_params or {})
    scene_obj = get_scene(scene, variant=variant, **scene_params)
    light_obj = get_light(light or scene_obj.default_light)
    cost_fn = cost_fn or cost_value
    if verify is None:
        outputs.check_results_store("--results", results_path or default_path())
        outputs.check_cache()
    # The search runs its candidates on Dask workers (one per core), each method's chain as
    # soon as a worker is free; the verification run runs alone in this process, so its
    # stored frame times are taken on a quiet machine. Frame times measured side by side are
    # distorted, so a search that ranks by them runs serially.
    timed = cost == "frame_ms" or any(c.name == "frame_ms" for c in constraints)
    screening = None if evaluate is not None else make_executor(
        workers=0 if timed else workers)
    verify = verify or (lambda cells, *, profile: evaluate_jobs(
        cells, profile=profile, results_path=results_path, store=True))

    try:
        if analysis is None:
            analysis = analyze_scene(scene_obj, light_obj, light_changes=light_changes)
        space = build_space(scene_obj, analysis, profile=profile, methods=methods,
                            band_margin=band_margin)
        if not space.methods:
            raise PrtbenchError("no method can model this scene within the analysis' requirements: "
                                + "; ".join(f"{p['method']}: {p['why']}" for p in space.pruned))

        def cell(c: Candidate) -> Job:
            return Job(method=c.method, scene=scene, label={"advise": c.label()}, variant=variant,
                        light=light, overrides=c.overrides, scene_params=scene_params)

        pool = _CandidatePool(JobPool(screening), cell) if screening is not None else None

        def run_batch(batch: Sequence[Candidate], at: str) -> list[CellResult]:  # injected
            results = list(evaluate([cell(c) for c in batch], profile=at))
            if len(results) != len(batch):
                raise PrtbenchError(f"evaluate returned {len(results)} results for {len(batch)} cells")
            return [normalise(r) for r in results]

        judge = Judge(constraints, cost, cost_fn)
        names = [m.method for m in space.methods]
        history, notes, pruned = [], [], list(space.pruned)
        starts: dict[str, Candidate] = {}
        if profile != "smoke" and len(names) > 2:  # successive halving over fidelity
            screen = search(space, names, profile="smoke", judge=judge, echo=echo,
                            **({"pool": pool} if pool else {"run_batch": run_batch}))
            history += screen
            best = best_per_method(screen)
            ranked = sorted(best.values(), key=Evaluation.key)
            keep = max(min(2, len(ranked)), math.ceil(keep_fraction * len(names)))
            kept = [e for e in ranked[:keep] if e.row is not None] or ranked[:1]
            for rank, e in enumerate(ranked[len(kept):], start=len(kept) + 1):
                pruned.append({"method": e.candidate.method, "why": (
                    f"screened out at the smoke profile (rank {rank} of {len(ranked)}): "
                    + (brief(e, judge) if e.row is not None else f"failed ({e.error})"))})
            names = [e.candidate.method for e in kept]
            starts = {e.candidate.method: e.candidate for e in kept}
            notes.append(f"smoke screening: {len(screen)} cells over {len(best)} methods; kept "
                         f"{', '.join(names)}")
        final = search(space, names, profile=profile, judge=judge,
                       **({"pool": pool} if pool else {"run_batch": run_batch}),
                       starts=starts, echo=echo)
        history += final
    finally:
        if screening is not None:
            screening.close()
    ranked = sorted(final, key=Evaluation.key)
    if not ranked or ranked[0].row is None:
        raise PrtbenchError("no candidate could be measured: "
                            + "; ".join(f"{e.candidate.method} {e.candidate.label()}: {e.error}"
                                        for e in final[:5]))

    def runner_up_of(choice: Evaluation) -> Evaluation | None:
        # The next feasible one, of another method where possible; else the next closest.
        others = [e for e in ranked if e.candidate != choice.candidate and e.row is not None]
        feasible = [e for e in others if e.feasible]
        other_methods = [e for e in feasible if e.candidate.method != choice.candidate.method]
        return (other_methods or feasible or others or [None])[0]

    # Verify: the answer's numbers are those of a real, stored run in the requested profile.
    verified = None
    tried = [ranked[0]] + ([r] if (r := runner_up_of(ranked[0])) is not None and r.feasible else [])
    for pick in tried:
        result = normalise(list(verify([cell(pick.candidate)], profile=profile))[0])
        verified = judge(pick.candidate, profile, result)
        if verified.feasible or not pick.feasible:
            break
        notes.append(f"verification of {pick.candidate.method} {pick.candidate.label()} missed "
                     f"({brief(verified, judge)}); trying the runner-up")
    if verified.row is None:
        raise PrtbenchError(f"the verification run of {verified.candidate.method} "
                            f"{verified.candidate.label()} failed: {verified.error}")
    met = verified.feasible
    hint = "" if met else _hint(verified, space, judge, final)
    return Advice(choice=verified, met=met, hint=hint, cost_kind=cost, evaluated=len(history),
                  grid_size=space.size, runner_up=runner_up_of(verified),
                  pruned=pruned, analysis=analysis_json(analysis), constraints=constraints,
                  history=history, notes=notes)


def format_advice(advice: Advice, *, top: int = 8) -> str:
    """The terminal report: analysis, pruning, search, the best candidates and the answer."""
    judge_names = list(dict.fromkeys(c.name for c in advice.constraints))
    lines = ["analysis: " + " ".join(f"{k}={v}" for k, v in advice.analysis.items()
                                     if not isinstance(v, (dict, list)))]
    if advice.pruned:
        width = max(len(p["method"]) for p in advice.pruned)
        lines.append("pruned:")
        lines += [f"  {p['method']:<{width}}  {p['why']}" for p in advice.pruned]
    lines.append(f"search: {advice.evaluated} cells evaluated for a grid of {advice.grid_size} "
                 f"(+1 verification run)")
    lines += [f"  {n}" for n in advice.notes]
    final = [e for e in advice.history if e.profile == advice.choice.profile and e.row]
    shown = judge_names + ([] if advice.cost_kind in judge_names else [advice.cost_kind])
    header = ["method", "config", *shown, "meets"]
    rows = []
    for e in sorted(final, key=Evaluation.key)[:top]:
        values = [e.values.get(name) for name in judge_names]
        values += [] if advice.cost_kind in judge_names else [e.cost]
        rows.append([e.candidate.method, e.candidate.label(), *map(fmt, values),
                     "yes" if e.feasible else "no"])
    widths = [max(len(str(r[i])) for r in [header, *rows]) for i in range(len(header))]
    lines.append(f"best candidates at the {advice.choice.profile} profile:")
    lines += ["  " + "  ".join(str(v).ljust(w) for v, w in zip(r, widths)).rstrip()
              for r in [header, *rows]]
    c = advice.to_json()
    mem = c["memory_bytes"]
    lines.append(f"{'choice' if advice.met else 'closest (target not reached)'} (verified, stored): "
                 f"{c['method']} {advice.choice.candidate.label()}: "
                 + ", ".join(f"{k} {fmt(c['metrics'].get(k))}" for k in judge_names
                             if k in c["metrics"])
                 + f"; frame {fmt(c['frame_ms'])} ms, memory "
                 f"{fmt(mem / 2 ** 20 if mem is not None else None)} MiB, precompute "
                 f"{fmt(c['precompute_s'])} s, {advice.cost_kind} {fmt(advice.choice.cost)}")
    if advice.runner_up is not None:
        lines.append(f"runner-up: {advice.runner_up.candidate.method} "
                     f"{advice.runner_up.candidate.label()} ({advice.cost_kind} "
                     f"{fmt(advice.runner_up.cost)})")
    if not advice.met:
        lines.append(f"needed: {advice.hint}")
    return "\n".join(lines)
