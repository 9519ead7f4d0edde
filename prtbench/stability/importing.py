"""Rows of a written stability CSV back into a results store (``stability --import-csv``).

The committed ``reports/table-stability.csv`` holds every number its report prints, but the
results store it was written from is not committed: when that store is gone, cases measured
later cannot join the earlier ones in one report (``--from-store`` reads the store only).
Importing the CSV carries its rows over unchanged, each keeping the revision, device,
renderer, load and timestamp of the run that measured it, and marked ``imported_from`` (the
name and SHA-256 of the file it first came from) so that the report can say which rows it did
not measure itself. Values keep their type: the importer parses each column by its declared
kind (text, flag, number; integers stay integers), never by guessing from the value.

A row already in the store (the same method, case, revision, time and render run) is not
stored again, so importing a report into the store it was written from, or a report that an
import rewrote, adds nothing; a file with no new row is refused. Rows of interrupted runs
(``partial_run`` True) go into an import run that is never completed, so they count only with
``--partial``, as they did before. A later measurement of a case wins by its timestamp, and a
measured row wins a tie (:func:`prtbench.stability.matrix.stored_rows`). Everything is checked
before the one transaction that stores it.
"""

from __future__ import annotations

import csv
import hashlib
import io
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from prtbench.api.errors import InvalidInputError
from prtbench.stability.case import PROFILES
from prtbench.stability.matrix import TABLE, stored_runs
from prtbench.stability.outcome import OUTCOMES
from prtbench.stability.report import CSV_COLUMNS, IMPORTED_FROM
from prtbench.store import measurements
from prtbench.store.measurements import Batch

#: Columns holding text (never parsed as numbers: a run id may be all digits).
TEXT_COLUMNS = frozenset({
    "method", "case", "group", "outcome", "reason", "scene", "variant", "storage_dtype",
    "status", "run_id", "git_sha", "profile", "renderer", "device", "advice", "note",
    "timestamp", IMPORTED_FROM})
