"""The stability matrix: every case of every chosen method, measured, classified and stored.

Each case's numbers go into the results store as one row of the measurement table
``stability`` (:mod:`prtbench.store.measurements`), the moment the case finishes, so an interrupted
matrix keeps what it measured; the render rows the runner writes carry the same case name in
their ``scene_params``. When every case has run, a ``table stability`` report run names the
runner runs it used: the report (:mod:`prtbench.stability.report`) prints only stored rows.
"""

from __future__ import annotations

import math
import os
import sys
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from prtbench.api.errors import PrtbenchError
from prtbench.api.method import METHODS
from prtbench.bench.runner import device_description
from prtbench.stability.case import Case
from prtbench.stability.cases import base_case, method_cases, select
from prtbench.stability.core import core_rows
from prtbench.stability.outcome import classify
from prtbench.stability.report import IMPORTED_FROM
from prtbench.stability.run import run_case
from prtbench.store import measurements
from prtbench.store.results import ResultsStore

#: Name of the measurement table (and of the report run).
TABLE = "stability"
#: The pseudo-method of the SH core's rows (:mod:`prtbench.stability.core`).
CORE = "sh-core"


def _log(echo: bool, text: str) -> None:
    if echo:
        print(text, file=sys.stderr, flush=True)


def _load_1m() -> float:
    """The machine's 1-minute load average (NaN where the OS has none): a case's timings are
    only comparable with the load they were measured under."""
    try:
        return float(os.getloadavg()[0])
    except OSError:
        return math.nan


def table_name(scene_label: str | None = None) -> str:
    """The measurement table (and report run) of a matrix: :data:`TABLE` on the built-in base
    scenes, ``stability-<scene name>`` on a file scene (whose name carries its content hash),
    so a user's scene never mixes into the committed report's rows."""
    return TABLE if not scene_label else f"{TABLE}-{scene_label}"


def plan(methods: Sequence[str], *, profile: str, cases: Sequence[str] | None = None,
         scene_file: str | None = None, scene_params: Mapping[str, Any] | None = None,
         ) -> list[tuple[str, dict[str, Any], list[Case]]]:
    """``(method, base case, cases)`` for each method, validated before any work.

    Parameters
    ----------
    scene_file : str, optional
        An asset file (``--scene``) as every method's base scene, with ``scene_params``.

    Raises
    ------
    UnknownNameError
        An unknown method, profile or case name.
    InvalidInputError
        A scene file that cannot be imported (the scenefile message).
    """

    out = []
    known: set[str] = set()
    for method in methods:
        if method == CORE:
            continue
        cls = METHODS.get(method)
        all_cases = method_cases(cls, profile=profile, scene_file=scene_file,
                                 scene_params=scene_params)
        known |= {c.name for c in all_cases}
        chosen = [c for c in all_cases if not cases or c.name == "moderate" or c.name in cases]
        out.append((method, base_case(cls, scene_file=scene_file, scene_params=scene_params),
                    chosen))
    missing = [name for name in cases or () if name not in known]
    if missing:  # a case name must belong to at least one of the methods
        select([Case(n, "") for n in sorted(known)], missing)  # raises, listing the names
    return out


def run_matrix(methods: Sequence[str], *, profile: str, results_path: Path | None,
               out_dir: Path | None = None, cases: Sequence[str] | None = None,
               timeout_s: float | None = None, echo: bool = True,
               scene_file: str | None = None,
               scene_params: Mapping[str, Any] | None = None) -> str:
    """Measure every case of ``methods``; returns the report run's id.

    Parameters
    ----------
    methods : sequence of str
        Registered method names, and :data:`CORE` for the SH core's rows.
    profile : {"smoke", "quick"}
    results_path : Path or None
        The results store (None: the default one).
    out_dir : Path, optional
        Where the runs' images go (default: a temporary folder, removed afterwards).
    cases : sequence of str, optional
        Only these case names (the moderate case always runs first).
    timeout_s : float, optional
        Per-case limit (default :data:`prtbench.stability.run.TIMEOUTS`).
    echo : bool
        One progress line per case on stderr.
    scene_file, scene_params : optional
        An asset file as the base scene (:func:`plan`); its rows go to
        :func:`table_name` of the scene's name.
    """

    planned = plan(methods, profile=profile, cases=cases, scene_file=scene_file,
                   scene_params=scene_params)
    table = table_name(planned[0][1]["label"] if scene_file and planned else None)
    run_id = measurements.new_run_id()
    members: dict[str, dict[str, str]] = {}
    device = device_description()
    with tempfile.TemporaryDirectory(prefix="prtbench-stability-") as tmp:
        root = Path(out_dir) if out_dir is not None else Path(tmp)
        for method, base, method_cases_ in planned:
            moderate: dict[str, Any] | None = None
            moderate_exr = None
            for case in method_cases_:
                folder = root / method / case.name.replace("=", "-").replace("/", "-")
                load_before = _load_1m()
                measured = run_case(method, case, profile=profile, base=base,
                                    results_path=results_path, out_dir=folder,
                                    moderate_exr=moderate_exr, timeout_s=timeout_s)
                if measured.get("rows"):  # the client alone writes the store
                    ResultsStore(results_path).append(measured.pop("rows"))
                measured.pop("rows", None)
                is_moderate = case.name == "moderate"
                outcome, reason = classify(measured, None if is_moderate else (moderate or {}))
                if is_moderate:
                    moderate, moderate_exr = measured, measured.get("image_exr")
                row = {"method": method, "case": case.name, "group": case.group,
                       "note": case.note, "advice": case.advice,
                       "overrides": {**case.overrides, **measured.get("derived_overrides", {})},
                       "scene": case.scene or base.get("label", base["scene"]),
                       "variant": "glossy" if case.shininess is not None else base["variant"],
                       "outcome": outcome, "reason": reason,
                       "moderate_psnr_masked": (moderate or {}).get("psnr_masked"),
                       "moderate_flip_masked": (moderate or {}).get("flip_masked"),
                       "load_1m": max(load_before, _load_1m()),
                       **{k: v for k, v in measured.items() if k != "image_exr"}}
                measurements.record(table, [row], results_path=results_path, run_id=run_id,
                                    profile=profile, renderer=measured.get("renderer") or "",
                                    device=device)
                if measured.get("run_id"):
                    members[measured["run_id"]] = {"method": method, "case": case.name}
                _log(echo, f"[stability] {method} {case.name}: {outcome} ({reason}) "
                           f"{measured.get('wall_s', 0.0):.1f} s")
    if CORE in methods:

        for row in core_rows(profile=profile):
            measurements.record(table, [row], results_path=results_path, run_id=run_id,
                                profile=profile, device=device)
            _log(echo, f"[stability] {CORE} {row['case']}: {row['outcome']} ({row['reason']})")
    measurements.complete_report("table", table, profile=profile, run_id=run_id,
                                 members=members, results_path=results_path)
    return run_id


