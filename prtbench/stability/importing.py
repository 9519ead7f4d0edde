"""Rows of a written stability CSV back into a results store (``stability --import-csv``).

The committed ``reports/table-stability.csv`` holds every number its report prints, but the
results store it was written from is not committed: when that store is gone, cases measured
later cannot join the earlier ones in one report (``--from-store`` reads the store only).
Importing the CSV carries its rows over unchanged, each keeping the revision, device,
renderer, load and timestamp of the run that measured it, and marked ``imported_from`` (the
file's name and SHA-256) so that the report can say which rows it did not measure itself.
The values round-trip exactly: the CSV holds ``repr`` floats, and the importer parses each
column by its declared kind (text, flag, number), never by guessing from the value.

Rows of interrupted runs (``partial_run`` True) go into an import run that is never
completed, so they count only with ``--partial``, as they did before; the rest go into a
completed import run. A row of the same case measured later wins by its timestamp
(:func:`prtbench.stability.matrix.stored_rows`), whatever the order of import and measuring.
"""

from __future__ import annotations

import csv
import hashlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any

from ..errors import InvalidInputError
from .report import CSV_COLUMNS

#: Columns holding text (never parsed as numbers: a run id may be all digits).
TEXT_COLUMNS = frozenset({
    "method", "case", "group", "outcome", "reason", "scene", "variant", "storage_dtype",
    "status", "run_id", "git_sha", "profile", "renderer", "device", "advice", "note",
    "timestamp", "imported_from"})
#: Columns holding ``True``/``False``.
FLAG_COLUMNS = frozenset({"precompute_cached", "partial_run"})
#: Columns that belong to the stored record rather than to its payload.
RECORD_COLUMNS = ("git_sha", "renderer", "device", "timestamp", "profile")
#: The payload key naming the file a row was imported from.
IMPORTED_FROM = "imported_from"


@dataclass(frozen=True)
class ImportSummary:
    """What :func:`import_csv` stored: run ids and row counts (complete / partial)."""

    source: str
    complete_run: str | None
    partial_run: str | None
    complete_rows: int
    partial_rows: int


def _parse(value: str, column: str, where: str) -> Any:
    if value == "":
        return None
    if column in TEXT_COLUMNS:
        return value
    if column in FLAG_COLUMNS:
        if value not in ("True", "False"):
            raise InvalidInputError(f"{where}: {column}={value!r}; accepted: True, False or empty")
        return value == "True"
    try:  # ints first: the CSV writes 12 and 12.0 differently, and so must the round trip
        return int(value)
    except ValueError:
        pass
    try:
        return float(value)
    except ValueError:
        raise InvalidInputError(f"{where}: {column}={value!r}; accepted: a number or empty"
                                ) from None


def read_rows(path: Path) -> tuple[list[dict[str, Any]], str]:
    """The typed rows of a stability CSV and its source tag ``"<name> sha256:<12 hex>"``.

    Raises
    ------
    InvalidInputError
        A missing or unreadable file, a missing column, an empty file, or a value that is not
        of its column's kind (naming the row, the column and the value).
    """
    from ..results import PROFILES
    from .outcome import OUTCOMES

    accepted = "accepted: a table-stability CSV written by prtbench stability"
    try:
        data = Path(path).read_bytes()
        text = data.decode("utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InvalidInputError(f"--import-csv {path}: {exc.__class__.__name__}: "
                                f"{getattr(exc, 'strerror', None) or exc}; {accepted}") from None
    reader = csv.DictReader(text.splitlines())
    # A report written before imports existed has no imported_from column; every other is due.
    missing = [c for c in CSV_COLUMNS if c != IMPORTED_FROM and c not in (reader.fieldnames or ())]
    if missing:
        raise InvalidInputError(f"--import-csv {path}: no column {', '.join(missing)}; {accepted}")
    rows = []
    for number, raw in enumerate(reader, start=2):  # line 1 is the header
        where = f"--import-csv {path} line {number}"
        if None in raw:
            raise InvalidInputError(f"{where}: more values than columns; {accepted}")
        row = {c: _parse(v if v is not None else "", c, where) for c, v in raw.items()}
        for column in ("method", "case", "timestamp"):
            if not row.get(column):
                raise InvalidInputError(f"{where}: empty {column}; {accepted}")
        if row.get("outcome") not in OUTCOMES:
            raise InvalidInputError(f"{where}: outcome={row.get('outcome')!r}; accepted: "
                                    f"{', '.join(OUTCOMES)}")
        if row.get("profile") not in PROFILES:
            raise InvalidInputError(f"{where}: profile={row.get('profile')!r}; accepted: "
                                    f"{', '.join(PROFILES)}")
        try:
            datetime.fromisoformat(row["timestamp"])
        except ValueError:
            raise InvalidInputError(f"{where}: timestamp={row['timestamp']!r}; accepted: ISO "
                                    "8601") from None
        rows.append(row)
    if not rows:
        raise InvalidInputError(f"--import-csv {path}: no rows; {accepted}")
    return rows, f"{Path(path).name} sha256:{hashlib.sha256(data).hexdigest()[:12]}"


