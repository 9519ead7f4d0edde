"""The engine verdict: does a PRT method beat what engines ship, at the same bytes and work?

``prtbench verdict --scene S --light L`` answers an engine programmer's question from the results
store, under the protocol (docs/PROTOCOL.md):

1. **Measure what the store lacks.** The verdict grid (each method's ``verdict_grid``: SH PRT
   per vertex and per texel, wavelet PRT, the Greger irradiance volume, the engine probe volume
   relit and baked, AO with bent normals per vertex and per texel, a directional lightmap) runs
   on the scene and light through the one submit path; cells already stored for this code version
   are skipped (:func:`prtbench.tradeoff.sweep.run_cells`), so a second verdict only reads.
   Texel counts follow the scene (:func:`auto_texture_resolutions`).
2. **Best per family within each budget.** For resident memory of 1, 8 and 64 MiB
   (:data:`MEMORY_BUDGETS`), each method family's best configuration (``Method.family``: its
   best method's best configuration whose cost is within the budget, :func:`best_within`),
   with its masked PSNR and FLIP and their 95 % intervals, cost and light class. A fourth
   budget is *equal work*: operations per frame no more than the engine baseline chosen at
   the middle memory budget spends.
3. **One line per scene and panel**: at the middle budget, the best PRT family against the best
   engine baseline, the paired difference with its interval (over the views both were
   measured on, plus the reference noise: :func:`prtbench.tradeoff.dominance.paired_difference`),
   and the same for relightable configurations only -- under a changing sky, a baked light
   does not count.

Reports: ``verdict-<scene>-<light>.{md,csv}`` (or ``--name``: ``make table-engine`` writes
``table-engine.{md,csv}`` for four scenes), atomically, once everything is computed. Every
number in them is a stored row's value or a mean of them.
"""

from __future__ import annotations

import math
import re
import sys
from collections import defaultdict
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from prtbench.api.cache import atomic_path
from prtbench.api.errors import InvalidInputError, PrtbenchError
from prtbench.api.method import METHODS
from prtbench.api.profiles import get_profile
from prtbench.bench import outputs
from prtbench.scene.files import is_scene_path
from prtbench.scene.registry import SCENES, get_scene
from prtbench.store.results import default_path
from prtbench.tradeoff import grid as grid_mod
from prtbench.tradeoff.budget import (
    Budget,
    BudgetRow,
    best_within,
    mark_rows,
)
from prtbench.tradeoff.dominance import paired_difference
from prtbench.tradeoff.front import Point, knobs_text
from prtbench.tradeoff.pareto import light_points, open_selection
from prtbench.tradeoff.sweep import run_cells
from prtbench.tradeoff.verdict_report import csv_text, markdown_text

MIB = 1 << 20
#: The resident-memory budgets (bytes) of every verdict.
MEMORY_BUDGETS = (1 * MIB, 8 * MIB, 64 * MIB)
#: The budget the one-line conclusion is drawn at (index into :data:`MEMORY_BUDGETS`).
CONCLUSION_BUDGET = 1
#: Texels per triangle an atlas needs at the quick profile's padding (plants packs at 256² with
#: 3.9 per triangle); the smallest power of two at or above it, never below 256.
TEXELS_PER_TRIANGLE = 3.5
MIN_TEXTURE_RESOLUTION = 256
ERROR, SECOND_ERROR = "psnr_masked", "flip_masked"


def auto_texture_resolutions(triangles: int, *, count: int = 1) -> list[int]:
    """The atlas resolutions a verdict measures for a scene of ``triangles``: the smallest power
    of two with :data:`TEXELS_PER_TRIANGLE` texels per triangle (at least
    :data:`MIN_TEXTURE_RESOLUTION`), then ``count - 1`` doublings."""
    need = math.sqrt(max(triangles, 1) * TEXELS_PER_TRIANGLE)
    first = max(MIN_TEXTURE_RESOLUTION, 1 << max(0, math.ceil(math.log2(need))))
    return [first << i for i in range(count)]


