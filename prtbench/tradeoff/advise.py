"""``prtbench advise``: the cheapest configuration that meets a target, verified by a real run.

1. **Prune** (:mod:`.search_space`): from the scene analysis, drop the methods that cannot
   model what the scene requires and the knob steps that model more than it needs; every
   pruned method is reported with its reason. The analysis never drops a cheaper step: it
   only says where each method's search starts.
2. **Search adaptively** (:mod:`.search`), never the whole grid: a monotone lattice search
   per method (a measurement that clearly misses an accuracy bound rules out everything
   below it, one that meets all or already costs as much as the best found rules out
   everything above it), about O(log n) runs per knob. It ends only when measurements decide
   every candidate: each one left unmeasured either clearly misses the target or costs at
   least as much as the best one meeting it. The analysis orders (each method starts where it
   points), it never ends a search. Over fidelity this is **successive halving**: when the
   requested profile is larger than ``smoke`` and more than two methods remain, all are
   first searched at ``smoke``, and the better ``keep_fraction`` of them (at least two) go on
   to the requested profile, ranked by the smoke cost of their cheapest candidate that meets
   the target or misses it only narrowly (a cheap near miss is not dropped for a dear hit),
   then the rest by shortfall. There each search starts from that candidate and goes
   wherever the measurements leave something undecided.
3. **Verify**: the winner is run again in the requested profile with its rows stored in the
   results store, and the answer reports that run's numbers; the advisor never answers from
   a model or a screening run alone. If the verified run misses, the runner-up is verified.

A target nothing reaches is not an error: :class:`Advice` holds the closest configuration
(least relative shortfall) and ``hint`` says what would be needed, from the knobs that sat at
the limit of their range and the analysis; the CLI exits 1.

Each step (scene, analysis, pruning, screening, search, verification) is timed; with
``echo`` it says what it does and how long it took on stderr, and :attr:`Advice.steps`
keeps the times.

``analysis``, ``evaluate`` and ``cost_fn`` are injected (tests pass synthetic ones); the
defaults are :func:`prtbench.tradeoff.analyze.analyze_scene` and
:func:`prtbench.tradeoff.cost.cost_value`.
"""

from __future__ import annotations

