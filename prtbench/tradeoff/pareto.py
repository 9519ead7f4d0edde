"""Pareto fronts over (error, cost) from the results store (DESIGN.md §15).

A *point* is one configuration measured on one scene and light: the ok rows of one (method,
config, scene, variant, light, profile, resolution) against the path reference, its error
averaged over the views and its cost (:mod:`.cost`) over the same rows. Configurations are
compared across all methods together, separately for each material variant and resolution (a
*panel*): a diffuse and a glossy plants scene have different references, so their errors are
not comparable.

Error is masked PSNR (higher is better) or masked FLIP (lower is better). It is never reported
tighter than the reference allows: a view's PSNR above its reference's noise ceiling,
``−20·log10(reference_noise)`` (the reference's own display-space noise RMSE), is clipped to
that ceiling before averaging and the point is flagged ``clipped``; configurations clipped to the
same ceiling tie on error, so the cheaper one dominates. FLIP has no stored noise ceiling (no
reference-against-itself FLIP is measured), so it is never clipped and the reports say so.

A point is dominated when another point of its panel is at least as good on both error and
cost and strictly better on one; equal points dominate neither (both stay on the front). Points
whose cost is unknown (not measured, or the method has no ``ops`` model) are listed, never
placed on a front.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

from prtbench.api.errors import PrtbenchError
from prtbench.api.profiles import get_profile
from prtbench.bench import outputs
from prtbench.scene.files import is_scene_path
from prtbench.scene.registry import get_scene
from prtbench.store.results import ResultsStore, default_path
from prtbench.tradeoff import cost as cost_mod
from prtbench.tradeoff.front import (
    ParetoResult,
    Point,
    check_error_kind,
    collect_points,
    mark_fronts,
    ops_correlations,
)
from prtbench.tradeoff.pareto_report import write_reports


def fill_hint(scene: str, profile: str) -> str:
    """The command that fills the store for ``scene`` (a sweep file when one exists here)."""
    grid = Path("sweeps") / f"{scene}-all.toml"
    if grid.is_file():
        return f"`prtbench sweep {grid} --profile {profile}` fills it"
    return f"`prtbench sweep --scene {scene} --method METHOD,... --profile {profile}` fills it"


def select_rows(store, *, scene: str, light: str | None, profile: str,
                fill: str | None = None) -> dict[str, list]:
    """The store's rows of ``scene`` and ``profile`` by light (ok, against the path reference).

    Raises a one-line PrtbenchError naming the command that fills the store when nothing fits.
    """
    rows = store.query(scene=scene, profile=profile, status="ok")
    rows = [r for r in rows if r.reference_kind == "path"]
    by_light: dict[str, list] = defaultdict(list)
    for r in rows:
        by_light[r.light].append(r)
    fill = fill or fill_hint(scene, profile)
    if not by_light:
        raise PrtbenchError(f"no ok rows of scene '{scene}' in profile '{profile}' against the "
                            f"path reference in results store '{store.path}'; {fill}")
    if light is not None:
        if light not in by_light:
            raise PrtbenchError(f"no ok rows of scene '{scene}' under light '{light}' in profile "
                                f"'{profile}' in '{store.path}' (stored lights: "
                                f"{', '.join(sorted(by_light))}); {fill}")
        return {light: by_light[light]}
    return dict(sorted(by_light.items()))


@dataclass
class Selection:
    """What every report over the store starts from, once its options are checked.

    Attributes
    ----------
    scene : str
        The name the rows are stored under (an asset file's content-hash name).
    path : Path
        The results store, opened read-only.
    hint : str
        The command that fills the store, for messages.
    rows_by_light : dict
        light -> the ok rows against the path reference (:func:`select_rows`).
    """

    scene: str
    path: Path
    hint: str
    rows_by_light: dict[str, list]


def open_selection(*, scene: str, light: str | None, error: str, cost: str, profile: str,
                   results_path: str | Path | None, reports_dir: str | Path,
                   scene_params: dict | None) -> Selection:
    """Check every option before any work, then read the store's rows (read-only).

    ``scene`` may be an asset file (DESIGN.md §16): it is imported with ``scene_params`` to
    find the name its rows are stored under. Raises PrtbenchError (one line) for bad names,
    an unwritable ``reports_dir``, a missing store and an empty selection.
    """
    if is_scene_path(scene):
        given = scene
        scene = get_scene(given, **(scene_params or {})).name
        hint = fill_hint(given, profile)
    else:
        hint = fill_hint(scene, profile)
    check_error_kind(error)
    cost_mod.check_cost_kind(cost)
    get_profile(profile)
    outputs.check_folder("--reports", Path(reports_dir))
    path = Path(results_path) if results_path is not None else default_path()
    if not path.is_file() and not path.is_dir():
        raise PrtbenchError(f"no results store at '{path}'; {hint}")
    store = ResultsStore(path, readonly=True)
    return Selection(scene=scene, path=path, hint=hint,
                     rows_by_light=select_rows(store, scene=scene, light=light, profile=profile,
                                               fill=hint))


def light_points(selection: Selection, light: str, *, error: str, cost: str
                 ) -> tuple[list[Point], list[str]]:
    """:func:`collect_points` of one light's rows; a one-line PrtbenchError when none has a
    finite ``error``."""
    points, skipped = collect_points(selection.rows_by_light[light], error=error, cost=cost)
    if not points:
        raise PrtbenchError(f"no configuration of scene '{selection.scene}' under light "
                            f"'{light}' has a finite {error} in '{selection.path}'; "
                            f"{selection.hint}")
    return points, skipped


def pareto(*, scene: str, light: str | None = None, error: str = "psnr_masked",
           cost: str = "frame_ms", profile: str = "quick", results_path: str | Path | None = None,
           reports_dir: str | Path = "reports",
           scene_params: dict | None = None) -> list[ParetoResult]:
    """Fronts of ``scene`` (every stored light, or ``light``) and their reports.

    ``scene`` may be an asset file (DESIGN.md §16): it is imported with ``scene_params`` to
    find the name its rows are stored under (the file's content hash and the parameters).
    Reads the store read-only; writes ``reports_dir/pareto-<scene>-<light>.{md,csv,png,svg}``
    atomically. Raises PrtbenchError (one line) for bad names and an empty selection.
    """
    selection = open_selection(scene=scene, light=light, error=error, cost=cost, profile=profile,
                               results_path=results_path, reports_dir=reports_dir,
                               scene_params=scene_params)
    results = []
    for name, rows in selection.rows_by_light.items():
        points, skipped = light_points(selection, name, error=error, cost=cost)
        mark_fronts(points, error=error)
        correlation = ops_correlations(rows)
        result = ParetoResult(scene=selection.scene, light=name, error=error, cost=cost,
                              profile=profile, points=points, skipped=skipped,
                              correlation=correlation, paths=[])
        result.paths = write_reports(result, reports_dir=Path(reports_dir),
                                     results_path=selection.path)
        results.append(result)
    return results