def _values(declared: Any, *, triangles: int, light: str) -> list:
    """A ``verdict_grid`` entry's values: ``auto``/``auto2`` texture resolutions for the scene,
    ``@light`` the verdict's light, else the list as declared."""
    if declared in ("auto", "auto2"):
        return auto_texture_resolutions(triangles, count=2 if declared == "auto2" else 1)
    if declared == "@light":
        return [light]
    return list(declared)


def verdict_spec(*, scene: str, light: str, triangles: int, profile: str,
                 scene_params: Mapping[str, Any] | None = None, views: int | None = None,
                 methods: Sequence[str] | None = None) -> dict[str, Any]:
    """The sweep spec (:func:`prtbench.tradeoff.grid.expand`'s schema) of one scene's verdict:
    every method's ``verdict_grid`` (:attr:`prtbench.api.method.Method.verdict_grid`) with its
    ``auto`` resolutions resolved, one path reference of one bounce for every method (one
    panel)."""
    tables = []
    for name in METHODS.names():
        declared = METHODS.get(name).verdict_grid
        if declared is None or (methods is not None and name not in methods):
            continue
        grid = {k: _values(v, triangles=triangles, light=light) for k, v in declared.items()}
        tables.append({"name": name, **({"grid": grid} if grid else {})})
    spec: dict[str, Any] = {"profile": profile, "scene": scene, "light": light,
                            "variant": "diffuse", "reference_bounces": 1, "method": tables}
    if scene_params:
        spec["scene_params"] = dict(scene_params)
    if views is not None:
        spec["views"] = views
    return spec


@dataclass
class FamilyRow:
    """One family's best configuration within one budget (``point`` None: none fits)."""

    family: str
    engine: bool
    row: BudgetRow
    flip: Point | None = None

    @property
    def point(self) -> Point | None:
        return self.row.point


@dataclass
class BudgetBlock:
    """The families within one budget, in one panel."""

    budget: Budget
    rows: list[FamilyRow]
    note: str = ""


@dataclass
class PanelVerdict:
    """One scene, light and panel: the blocks and the conclusion."""

    scene: str
    light: str
    panel: str
    blocks: list[BudgetBlock]
    conclusion: str
    relight_conclusion: str


@dataclass
class VerdictResult:
    """What :func:`verdict` computed and wrote."""

    scenes: list[str]
    profile: str
    panels: list[PanelVerdict]
    skipped: list[str]
    measured: list[str] = field(default_factory=list)
    paths: list[Path] = field(default_factory=list)


def family_of(method: str) -> tuple[str, bool]:
    """``(family, engine_baseline)`` of a registered method (its own name where it is gone)."""
    try:
        cls = METHODS.get(method)
    except PrtbenchError:
        return method, False
    return cls.family or method, bool(cls.engine_baseline)


def _key(p: Point) -> tuple[str, str, str]:
    return p.method, p.config_json, p.panel


def family_rows(points: Sequence[Point], *, budget: Budget,
                flips: Mapping[tuple, Point]) -> list[FamilyRow]:
    """Per family, its best method's row within ``budget`` (:func:`budget.best_within` per
    method, then the family's best by PSNR, ties to the cheaper), marked beyond the intervals
    among families like :func:`prtbench.tradeoff.budget.mark_rows`."""
    by_family: dict[str, list[BudgetRow]] = defaultdict(list)
    for r in best_within(points, budget=budget, error=ERROR):
        by_family[family_of(r.method)[0]].append(r)
    out = []
    for family, rows in by_family.items():
        within = [r for r in rows if r.within]
        if within:
            best = max(within, key=lambda r: (r.point.error, -r.point.cost, r.method))
        else:  # none fits: the cheapest the family has
            priced = [r for r in rows if r.cheapest is not None]
            best = (min(priced, key=lambda r: r.cheapest.cost) if priced else rows[0])
        out.append(FamilyRow(family=family, engine=family_of(best.method)[1], row=best,
                             flip=flips.get(_key(best.point)) if best.point else None))
    out.sort(key=lambda f: (0, -f.point.error, f.point.cost) if f.point
             else (1, f.row.cheapest.cost if f.row.cheapest else math.inf, 0.0))
    mark_rows([f.row for f in out], error=ERROR)
    return out