def load_rows(run_id: str, *, results_path: Path | None,
              table: str = TABLE) -> list[dict[str, Any]]:
    """The stored rows of one matrix run (of measurement ``table``), in measured order."""

    frame = measurements.load(table, run_ids=[run_id], results_path=results_path)
    rows = frame.to_dict(orient="records")
    return [{k: (None if isinstance(v, float) and v != v else v) for k, v in r.items()}
            for r in rows]


def stored_rows(*, profile: str, results_path: Path | None, partial: bool = False,
                table: str = TABLE) -> list[dict[str, Any]]:
    """The newest stored row of each (method, case) for ``profile`` (SH core rows last).

    Matrix runs over different methods or cases (e.g. run side by side) are merged; each row
    keeps the run it came from (its moderate case is that run's). Newest is the row's own
    measurement time (rows imported from a CSV keep theirs), then the newest run. Only
    complete runs count unless ``partial``: then an interrupted run (rows stored, no report
    run) counts too, and its rows are marked ``partial_run = True``.

    Raises
    ------
    PrtbenchError
        No (complete, unless ``partial``) stability run for ``profile`` in the store.
    """

    runs, complete = stored_runs(profile=profile, results_path=results_path, partial=partial,
                                 table=table)
    if not runs:
        path = measurements.store_path(results_path)
        raise PrtbenchError(f"no {'' if partial else 'complete '}stability run for profile "
                            f"'{profile}' in results store '{path}'; measure it first with: "
                            f"prtbench stability --profile {profile} --results {path}")
    chosen: dict[tuple[str, str], dict[str, Any]] = {}
    for run in runs:  # newest run first; a row measured later (its timestamp) replaces one
        for row in load_rows(run, results_path=results_path, table=table):
            key = (row["method"], row["case"])
            # Imported rows keep their own time and join the store after later runs, so the
            # run order alone would let an old row win. Timestamps are all the store's UTC
            # format (the importer refuses others), so they order as strings. On a tie a
            # measured row beats an imported one, else the newer run's row stays.
            held = chosen.get(key)
            stamp, held_stamp = str(row.get("timestamp") or ""), str((held or {}).get(
                "timestamp") or "")
            if held is None or stamp > held_stamp or (
                    stamp == held_stamp and held.get(IMPORTED_FROM) and not row.get(IMPORTED_FROM)):
                chosen[key] = {**row, "partial_run": run not in complete}
    methods = sorted({m for m, _ in chosen}, key=lambda m: (m == CORE, m))
    out = []
    for m in methods:
        mine = [row for (method, _), row in chosen.items() if method == m]
        out += sorted(mine, key=_catalogue_order(m, profile)) if m != CORE else mine
    return out


def stored_runs(*, profile: str, results_path: Path | None, partial: bool = False,
                table: str = TABLE) -> tuple[list[str], set[str]]:
    """The stability runs of ``profile`` with rows in the store, newest first (by their last
    row), complete ones only unless ``partial``; and the set of complete ones.

    Both empty when the store or its tables do not exist; an unusable store raises
    :class:`~prtbench.api.errors.InvalidInputError` (the store's reader).
    """

    complete = {r[0] for r in measurements._read(  # noqa: SLF001 - the store's read-only reader
        results_path, "SELECT run_id FROM report_runs WHERE kind = 'table' AND name = ? AND "
        "profile = ?", [table, profile])}
    runs = [r[0] for r in measurements._read(  # noqa: SLF001
        results_path, "SELECT run_id FROM measurements WHERE name = ? AND profile = ? "
        "GROUP BY run_id ORDER BY MAX(id) DESC", [table, profile])]
    return [r for r in runs if partial or r in complete], complete


def _catalogue_order(method: str, profile: str):
    """Sort key of a method's rows: moderate first, then the catalogue's order (cases it no
    longer has last, by name)."""

    try:
        names = [c.name for c in method_cases(METHODS.get(method), profile=profile)]
    except Exception:  # noqa: BLE001 - a method no longer registered keeps its rows by name
        names = []
    index = {name: i for i, name in enumerate(names)}
    return lambda row: (row["case"] != "moderate", index.get(row["case"], len(index)),
                        row["case"])
