"""The claims ledger's pages: ``claims.md`` (provenance, counts per verdict, one row per claim)
and ``claims.csv``, from the assessments :mod:`prtbench.bench.claims` makes."""

from __future__ import annotations

import csv
import io
import math
from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from prtbench.api.cache import atomic_path
from prtbench.bench.claims import CONTRADICTED, CSV_COLUMNS, NO_DATA, VERDICTS, Assessment
from prtbench.bench.reproduction import load_note
from prtbench.bench.runner import device_description, load_average
from prtbench.store.results import git_sha


def counts(assessments: Sequence[Assessment]) -> dict[str, int]:
    """Claims per verdict, every verdict listed."""
    found = Counter(a.verdict for a in assessments)
    return {v: found.get(v, 0) for v in VERDICTS}


def counts_text(assessments: Sequence[Assessment]) -> str:
    """``N claims: a reproduced, b direction only, ...`` (saying how many have no data)."""
    tally = counts(assessments)
    no_data = sum(a.no_data for a in assessments)
    return (f"{len(assessments)} claims: " + ", ".join(f"{n} {v}" for v, n in tally.items())
            + (f" (of which {no_data} {NO_DATA})" if no_data else ""))


def display_path(path: str | Path) -> str:
    """A path as a report may print it: relative to the working folder, else its file name
    (reports never name a machine's absolute path)."""
    path = Path(path)
    try:
        return path.resolve().relative_to(Path.cwd().resolve()).as_posix()
    except ValueError:
        return path.name


def _distinct(frames: Sequence[Any], column: str) -> list[str]:
    return sorted({str(v) for f in frames if len(f) and column in f.columns
                   for v in f[column] if v is not None and not _nan(v) and str(v)})


def _nan(value) -> bool:
    return isinstance(value, float) and math.isnan(value)


def provenance_text(assessments: Sequence[Assessment], *, ledger_sha: str | None = None) -> str:
    """Where the verdicts come from, as the other reports say it: the commit the ledger ran at,
    the commits, renderers and machines of every stored run read, and the 1-minute load while
    they were measured (:func:`prtbench.bench.reproduction.load_note`).

    With no run read, the machine and load are this machine's now (nothing was measured).
    """
    ledger_sha = ledger_sha or git_sha()
    runs = list({id(r): r for a in assessments for r in a.runs}.values())
    frames = [f for r in runs for f in r.provenance_frames()]
    head = f"Ledger evaluated at git {ledger_sha}."
    if not runs:
        load = load_average()
        return (head + " No stored run was read (every claim that needs one is "
                f"'{NO_DATA}'). Machine: {device_description()}."
                + (f" Load when written: 1-min load average {load:.1f} to {load:.1f}."
                   if load is not None else ""))
    commits = _distinct(frames, "git_sha")
    same = commits == [ledger_sha]
    return (head + f" The {len(runs)} stored report run{'s' if len(runs) != 1 else ''} read: "
            + ("measured at the same commit" if same else f"measured at git {', '.join(commits)}")
            + f"; profiles {', '.join(sorted({r.profile for r in runs}))}. "
            f"GL renderer: {', '.join(_distinct(frames, 'renderer')) or 'n/a'}. "
            f"Machine: {'; '.join(_distinct(frames, 'device')) or 'n/a'}.{load_note(frames)}")


def csv_text(assessments: Sequence[Assessment]) -> str:
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    writer.writerows(a.row() for a in assessments)
    return buf.getvalue()


def _cell(text: str) -> str:
    return " ".join(str(text).split()).replace("|", "\\|") or "—"


def markdown_text(assessments: Sequence[Assessment], *, results_path: str | Path,
                  provenance: str | None = None, note: str = "") -> str:
    """The ledger page: provenance, counts per verdict, one row per claim.

    ``provenance`` defaults to :func:`provenance_text`; ``note`` is a line added under it
    (e.g. that only some sources were asked for).
    """
    tally = counts(assessments)
    no_data = sum(a.no_data for a in assessments)
    provenance = provenance_text(assessments) if provenance is None else provenance
    lines = ["# Claims ledger: the papers' claims against our measurements", "",
             (f"Results store: `{display_path(results_path)}`. Each verdict reads the newest "
              "complete run of the claim's report (the most thorough profile stored, or the one "
              "asked for); `prtbench claims` rebuilds this page and `claims.csv` from the store "
              "alone. A paper's number is only ever in the *paper* column; *ours* is measured "
              f"here. A claim the store cannot answer says '{NO_DATA}' and gives the command "
              "that measures it."), "", provenance, "",
             *([note, ""] if note else []),
             counts_text(assessments), "", "| verdict | claims |", "|---|---|",
             *(f"| {v} | {n} |" for v, n in tally.items()),
             *([f"| (of which {NO_DATA}) | {no_data} |"] if no_data else []), "",
             ("| id | source | claim | paper | ours | interval | verdict | explanation | report "
              "| command |"), "|---|---|---|---|---|---|---|---|---|---|"]
    for a in assessments:
        c = a.claim
        lines.append("| " + " | ".join(_cell(x) for x in (
            c.id, f"{c.source}, {c.section}", c.quote, c.paper, a.ours, a.interval, a.verdict,
            a.explanation, (c.report or "computed") + (f" ({a.profile})" if a.run_id else ""),
            f"`{a.command}`" if a.command else "")) + " |")
    unexplained = [a for a in assessments if a.verdict == CONTRADICTED
                   and "unexplained" in a.explanation]
    if unexplained:
        lines += ["", "## Contradictions no stored measurement explains yet", ""]
        lines += [f"- `{a.claim.id}`: {a.explanation}" for a in unexplained]
    return "\n".join(lines) + "\n"


def write_reports(assessments: Sequence[Assessment], *, reports_dir: Path,
                  results_path: Path, note: str = "") -> list[Path]:
    """``claims.md`` and ``claims.csv`` in ``reports_dir``, each written atomically."""
    md, csv_path = Path(reports_dir) / "claims.md", Path(reports_dir) / "claims.csv"
    text_md = markdown_text(assessments, results_path=results_path, note=note)
    text_csv = csv_text(assessments)
    with atomic_path(csv_path) as tmp:
        tmp.write_text(text_csv)
    with atomic_path(md) as tmp:
        tmp.write_text(text_md)
    return [md, csv_path]