def difference_text(a: Point, b: Point) -> tuple[str, float, float]:
    """``beats`` / ``is beaten by`` / ``ties with``: ``a`` against ``b`` beyond the paired
    interval (:func:`~prtbench.tradeoff.dominance.paired_difference`, whose half-width is taken
    in the direction of the difference, so this is
    :func:`~prtbench.tradeoff.dominance.better_beyond` either way round), with the mean
    difference and that half-width."""
    mean, half = paired_difference(a, b, higher_is_better=True)
    word = ("beats" if mean - half > 0.0 else "is beaten by" if mean + half < 0.0
            else "ties with")
    return word, mean, half


def _candidates(rows: Sequence[FamilyRow], *, engine: bool, relight_only: bool
                ) -> list[FamilyRow]:
    """The rows with a configuration within budget of PRT (``engine`` False) or of the engine
    baselines, relightable ones only with ``relight_only``."""
    return [f for f in rows if f.point is not None and f.engine == engine
            and (not relight_only or f.point.light_class == "relight")]


def _best(rows: Sequence[FamilyRow], *, engine: bool, relight_only: bool) -> FamilyRow | None:
    return max(_candidates(rows, engine=engine, relight_only=relight_only),
               key=lambda f: (f.point.error, -f.point.cost), default=None)


def _opponent(prt: FamilyRow, engines: Sequence[FamilyRow]) -> tuple[FamilyRow, str, float, float]:
    """The engine baseline the conclusion names, with the paired comparison against it: one
    that beats the PRT row beyond the intervals (the clearest), else, when the PRT row beats
    every one, the closest of them, else the best by mean of those it ties with."""
    compared = [(e, *difference_text(prt.point, e.point)) for e in engines]
    beaten = [c for c in compared if c[1] == "is beaten by"]
    if beaten:  # the largest margin beyond the interval
        return max(beaten, key=lambda c: -c[2] - c[3])
    ties = [c for c in compared if c[1] == "ties with"]
    return max(ties or compared, key=lambda c: c[0].point.error)


def conclusion(rows: Sequence[FamilyRow], *, budget: Budget, scene: str,
               relight_only: bool) -> str:
    """The one-line verdict of one budget block: the best PRT family against the engine
    baselines, paired beyond the intervals (:func:`_opponent`)."""
    what = "relightable " if relight_only else ""
    prt = _best(rows, engine=False, relight_only=relight_only)
    engines = _candidates(rows, engine=True, relight_only=relight_only)
    at = f"at {budget.text}"
    if prt is None and not engines:
        return f"{at}, no {what}configuration fits on {scene}"
    if prt is None:
        best = max(engines, key=lambda f: f.point.error)
        return (f"{at}, no {what}PRT configuration fits on {scene}; the best {what}engine "
                f"baseline is {best.point.method} ({best.point.error:.2f} dB)")
    if not engines:
        return (f"{at}, no {what}engine baseline fits on {scene}; the best {what}PRT "
                f"method is {prt.point.method} ({prt.point.error:.2f} dB)")
    engine, word, mean, half = _opponent(prt, engines)
    whom = {"beats": f"every {what}engine baseline; the closest,",
            "ties with": f"the {what}engine baseline",
            "is beaten by": f"the {what}engine baseline"}[word]
    who = (f"{at}, {prt.point.method} ({prt.family}, {prt.point.light_class}) {word} {whom} "
           f"{engine.point.method} ({engine.family}, {engine.point.light_class})")
    if word == "ties with":
        return (f"{who} on {scene}: masked PSNR difference {mean:+.2f} ± {half:.2f} dB, within "
                "the intervals")
    return f"{who}, by {abs(mean):.2f} ± {half:.2f} dB masked PSNR on {scene}"