def _already_imported(source: str, *, results_path: Path | None, table: str) -> str | None:
    """The run that already imported ``source`` into ``table``, if any."""
    from .. import measurements

    if not measurements.store_path(results_path).exists():
        return None
    hits = measurements._read(  # noqa: SLF001 - the store's read-only reader
        results_path, "SELECT run_id FROM measurements WHERE name = ? AND "
        "json_extract(data, '$.imported_from') = ? LIMIT 1", [table, source])
    return str(hits[0][0]) if hits else None


def _record(rows: Sequence[Mapping[str, Any]], *, run_id: str, table: str,
            results_path: Path | None) -> None:
    from .. import measurements

    # One record per (revision, renderer, device, time, profile): the record carries them.
    groups: dict[tuple, list[dict[str, Any]]] = {}
    for row in rows:
        key = tuple(row.get(c) or "" for c in RECORD_COLUMNS)
        payload = {k: v for k, v in row.items()
                   if k not in RECORD_COLUMNS and k != "partial_run" and v is not None}
        groups.setdefault(key, []).append(payload)
    for (sha, renderer, device, stamp, profile), payloads in groups.items():
        measurements.record(table, payloads, results_path=results_path, run_id=run_id,
                            profile=profile, git_sha=sha, renderer=renderer, device=device,
                            timestamp=stamp)


def import_csv(path: Path, *, results_path: Path | None, table: str | None = None
               ) -> ImportSummary:
    """Store the rows of the stability CSV ``path`` as imported rows of ``table``.

    Every row is read and checked before anything is written; a file already imported into
    this store (same SHA-256) is refused, so an import cannot double its rows.

    Returns
    -------
    ImportSummary
    """
    from .. import measurements
    from .matrix import TABLE

    table = table or TABLE
    rows, source = read_rows(Path(path))
    earlier = _already_imported(source, results_path=results_path, table=table)
    if earlier:
        raise InvalidInputError(f"--import-csv {path}: {source} is already in the store (import "
                                f"run {earlier}); accepted: a CSV not yet imported")
    for row in rows:  # a row imported twice (a re-written report) keeps its first source
        row[IMPORTED_FROM] = row.get(IMPORTED_FROM) or source
    complete = [r for r in rows if not r.get("partial_run")]
    partial = [r for r in rows if r.get("partial_run")]
    complete_run = partial_run = None
    if complete:
        complete_run = measurements.new_run_id()
        _record(complete, run_id=complete_run, table=table, results_path=results_path)
        profiles = sorted({r["profile"] for r in complete})
        for profile in profiles:  # the import run is a complete report run of each profile
            measurements.complete_report("table", table, profile=profile, run_id=complete_run,
                                         members={}, results_path=results_path)
    if partial:
        partial_run = measurements.new_run_id()
        _record(partial, run_id=partial_run, table=table, results_path=results_path)
    return ImportSummary(source=source, complete_run=complete_run, partial_run=partial_run,
                         complete_rows=len(complete), partial_rows=len(partial))
