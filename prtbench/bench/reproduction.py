"""Reproductions of paper tables and figures (DESIGN.md §11).

A reproduction declares the paper and table, its sweep (methods × configs × scenes × lights ×
views) as :class:`Job` objects, the paper's own numbers (shown only in "paper" columns), the
scene substitutions it had to make, and a formatter. :func:`run_table` runs the sweep through
the ordinary runner, which appends rows to the results store, records the sweep as a *report
run* (:mod:`prtbench.store.measurements`), then builds the report **from the store** (the report
run's rows only) and writes ``reports/table-<name>.md`` and ``.csv``. A :class:`Figure` splits
the same way into :meth:`Figure.measure` (writes rows) and :meth:`Figure.plot` (reads them).
``--from-store`` skips the measuring and formats the newest complete report run again.
"""

from __future__ import annotations

import csv
import io
import math
import re
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from prtbench.api.cache import atomic_path
from prtbench.api.profiles import get_profile
from prtbench.api.registry import Registry
from prtbench.bench.job import Job
from prtbench.bench.submit import JobResult, submit
from prtbench.store import measurements
from prtbench.store.results import load


class Reproduction:
    """Base class: subclasses set the attributes and implement :meth:`format`, and :meth:`cells`
    and/or :meth:`measure` for what it measures."""

    name: str = ""
    paper: str = ""
    title: str = ""
    substitutions: Sequence[str] = ()
    notes: Sequence[str] = ()

    def cells(self, profile: str) -> list[Job]:
        """The runner cells this table sweeps. Default none: a table that measures everything
        itself (its own harness in :meth:`measure`) needs no cells."""
        return []

    def measure(self, profile: str, *, results_path: Path | None = None) -> list[str]:
        """Measurements the generic runner cannot make (e.g. per-pass timings).

        A table that times things itself appends its rows to the results store at
        ``results_path`` (None: the default store) and returns their run ids, which
        :func:`run_table` adds to the rows of :meth:`cells`. The default measures nothing.
        """
        return []

    #: Measurement tables (:mod:`prtbench.store.measurements`) :func:`run_table` hands to
    #: :meth:`format`: tables with a ``cell_run_id`` column are joined onto the rows of that run;
    #: others (facts of the whole report) are DataFrames in ``frame.attrs[name]``.
    measurement_tables: Sequence[str] = ()

    def measure_rows(self, frame, *, profile: str) -> dict[str, list[dict]]:
        """Further measurements of the swept runs: measurement table name -> rows.

        Called once the sweep's rows are stored, with their DataFrame; rows that belong to one
        runner run carry its id as ``cell_run_id``. The default measures nothing.
        """
        return {}

    def format(self, frame, *, profile: str) -> tuple[list[str], list[list[Any]]]:
        """(header, rows) of the table from the results DataFrame of this sweep."""
        raise NotImplementedError

    def markdown(self, header: Sequence[str], rows: Sequence[Sequence[Any]], *, profile: str,
                 frame) -> str:
        def distinct(column: str) -> str:
            # Path-reference columns are NaN on rows compared with a method: skip them.
            values = sorted({_fmt(v) for v in frame[column] if v not in (None, "") and v == v}
                            ) if len(frame) else []
            return ", ".join(values) or "n/a"

        lines = [f"# {self.title}", "", f"Source: {self.paper}", "",
                 f"Profile: `{profile}`. GL renderer: {distinct('renderer')}. "
                 f"Timing: {distinct('timing_source')} (`timer-query` = GL timer queries; "
                 f"`wall+finish` = host clock around draw + glFinish, used on software "
                 f"rasterisers). Machine: {distinct('device')}. Git: {distinct('git_sha')}."
                 f"{load_note([frame])}", ""]
        # Rows that name the path reference but compared nothing with it (own-harness timings)
        # carry no noise estimate.
        path_rows = frame[(frame["reference_kind"] == "path") & frame["reference_noise"].notna()
                          ] if len(frame) else frame
        if len(path_rows):
            noise = float(path_rows["reference_noise"].max())
            ceiling = float("inf") if noise <= 0 else -20 * math.log10(noise)
            lines += [f"Path reference: Mitsuba 3, {distinct('reference_spp')} spp; its own display "
                      f"noise RMSE is at most {noise:.4f}, so PSNRs above ~{ceiling:.1f} dB are not "
                      f"resolved by it.", ""]
        lines.append("| " + " | ".join(header) + " |")
        lines.append("|" + "|".join("---" for _ in header) + "|")
        for row in rows:
            lines.append("| " + " | ".join(_fmt(v) for v in row) + " |")
        if self.substitutions:
            lines += ["", "## Scene substitutions", ""] + [f"- {s}" for s in self.substitutions]
        if self.notes:
            lines += ["", "## Notes", ""] + [f"- {n}" for n in self.notes]
        return "\n".join(lines) + "\n"


def _fmt(value: Any) -> str:
    if isinstance(value, float):
        if value != value:  # NaN
            return "—"
        return f"{value:.4g}" if abs(value) < 1e4 else f"{value:.3e}"
    return str(value)