def _ops_budget(blocks: Sequence[BudgetBlock], ops_points: Mapping[tuple, Point]
                ) -> tuple[Budget | None, str]:
    """Equal work: the ops per frame of the engine baseline chosen at the conclusion budget."""
    engine = _best(blocks[CONCLUSION_BUDGET].rows, engine=True, relight_only=False)
    if engine is None:
        return None, "no engine baseline within the middle memory budget to set the work"
    ops = ops_points.get(_key(engine.point))
    if ops is None or not math.isfinite(ops.cost):
        return None, f"{engine.point.method} has no ops count to set the work"
    return (Budget(kind="ops", value=ops.cost, text=f"{ops.cost:.3g} ops"),
            f"equal work: at most the {ops.cost:.3g} operations per frame of "
            f"{engine.point.method} ({knobs_text(engine.point)}), the engine baseline chosen at "
            f"{blocks[CONCLUSION_BUDGET].budget.text}")


def panel_verdicts(selection, light: str, *, scene_label: str) -> tuple[list[PanelVerdict], list[str]]:
    """The verdict of one light: per panel, the budget blocks and the conclusions."""
    memory, skipped = light_points(selection, light, error=ERROR, cost="memory")
    ops_all, _ = light_points(selection, light, error=ERROR, cost="ops")
    flip_all, _ = light_points(selection, light, error=SECOND_ERROR, cost="memory")
    ops_points = {_key(p): p for p in ops_all}
    flips = {_key(p): p for p in flip_all}
    out = []
    for panel in sorted({p.panel for p in memory}):
        mine = [p for p in memory if p.panel == panel]
        blocks = [BudgetBlock(budget=b, rows=family_rows(mine, budget=b, flips=flips))
                  for b in (Budget(kind="memory", value=float(v), text=f"{v // MIB} MiB")
                            for v in MEMORY_BUDGETS)]
        ops_budget, note = _ops_budget(blocks, ops_points)
        if ops_budget is not None:
            mine_ops = [p for p in ops_all if p.panel == panel]
            blocks.append(BudgetBlock(budget=ops_budget, note=note,
                                      rows=family_rows(mine_ops, budget=ops_budget, flips=flips)))
        else:
            skipped.append(f"{scene_label}/{light} {panel}: no equal-work budget ({note})")
        middle = blocks[CONCLUSION_BUDGET]
        # Under a changing sky each family stands by its best relightable configuration, which
        # need not be its best overall (a baked probe volume beside the relit one).
        relit = family_rows([p for p in mine if p.light_class == "relight"],
                            budget=middle.budget, flips=flips)
        out.append(PanelVerdict(
            scene=scene_label, light=light, panel=panel, blocks=blocks,
            conclusion=conclusion(middle.rows, budget=middle.budget, scene=scene_label,
                                  relight_only=False),
            relight_conclusion=conclusion(relit, budget=middle.budget, scene=scene_label,
                                          relight_only=True)))
    return out, skipped


_SAFE = re.compile(r"[^A-Za-z0-9._-]+")


def report_stem(scenes: Sequence[str], light: str | None) -> str:
    """``verdict-<scene>[-<scene>…]-<light>`` (filename-safe; ``default`` for each scene's own
    light)."""
    names = [_SAFE.sub("_", Path(s).stem if is_scene_path(s) else s) for s in scenes]
    return f"verdict-{'-'.join(names)}-{_SAFE.sub('_', light or 'default')}"


# -- the command --------------------------------------------------------------------------------

