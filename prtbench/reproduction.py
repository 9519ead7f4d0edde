"""Reproductions of paper tables and figures (DESIGN.md §11).

A reproduction declares the paper and table, its sweep (methods × configs × scenes × lights ×
views) as :class:`Cell` objects, the paper's own numbers (shown only in "paper" columns), the
scene substitutions it had to make, and a formatter. :func:`run_table` runs the sweep through
the ordinary runner, which appends rows to the results store, then builds the report **from
the store** (filtered to this sweep's run ids) and writes ``reports/table-<name>.md`` and
``.csv``.
"""

from __future__ import annotations

import csv
import io
import math
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .cache import atomic_path
from .registry import Registry


@dataclass(frozen=True)
class Cell:
    """One measured configuration of a sweep.

    ``label`` holds the row/column keys the formatter groups by (e.g. ``{"ground": "2"}``).
    """

    method: str
    scene: str
    label: Mapping[str, Any]
    variant: str = "diffuse"
    light: str | None = None
    overrides: Mapping[str, Any] = field(default_factory=dict)
    scene_params: Mapping[str, Any] = field(default_factory=dict)
    reference: str = "path"
    views: int | None = None


class Reproduction:
    """Base class: subclasses set the attributes and implement :meth:`cells` and :meth:`format`."""

    name: str = ""
    paper: str = ""
    title: str = ""
    substitutions: Sequence[str] = ()
    notes: Sequence[str] = ()

    def cells(self, profile: str) -> list[Cell]:
        raise NotImplementedError

    def measure(self, profile: str, *, results_path: Path | None = None) -> list[str]:
        """Measurements the generic runner cannot make (e.g. per-pass timings).

        A table that times things itself appends its rows to the results store at
        ``results_path`` (None: the default store) and returns their run ids, which
        :func:`run_table` adds to the rows of :meth:`cells`. The default measures nothing.
        """
        return []

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
                 f"rasterisers). Machine: {distinct('device')}. Git: {distinct('git_sha')}.", ""]
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


def run_table(reproduction: Reproduction, *, profile: str = "quick",
              results_path: Path | None = None, reports_dir: Path = Path("reports"),
              progress: bool = True) -> list[Path]:
    """Run the sweep, then write the report from the stored rows; returns the written paths."""
    from .results import load
    from .runner import RunRequest, execute, prepare

    cells = reproduction.cells(profile)
    # Validate every cell before running any, so a bad cell writes nothing.
    prepared = [prepare(RunRequest(
        method=c.method, scene=c.scene, variant=c.variant, light=c.light, views=c.views,
        profile=profile, reference=c.reference, overrides=dict(c.overrides),
        scene_params=dict(c.scene_params), out_dir=None, results_path=results_path,
        write_images=False)) for c in cells]
    run_ids: dict[str, Cell] = {}
    for i, (cell, job) in enumerate(zip(cells, prepared)):
        print(f"[table {reproduction.name}] cell {i + 1}/{len(cells)}: {dict(cell.label)}",
              file=sys.stderr, flush=True)
        summary = execute(job, progress=progress)
        run_ids[summary.run_id] = cell
    own_run_ids = reproduction.measure(profile, results_path=results_path)
    frame = load(results_path)
    frame = frame[frame["run_id"].isin([*run_ids, *own_run_ids])].copy()
    for key in sorted({k for c in cells for k in c.label}):
        frame[f"label_{key}"] = [dict(run_ids[r].label).get(key) if r in run_ids else None
                                 for r in frame["run_id"]]
    header, rows = reproduction.format(frame, profile=profile)
    reports_dir.mkdir(parents=True, exist_ok=True)
    md_path = reports_dir / f"table-{reproduction.name}.md"
    csv_path = reports_dir / f"table-{reproduction.name}.csv"
    with atomic_path(md_path) as tmp:
        tmp.write_text(reproduction.markdown(header, rows, profile=profile, frame=frame))
    buf = io.StringIO()
    writer = csv.writer(buf)
    writer.writerow(header)
    writer.writerows(rows)
    with atomic_path(csv_path) as tmp:
        tmp.write_text(buf.getvalue())
    return [md_path, csv_path]


class Figure:
    """A paper figure regenerated from our own renders (PNG panels with labels)."""

    name: str = ""
    paper: str = ""
    title: str = ""
    substitutions: Sequence[str] = ()

    def make(self, *, profile: str, reports_dir: Path, results_path: Path | None = None,
             progress: bool = True) -> list[Path]:
        """Render and write the figure; returns the written paths (PNG and a caption .md)."""
        raise NotImplementedError


#: name -> Figure instance, lazily imported from ``reproductions``.
FIGURES: Registry[Figure] = Registry("figure", entry_point_group="prtbench.figures")