#: Columns holding ``True``/``False``.
FLAG_COLUMNS = frozenset({"precompute_cached", "partial_run"})
#: Columns that belong to the stored record rather than to its payload.
RECORD_COLUMNS = ("git_sha", "renderer", "device", "timestamp", "profile")
#: What identifies one measurement of a case (a row imported twice has the same).
IDENTITY = ("method", "case", "git_sha", "timestamp", "run_id")
#: The store's timestamp format (:func:`prtbench.store.measurements._utc_now`): UTC, seconds. Rows
#: are ordered by comparing these strings, so no other form may enter.
TIMESTAMP = re.compile(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\+00:00")
_ACCEPTED = "accepted: a table-stability CSV written by prtbench stability"


@dataclass(frozen=True)
class ImportSummary:
    """What :func:`import_csv` stored.

    Attributes
    ----------
    source : str
        ``"<file name> sha256:<12 hex>"``.
    complete_run, partial_run : str or None
        The import runs (complete; of interrupted runs' rows), None where no row went there.
    complete_rows, partial_rows, skipped_rows : int
        Rows stored in each run, and rows already in the store (not stored again).
    profile : str
    """

    source: str
    complete_run: str | None
    partial_run: str | None
    complete_rows: int
    partial_rows: int
    skipped_rows: int
    profile: str


def _parse(value: str, column: str, where: str) -> Any:
    """``value`` of ``column`` as its kind: text, a flag, an int, a float, or None if empty."""
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


def _check_row(row: Mapping[str, Any], where: str) -> None:
    for column in ("method", "case", "timestamp"):
        if not row.get(column):
            raise InvalidInputError(f"{where}: empty {column}; {_ACCEPTED}")
    if row.get("outcome") not in OUTCOMES:
        raise InvalidInputError(f"{where}: outcome={row.get('outcome')!r}; accepted: "
                                f"{', '.join(OUTCOMES)}")
    if row.get("profile") not in PROFILES:
        raise InvalidInputError(f"{where}: profile={row.get('profile')!r}; accepted: "
                                f"{', '.join(PROFILES)}")
    stamp = row["timestamp"]
    if not TIMESTAMP.fullmatch(stamp):
        raise InvalidInputError(f"{where}: timestamp={stamp!r}; accepted: UTC as the store "
                                "writes it, e.g. 2026-12-02T02:39:51+00:00")
    try:
        when = datetime.fromisoformat(stamp)
    except ValueError:
        raise InvalidInputError(f"{where}: timestamp={stamp!r} is no date; accepted: UTC as "
                                "the store writes it") from None
    if when > datetime.now(timezone.utc):  # it would outrank every later measurement
        raise InvalidInputError(f"{where}: timestamp={stamp!r} is in the future; accepted: "
                                "times up to now")


def read_rows(path: Path) -> tuple[list[dict[str, Any]], str]:
    """The typed rows of a stability CSV and its source tag ``"<name> sha256:<12 hex>"``.

    Parameters
    ----------
    path : Path
        A ``table-stability*.csv`` that ``prtbench stability`` wrote.

    Returns
    -------
    rows : list of dict
        One per CSV row, each value parsed by its column's kind (empty cells: None).
    source : str

    Raises
    ------
    InvalidInputError
        A missing or unreadable file, a missing or unknown column, no rows, more than one
        profile, or a value that is not of its column's kind (naming the line, the column and
        the value).
    """
    try:
        data = Path(path).read_bytes()
        text = data.decode("utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InvalidInputError(f"--import-csv {path}: {exc.__class__.__name__}: "
                                f"{getattr(exc, 'strerror', None) or exc}; {_ACCEPTED}") from None
    reader = csv.DictReader(io.StringIO(text, newline=""))
    header = reader.fieldnames or ()
    # A report written before imports existed has no imported_from column; every other is due.
    missing = [c for c in CSV_COLUMNS if c != IMPORTED_FROM and c not in header]
    unknown = [c for c in header if c not in CSV_COLUMNS]
    if missing or unknown:
        problem = (f"no column {', '.join(missing)}" if missing else
                   f"unknown column {', '.join(unknown)}")
        raise InvalidInputError(f"--import-csv {path}: {problem}; {_ACCEPTED}")
    rows = []
    for raw in reader:
        where = f"--import-csv {path} line {reader.line_num}"
        if None in raw:
            raise InvalidInputError(f"{where}: more values than columns; {_ACCEPTED}")
        row = {c: _parse(v if v is not None else "", c, where) for c, v in raw.items()}
        _check_row(row, where)
        rows.append(row)
    if not rows:
        raise InvalidInputError(f"--import-csv {path}: no rows; {_ACCEPTED}")
    profiles = sorted({r["profile"] for r in rows})
    if len(profiles) > 1:  # a stability report is one profile's; so is its import run
        raise InvalidInputError(f"--import-csv {path}: rows of profiles {', '.join(profiles)}; "
                                "accepted: one profile per file")
    return rows, f"{Path(path).name} sha256:{hashlib.sha256(data).hexdigest()[:12]}"


def _identity(row: Mapping[str, Any]) -> tuple[str, ...]:
    return tuple(str(row.get(k) or "") for k in IDENTITY)


def _stored_identities(*, results_path: Path | None, table: str) -> set[tuple[str, ...]]:
    """The :data:`IDENTITY` of every row of ``table`` in the store."""

    frame = measurements.load(table, results_path=results_path)
    return {_identity(r) for r in frame.to_dict(orient="records")}


def _batches(rows: Sequence[Mapping[str, Any]], run_id: str) -> list:
    """The rows as :class:`prtbench.store.measurements.Batch` es of ``run_id``, one per distinct
    (revision, renderer, device, time, profile): the stored record carries those."""

    groups: dict[tuple, list[dict[str, Any]]] = {}
    for row in rows:
        key = tuple(row.get(c) or "" for c in RECORD_COLUMNS)
        payload = {k: v for k, v in row.items()
                   if k not in RECORD_COLUMNS and k != "partial_run" and v is not None}
        groups.setdefault(key, []).append(payload)
    return [Batch(run_id=run_id, profile=profile, git_sha=sha, renderer=renderer, device=device,
                  timestamp=stamp, rows=payloads)
            for (sha, renderer, device, stamp, profile), payloads in groups.items()]


def import_csv(path: Path, *, results_path: Path | None, table: str | None = None,
               profile: str | None = None, need_complete_run: bool = False) -> ImportSummary:
    """Store the rows of the stability CSV ``path`` as imported rows of ``table``.

    Parameters
    ----------
    path : Path
    results_path : Path or None
        The results store (None: the default one).
    table : str, optional
        The measurement table (default :data:`prtbench.stability.matrix.TABLE`).
    profile : str, optional
        The profile the rows must have (``--profile`` when the report is rebuilt next).
    need_complete_run : bool
        Refuse an import after which the store would hold no complete run of the rows'
        profile (``--from-store`` without ``--partial`` would then have no rows to report).

    Returns
    -------
    ImportSummary

    Raises
    ------
    InvalidInputError
        A bad file (:func:`read_rows`), rows of another profile than ``profile``, no row
        that the store does not already hold, or (``need_complete_run``) no complete run;
        nothing is written then.
    """

    table = table or TABLE
    rows, source = read_rows(Path(path))
    found = rows[0]["profile"]
    if profile is not None and found != profile:
        raise InvalidInputError(f"--import-csv {path}: rows of profile {found!r} with --profile "
                                f"{profile!r}; accepted: --profile {found}")
    stored = _stored_identities(results_path=results_path, table=table)
    new = [r for r in rows if _identity(r) not in stored]
    if not new:
        raise InvalidInputError(f"--import-csv {path}: all {len(rows)} rows of {source} are "
                                "already in the store; accepted: a CSV with rows not yet stored")
    for row in new:  # a row imported twice (a rewritten report) keeps its first source
        row[IMPORTED_FROM] = row.get(IMPORTED_FROM) or source
    complete = [r for r in new if not r.get("partial_run")]
    partial = [r for r in new if r.get("partial_run")]
    if need_complete_run and not complete and not stored_runs(
            profile=found, results_path=results_path, table=table)[0]:
        raise InvalidInputError(f"--import-csv {path}: only rows of interrupted runs and no "
                                f"complete {found} run in the store; accepted: --partial")
    complete_run = measurements.new_run_id() if complete else None
    partial_run = measurements.new_run_id() if partial else None
    batches = [*(_batches(complete, complete_run) if complete else []),
               *(_batches(partial, partial_run) if partial else [])]
    measurements.record_batches(table, batches, results_path=results_path,
                                completed=[(complete_run, found)] if complete else [])
    return ImportSummary(source=source, complete_run=complete_run, partial_run=partial_run,
                         complete_rows=len(complete), partial_rows=len(partial),
                         skipped_rows=len(rows) - len(new), profile=found)