def verdict(*, scenes: Sequence[str], light: str | None = None, profile: str = "quick",
            results_path: str | Path | None = None, reports_dir: str | Path = "reports",
            name: str | None = None, scene_params: Mapping[str, Any] | None = None,
            measure: bool = True, workers: int | None = None, views: int | None = None,
            methods: Sequence[str] | None = None, command: str = "prtbench verdict",
            progress: bool = True,
            echo: Callable[[str], None] | None = None) -> VerdictResult:
    """Measure what the store lacks (unless ``measure`` is False), then the verdict's reports.

    Parameters
    ----------
    scenes : sequence of str
        Built-in scene names or asset files (``path.glb``, imported with ``scene_params``).
    light : str, optional
        One light for every scene (default: each scene's default light).
    profile : str
    results_path : str or Path, optional
        The results store (default results/prtbench.sqlite); measured rows are appended to it.
    reports_dir : str or Path
    name : str, optional
        The reports' stem (default :func:`report_stem`).
    measure : bool
        Run the verdict grid's missing cells first (False: read the store only).
    workers : int, optional
        Dask workers of the measurement (default one per core; 0: serial).
    views : int, optional
        Views per configuration (default: the profile's).
    methods : sequence of str, optional
        Only these methods' verdict cells are measured (default: every method with a
        ``verdict_grid``); the store's other rows still count.

    Raises
    ------
    PrtbenchError
        One line, before any work, for a bad scene, light, profile, name or output location;
        a failed measurement cell is reported and left out, never fatal.
    """
    echo = echo or (lambda text: print(text, file=sys.stderr, flush=True))
    get_profile(profile)
    for method in methods or ():
        if METHODS.get(method).verdict_grid is None:
            raise InvalidInputError(f"--method '{method}' has no verdict configurations; "
                                    "accepted: " + ", ".join(
                                        n for n in METHODS.names()
                                        if METHODS.get(n).verdict_grid is not None))
    if not scenes:
        raise InvalidInputError("verdict: no --scene; accepted: one or more scene names or "
                                "asset files (prtbench list scenes)")
    if name is not None and not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9._-]*", name):
        raise InvalidInputError(f"--name '{name}': accepted: letters, digits, '.', '_' and '-', "
                                "starting with a letter or digit")
    reports = Path(reports_dir)
    outputs.check_folder("--reports", reports)
    path = Path(results_path) if results_path is not None else default_path()
    built = {}
    for scene in scenes:  # every scene and the light checked before any work
        SCENES.check(scene)
        built[scene] = get_scene(scene, **dict(scene_params or {}))
    sweeps = []
    for scene in scenes:
        spec = verdict_spec(scene=scene, light=light or built[scene].default_light,
                            triangles=built[scene].n_triangles,
                            profile=profile, scene_params=scene_params, views=views,
                            methods=methods)
        sweeps.append(grid_mod.expand(spec, source="command line", profile=profile))
    labels = {s: Path(s).name if is_scene_path(s) else s for s in scenes}  # no machine path
    result = VerdictResult(scenes=[labels[s] for s in scenes], profile=profile, panels=[],
                           skipped=[])
    if measure:
        cells = [c for s in sweeps for c in s.cells]
        echo(f"verdict: {len(cells)} cells on {', '.join(scenes)} ({profile}); cells already "
             f"stored for this code version are skipped")
        outcome = run_cells(cells, profile=profile, results_path=path, workers=workers,
                            progress=progress)
        result.measured = [f"{outcome.count('done')} measured, {outcome.count('skipped')} "
                           f"already stored, {outcome.count('failed')} failed"]
        for item in outcome.failed:
            result.skipped.append(f"cell failed: {item.job.describe()}: {item.error}")
        for s in sweeps:
            for cell, reason in s.dropped:
                result.skipped.append(f"left out {cell.method} {cell.scene}: {reason}")
    for scene in scenes:
        selection = open_selection(scene=scene, light=light, error=ERROR, cost="memory",
                                   profile=profile, results_path=path, reports_dir=reports,
                                   scene_params=scene_params)
        label = labels[scene]
        for stored_light in selection.rows_by_light:
            if light is None and stored_light != built[scene].default_light:
                continue
            panels, skipped = panel_verdicts(selection, stored_light, scene_label=label)
            result.panels += panels
            result.skipped += skipped
    if not result.panels:
        raise PrtbenchError(f"verdict: no stored rows under the scenes' lights in '{path}'; "
                            "run without --no-measure to measure them")
    stem = name or report_stem(scenes, light)
    md, csv_path = reports / f"{stem}.md", reports / f"{stem}.csv"
    with atomic_path(csv_path) as tmp:
        tmp.write_text(csv_text(result))
    with atomic_path(md) as tmp:
        tmp.write_text(markdown_text(result, results_path=path, command=command) + "\n")
    result.paths = [md, csv_path]
    return result