#: name -> Reproduction instance, lazily imported from ``reproductions``.
TABLES: Registry[Reproduction] = Registry("table", entry_point_group="prtbench.tables")


def _check_profile(profile: str) -> None:
    get_profile(profile)  # an unknown profile is a one-line error before any work


class Stored:
    """What a formatter or plotter may read: one complete report run, from the store only.

    Parameters
    ----------
    report : prtbench.store.measurements.ReportRun
    """

    def __init__(self, report):
        self.report = report
        self.profile = report.profile
        self.run_id = report.run_id
        self.results_path = report.results_path

    def frame(self):
        """The result rows of the report's runner runs (and own runs), with ``label_<key>`` columns."""

        members = self.report.members
        frame = load(self.results_path)
        if len(frame):
            frame = frame[frame["run_id"].isin(list(members))].copy()
        for key in sorted({k for label in members.values() for k in label}):
            frame[f"label_{key}"] = [members.get(r, {}).get(key) for r in frame["run_id"]]
        return frame

    def table(self, name: str):
        """Measurement table ``name`` of this report run (:func:`prtbench.store.measurements.load`)."""

        return measurements.load(name, run_ids=[self.run_id], results_path=self.results_path)

    def images(self) -> dict:
        """The panels stored with this report run, key -> ndarray.

        Panels stored as 8-bit display values (:func:`display_panels`) come back as float32 in
        [0, 1]; other arrays as stored.
        """

        return {k: (v.astype(np.float32) / 255.0 if v.dtype == np.uint8 else v) for k, v in
                measurements.load_images(self.run_id, results_path=self.results_path).items()}


def display_panels(images: Mapping[str, Any]) -> dict:
    """Display images (float in [0, 1]) as the 8-bit values a PNG shows, for storing.

    Parameters
    ----------
    images : dict of str to ndarray, shape (H, W) or (H, W, 3), float

    Returns
    -------
    dict of str to ndarray, uint8
        A paper-size panel is 6 MiB instead of 25 MiB of float32; :meth:`Stored.images`
        turns them back into floats.
    """

    return {k: np.round(np.clip(np.asarray(v, np.float64), 0.0, 1.0) * 255.0).astype(np.uint8)
            for k, v in images.items()}


def _write_text(path: Path, text: str) -> Path:
    with atomic_path(path) as tmp:
        tmp.write_text(text)
    return path


def write_csv(path: Path, header: Sequence[str], rows: Sequence[Sequence[Any]]) -> Path:
    """Atomically write a CSV of ``header`` and ``rows``."""
    buf = io.StringIO()
    writer = csv.writer(buf)
    writer.writerow(header)
    writer.writerows(rows)
    return _write_text(path, buf.getvalue())


def run_table(reproduction: Reproduction, *, profile: str = "quick",
              results_path: Path | None = None, reports_dir: Path = Path("reports"),
              progress: bool = True, from_store: bool = False) -> list[Path]:
    """Run the sweep (unless ``from_store``), then write the report from the stored rows.

    With ``from_store`` nothing is measured: the newest complete run of this table for
    ``profile`` is formatted again (a one-line error, writing nothing, if there is none).
    Returns the written paths.
    """

    _check_profile(profile)
    if from_store:
        report = measurements.require_report("table", reproduction.name, profile=profile,
                                              results_path=results_path)
    else:
        report = _measure_table(reproduction, profile=profile, results_path=results_path,
                                progress=progress)
    stored = Stored(report)
    frame = stored.frame()
    per_report = {}
    for table in reproduction.measurement_tables:
        rows = stored.table(table)
        if "cell_run_id" in rows.columns:
            frame = _merge_measurements(frame, rows)
        else:  # facts of the whole report (e.g. a GL limit): frame.attrs[table]
            per_report[table] = rows
    frame.attrs.update(per_report)
    header, rows = reproduction.format(frame, profile=profile)
    reports_dir = Path(reports_dir)
    reports_dir.mkdir(parents=True, exist_ok=True)
    md_path = _write_text(reports_dir / f"table-{reproduction.name}.md",
                          reproduction.markdown(header, rows, profile=profile, frame=frame))
    csv_path = write_csv(reports_dir / f"table-{reproduction.name}.csv", header, rows)
    return [md_path, csv_path]


def _measure_table(reproduction: Reproduction, *, profile: str, results_path: Path | None,
                   progress: bool):
    jobs = reproduction.cells(profile)

    def announce(result: JobResult) -> None:
        print(f"[table {reproduction.name}] {result.job.describe()}: {result.status}"
              f"{f' ({result.error})' if result.error else ''}", file=sys.stderr, flush=True)

    # Every cell is validated before any runs; a failing cell is an error of the table.
    submission = submit(jobs, profile=profile, results_path=results_path, progress=progress,
                        run_progress=progress, echo=progress, desc=f"table {reproduction.name}",
                        raise_errors=True, on_result=announce)
    members: dict[str, dict] = {}
    for job, result in zip(jobs, submission.per_job):
        members[result.summary.run_id] = dict(job.label)
    for own in reproduction.measure(profile, results_path=results_path):
        members.setdefault(own, {})
    run_id = measurements.new_run_id()
    partial = Stored(measurements.ReportRun("table", reproduction.name, profile, run_id, "", "",
                                            members, measurements.store_path(results_path)))
    extra = reproduction.measure_rows(partial.frame(), profile=profile)
    for table, rows in extra.items():
        measurements.record(table, rows, results_path=results_path, run_id=run_id,
                            profile=profile)
    return measurements.complete_report("table", reproduction.name, profile=profile,
                                        run_id=run_id, members=members,
                                        results_path=results_path)