import dataclasses
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
    brief,
    clear_miss,
    fmt,
    normalise,
    search,
)
from prtbench.tradeoff.search_space import (
    Candidate,
    SearchSpace,
    analysis_json,
    build_space,
)
from prtbench.tradeoff.steps import Step, StepClock
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
    steps: list[Step] = field(default_factory=list)
    total_s: float = 0.0

    def to_json(self) -> dict[str, Any]:
        """``{"method", "config", "metrics", "frame_ms", "memory_bytes", "precompute_s",
        "cost_kind", "evaluated", "grid_size", "runner_up", "pruned", "analysis", "steps",
        "total_s"}``; ``steps`` is one ``{"step", "seconds", "cells", "profile", "detail"}``
        per step, in order."""
        out = _evaluation_json(self.choice)
        out.pop("cost")
        return {**out, "cost_kind": self.cost_kind, "evaluated": self.evaluated,
                "grid_size": self.grid_size,
                "runner_up": _evaluation_json(self.runner_up) if self.runner_up else None,
                "pruned": list(self.pruned), "analysis": self.analysis,
                "steps": [s.to_json() for s in self.steps], "total_s": round(self.total_s, 3)}


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
           workers: int | None = None, reference_bounces: int = 1,
           echo: bool = False) -> Advice:
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
    reference_bounces : int
        Bounces of the one path reference every candidate is scored against
        (docs/PROTOCOL.md: one reference per comparison; default 1, as the sweeps).
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
    if verify is None:
        outputs.check_results_store("--results", results_path or default_path())
        outputs.check_cache()
    scene_params = dict(scene_params or {})
    cost_fn = cost_fn or cost_value
    clock = StepClock(echo=echo)
    # The scene's and the light's errors are the user's input: said as one line, no progress.
    with clock.step("scene", f"loading {scene} and its light", announce=False) as step:
        scene_obj = get_scene(scene, variant=variant, **scene_params)
        light_obj = get_light(light or scene_obj.default_light)
        step.detail = f"{_scene_size(scene_obj)}, light {light_obj.name}"
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
        with clock.step("analysis", f"what {scene} under {light_obj.name} requires") as step:
            if analysis is None:
                analysis = analyze_scene(scene_obj, light_obj, light_changes=light_changes,
                                         progress=echo)
            else:
                step.detail = "given by the caller; "
            step.detail += _analysis_text(analysis)
        with clock.step("pruning", "methods and knob ladders from the analysis") as step:
            space = build_space(scene_obj, analysis, profile=profile, methods=methods,
                                band_margin=band_margin)
            step.detail = (f"{space.size} candidates over {len(space.methods)} methods, "
                           f"{len(space.pruned)} methods pruned")
        if not space.methods:
            raise PrtbenchError("no method can model this scene within the analysis' requirements: "
                                + "; ".join(f"{p['method']}: {p['why']}" for p in space.pruned))

        def cell(c: Candidate) -> Job:
            return Job(method=c.method, scene=scene, label={"advise": c.label()}, variant=variant,
                        light=light, overrides=c.overrides, scene_params=scene_params,
                        reference_bounces=reference_bounces)

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
        runs = {"pool": pool} if pool else {"run_batch": run_batch}
        if profile != "smoke" and len(names) > 2:  # successive halving over fidelity
            with clock.step("screening", f"{len(names)} methods at the smoke profile",
                            profile="smoke") as step:
                screen = search(space, names, profile="smoke", judge=judge, echo=echo, **runs)
                history += screen
                best = _screening_best(screen)
                ranked = sorted(best.values(), key=lambda e: _screening_key(e))
                keep = max(min(2, len(ranked)), math.ceil(keep_fraction * len(names)))
                kept = [e for e in ranked[:keep] if e.row is not None] or ranked[:1]
                for rank, e in enumerate(ranked[len(kept):], start=len(kept) + 1):
                    pruned.append({"method": e.candidate.method, "why": (
                        f"screened out at the smoke profile (rank {rank} of {len(ranked)}): "
                        + (brief(e, judge) if e.row is not None else f"failed ({e.error})"))})
                names = [e.candidate.method for e in kept]
                starts = {e.candidate.method: e.candidate for e in kept}
                step.cells, step.detail = len(screen), f"kept {', '.join(names)}"
            notes.append(f"smoke screening: {len(screen)} cells over {len(best)} methods; kept "
                         f"{', '.join(names)}")
        # The screening optimum only orders the final search (it is measured first); the
        # search may go anywhere in the method's space and stops only where measurements
        # decide every candidate left (search._decided): each one unmeasured either clearly
        # misses an accuracy bound or costs at least as much as the best meeting the target.
        final_space = SearchSpace([dataclasses.replace(m, start=starts.get(m.method, m.start))
                                   for m in space.methods], space.pruned)
        with clock.step("search", f"{len(names)} methods at the {profile} profile",
                        profile=profile) as step:
            final = search(final_space, names, profile=profile, judge=judge, **runs, echo=echo)
            history += final
            step.cells = len(final)
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
    with clock.step("verification", f"{ranked[0].candidate.method} "
                    f"{ranked[0].candidate.label()}, stored", profile=profile) as step:
        for pick in tried:
            result = normalise(list(verify([cell(pick.candidate)], profile=profile))[0])
            verified = judge(pick.candidate, profile, result)
            step.cells += 1
            if verified.feasible or not pick.feasible:
                break
            notes.append(f"verification of {pick.candidate.method} {pick.candidate.label()} "
                         f"missed ({brief(verified, judge)}); trying the runner-up")
        step.detail = f"{verified.candidate.method} {verified.candidate.label()}: " + brief(
            verified, judge)
    if verified.row is None:
        raise PrtbenchError(f"the verification run of {verified.candidate.method} "
                            f"{verified.candidate.label()} failed: {verified.error}")
    clock.say(f"total: {clock.total:.1f} s")
    met = verified.feasible
    hint = "" if met else _hint(verified, space, judge, final)
    return Advice(choice=verified, met=met, hint=hint, cost_kind=cost, evaluated=len(history),
                  grid_size=space.size, runner_up=runner_up_of(verified),
                  pruned=pruned, analysis=analysis_json(analysis), constraints=constraints,
                  history=history, notes=notes, steps=clock.steps, total_s=clock.total)


def _scene_size(scene: Any) -> str:
    """``12,345 triangles`` (what a user's file costs the steps after it), or ''."""
    triangles = getattr(scene, "n_triangles", None)
    return f"{int(triangles):,} triangles" if isinstance(triangles, (int, float)) else "built"


def _hopeful(e: Evaluation) -> bool:
    """Whether a screening measurement leaves its candidate a chance at the final profile: it
    meets everything, or misses only accuracy bounds and each of them narrowly
    (:func:`~prtbench.tradeoff.search.clear_miss`: the screening profile measures a little
    lower than the answer's)."""
    return (e.row is not None and not e.error
            and all(k.grows_with_model is True and not clear_miss(e, k) for k in e.failed))


def _screening_best(screen: Sequence[Evaluation]) -> dict[str, Evaluation]:
    """Per method, its screening representative: the cheapest hopeful candidate
    (:func:`_hopeful`), else the closest to the target."""
    best: dict[str, Evaluation] = {}
    for e in screen:
        m = e.candidate.method
        if m not in best or _screening_key(e) < _screening_key(best[m]):
            best[m] = e
    return best


def _screening_key(e: Evaluation) -> tuple:
    """Methods are kept by what they could cost at the final profile: hopeful ones by the
    cost of their cheapest hopeful candidate (one that narrowly misses for less is not
    dropped for one that meets at many times the cost), then the rest by shortfall."""
    if _hopeful(e):
        return (0, e.cost, 0 if e.feasible else 1, e.shortfall)
    return (1, e.shortfall, e.cost)


def _analysis_text(analysis: Any) -> str:
    """``required_bands 5, shadows yes, bounces no, ...``: the decisions pruning reads."""
    fields = (("required_bands", "required_bands"), ("glossy", "needs_glossy"),
              ("shadows", "needs_shadows"), ("textures", "needs_textures"),
              ("bounces", "needs_bounces"), ("fixed light", "fixed_light_ok"))
    values = {name: getattr(analysis, attr, None) for name, attr in fields}
    return ", ".join(f"{name} {'yes' if v is True else 'no' if v is False else v}"
                     for name, v in values.items() if v is not None)