def _merge_measurements(frame, table):
    """Columns of a measurement table keyed by ``cell_run_id`` joined onto the result rows."""
    if not len(table) or not len(frame):
        return frame
    provenance = {"run_id", "profile", "git_sha", "renderer", "device", "timestamp"}
    clash = sorted((set(table.columns) - provenance - {"cell_run_id"}) & set(frame.columns))
    if clash:  # a suffixed copy would hide the result rows' own column
        raise ValueError(f"measurement table columns {clash} are result-row columns already")
    extra = table.drop(columns=[c for c in table.columns if c in provenance])
    return frame.merge(extra, how="left", left_on="run_id", right_on="cell_run_id",
                       sort=False).drop(columns=["cell_run_id"])


class Figure:
    """A paper figure regenerated from stored rows.

    Subclasses implement :meth:`measure` (renders, writes result rows through the runner and
    measurement rows/panels under the report's run id) and :meth:`plot` (reads the store only
    and writes the PNG(s) and caption). :meth:`make` runs both, or only :meth:`plot` on the
    newest complete stored run with ``from_store``.
    """

    name: str = ""
    paper: str = ""
    title: str = ""
    substitutions: Sequence[str] = ()

    def measure(self, *, profile: str, results_path: Path | None, run_id: str,
                progress: bool = True) -> dict[str, dict]:
        """Measure and store; returns the runner run ids used, each with its cell label."""
        raise NotImplementedError

    def plot(self, stored: Stored, *, reports_dir: Path) -> list[Path]:
        """Write the figure from ``stored`` alone; returns the written paths."""
        raise NotImplementedError

    def make(self, *, profile: str, reports_dir: Path, results_path: Path | None = None,
             progress: bool = True, from_store: bool = False) -> list[Path]:
        """Measure (unless ``from_store``) and write the figure; returns the written paths."""

        _check_profile(profile)
        if from_store:
            report = measurements.require_report("figure", self.name, profile=profile,
                                                  results_path=results_path)
        else:
            run_id = measurements.new_run_id()
            members = self.measure(profile=profile, results_path=results_path, run_id=run_id,
                                   progress=progress)
            report = measurements.complete_report("figure", self.name, profile=profile,
                                                  run_id=run_id, members=members,
                                                  results_path=results_path)
        reports_dir = Path(reports_dir)
        reports_dir.mkdir(parents=True, exist_ok=True)
        return self.plot(Stored(report), reports_dir=reports_dir)


def provenance_line(frames: Sequence[Any], *, profile: str) -> str:
    """One caption line naming the profile and, from the stored rows, commit, renderer, machine.

    ``frames`` are DataFrames with ``git_sha`` (and optionally ``renderer``, ``device``) columns:
    result rows or measurement tables.
    """
    def distinct(column: str) -> str:
        values = sorted({str(v) for f in frames if len(f) and column in f.columns
                         for v in f[column] if v not in (None, "") and v == v})
        return ", ".join(values) or "n/a"

    return (f"Measured with profile `{profile}` at git {distinct('git_sha')}. "
            f"GL renderer: {distinct('renderer')}. Machine: {distinct('device')}."
            f"{load_note(frames)}")


#: A 1-minute load average above this many times the measuring machine's core count marks
#: its timings as taken on a busy machine (one run alone, with llvmpipe's threads, stays
#: under it).
BUSY_LOAD_PER_CORE = 1.5


def load_note(frames: Sequence[Any]) -> str:
    """`` Load while measuring: …`` from the rows' ``load_average`` ('' where none is stored).

    Says plainly when the largest load exceeds :data:`BUSY_LOAD_PER_CORE` × the cores named
    in the rows' ``device`` ("…, 2 cores"): frame times and FPS are then not representative.
    """
    loads = [float(v) for f in frames if len(f) and "load_average" in f.columns
             for v in f["load_average"] if v is not None and v == v]
    if not loads:
        return ""
    cores = [int(m.group(1)) for f in frames if len(f) and "device" in f.columns
             for d in f["device"] if isinstance(d, str)
             for m in [re.search(r"(\d+) cores", d)] if m]
    note = f" Load while measuring: 1-min load average {min(loads):.1f} to {max(loads):.1f}"
    if cores and max(loads) > BUSY_LOAD_PER_CORE * min(cores):
        note += (f" on {min(cores)} cores: the machine was busy, so frame times and FPS here "
                 "are not representative")
    return note + "."


#: name -> Figure instance, lazily imported from ``reproductions``.
FIGURES: Registry[Figure] = Registry("figure", entry_point_group="prtbench.figures")
