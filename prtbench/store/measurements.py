"""Named auxiliary measurement tables and report runs, in the results store (DESIGN.md §10, §11).

A reproduction prints numbers the runner's ``renders`` rows do not hold (an indirect-only RMSE,
a regressed transfer's error at two points, a leak MAE over some pixels). Those are rows of a
*named measurement table* in the same SQLite file: one JSON object per row (strict JSON:
non-finite floats are written as ``null``), each with the provenance of a render row (git sha,
profile, renderer and device where it is a timing, timestamp, run id). Image panels that a
figure shows beside its numbers are stored losslessly as arrays of the same run.

A *report run* names the rows one regeneration of a table or figure measured: its kind and name,
profile, its own run id (that of its measurement rows) and the runner run ids it used, each
with the cell label the formatter groups by. It is written last, once every row is stored, so a
report run in the store is complete; ``prtbench table|figure NAME --from-store`` rebuilds the
report from the newest one for the profile.

Writes go through :class:`prtbench.store.results.ResultsStore`'s connection (WAL mode, busy timeout,
schema check), each call one transaction. Reads open the file read-only and never create it.
"""

from __future__ import annotations

import io
import json
import math
import sqlite3
import uuid
import zlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np

from prtbench.api.errors import InvalidInputError, PrtbenchError, UnknownNameError
from prtbench.store.results import PROFILES, ResultsStore, default_path
from prtbench.store.results import git_sha as current_sha

_BUSY_TIMEOUT_S = 60.0
REPORT_KINDS = ("table", "figure")
_SCHEMA = (
    "CREATE TABLE IF NOT EXISTS measurements (id INTEGER PRIMARY KEY AUTOINCREMENT, "
    "name TEXT NOT NULL, run_id TEXT NOT NULL, row INTEGER NOT NULL, profile TEXT NOT NULL, "
    "git_sha TEXT NOT NULL, renderer TEXT, device TEXT, timestamp TEXT NOT NULL, "
    "data TEXT NOT NULL)",
    "CREATE INDEX IF NOT EXISTS measurements_by_run ON measurements (name, run_id)",
    "CREATE TABLE IF NOT EXISTS measurement_images (id INTEGER PRIMARY KEY AUTOINCREMENT, "
    "run_id TEXT NOT NULL, key TEXT NOT NULL, data BLOB NOT NULL, UNIQUE (run_id, key))",
    "CREATE TABLE IF NOT EXISTS report_runs (id INTEGER PRIMARY KEY AUTOINCREMENT, "
    "kind TEXT NOT NULL, name TEXT NOT NULL, profile TEXT NOT NULL, run_id TEXT NOT NULL UNIQUE, "
    "git_sha TEXT NOT NULL, timestamp TEXT NOT NULL, members TEXT NOT NULL)",
    "CREATE INDEX IF NOT EXISTS report_runs_by_name ON report_runs (kind, name, profile)",
)


def new_run_id() -> str:
    """A fresh run id (12 hex digits, like the runner's)."""
    return uuid.uuid4().hex[:12]


def _utc_now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def strict(value: Any) -> Any:
    """``value`` as plain JSON data: numpy scalars/arrays to Python, NaN and ±inf to None.

    Raises
    ------
    InvalidInputError
        For values JSON cannot hold (objects, bytes).
    """
    if isinstance(value, Mapping):
        return {str(k): strict(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [strict(v) for v in value]
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, int):
        return int(value)
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if hasattr(value, "tolist"):  # numpy scalar or array
        return strict(value.tolist())
    raise InvalidInputError(f"measurement value {value!r} ({type(value).__name__}); accepted: "
                            "numbers, strings, booleans, None, lists and dicts of them")


def _write(results_path: Path | None, statements) -> None:
    """Run ``statements(conn)`` in one immediate transaction on the store at ``results_path``."""

    with ResultsStore(results_path).transaction() as conn:
        for sql in _SCHEMA:
            conn.execute(sql)
        statements(conn)


def store_path(results_path: str | Path | None) -> Path:
    """``results_path``, or the default results store (:func:`prtbench.store.results.default_path`)."""

    return Path(results_path) if results_path is not None else default_path()


def _read(results_path: str | Path | None, sql: str, params: Sequence[Any] = ()) -> list[tuple]:
    """Rows of a read-only query; [] when the file or the table does not exist (nothing created)."""
    path = store_path(results_path)
    if not path.is_file():
        return []
    try:
        conn = sqlite3.connect(f"{path.resolve().as_uri()}?mode=ro", uri=True,
                               timeout=_BUSY_TIMEOUT_S)
    except sqlite3.Error as exc:
        raise InvalidInputError(f"results store '{path}' cannot be opened: {exc}") from None
    try:
        conn.execute(f"PRAGMA busy_timeout = {int(_BUSY_TIMEOUT_S * 1000)}")
        return conn.execute(sql, list(params)).fetchall()
    except sqlite3.OperationalError as exc:
        if "no such table" in str(exc):
            return []
        raise InvalidInputError(f"results store '{path}' cannot be read: {exc}") from None
    except sqlite3.DatabaseError as exc:
        raise InvalidInputError(f"results store '{path}' is not a usable SQLite file: {exc}") from None
    finally:
        conn.close()


def _encode_image(array) -> bytes:
    buf = io.BytesIO()
    np.save(buf, np.ascontiguousarray(array), allow_pickle=False)
    return zlib.compress(buf.getvalue(), 6)


def _decode_image(blob: bytes):
    return np.load(io.BytesIO(zlib.decompress(blob)), allow_pickle=False)


def record(name: str, rows: Sequence[Mapping[str, Any]], *, results_path: str | Path | None,
           run_id: str, profile: str, git_sha: str | None = None, renderer: str = "",
           device: str = "", images: Mapping[str, Any] | None = None) -> None:
    """Append ``rows`` to measurement table ``name`` (and ``images`` to the run) in one transaction.

    Parameters
    ----------
    name : str
        Table name, e.g. ``"figure-ddprt-8"``.
    rows : sequence of dict
        One JSON object each; NaN/inf are stored as null (:func:`strict`).
    results_path : Path or None
        The results store (None: :func:`prtbench.store.results.default_path`).
    run_id : str
        The report run the rows belong to.
    profile : str
        ``smoke``, ``quick`` or ``paper``.
    git_sha : str, optional
        Default :func:`prtbench.store.results.git_sha` of this source tree.
    renderer, device : str
        GL renderer string and machine, where the rows are timings or GL renders.
    images : dict of str to ndarray, optional
        Panels stored losslessly under ``run_id`` (keys unique within the run).
    """

    _check_profile(profile)
    payloads = [json.dumps(strict(dict(r)), sort_keys=True, allow_nan=False) for r in rows]
    blobs = [(key, _encode_image(value)) for key, value in (images or {}).items()]
    sha = git_sha if git_sha is not None else current_sha()
    stamp = _utc_now()

    def insert(conn: sqlite3.Connection) -> None:
        _insert_rows(conn, name, run_id, payloads, profile=profile, git_sha=sha,
                     renderer=renderer, device=device, timestamp=stamp)
        conn.executemany("INSERT INTO measurement_images (run_id, key, data) VALUES (?, ?, ?)",
                         [(run_id, key, blob) for key, blob in blobs])

    _write(results_path, insert)


def _check_profile(profile: str) -> None:
    if profile not in PROFILES:

        raise UnknownNameError("profile", profile, PROFILES)


def _insert_rows(conn: sqlite3.Connection, name: str, run_id: str, payloads: Sequence[str], *,
                 profile: str, git_sha: str, renderer: str, device: str, timestamp: str) -> None:
    """One measurement row per JSON payload, numbered from 0 within this call."""
    conn.executemany(
        "INSERT INTO measurements (name, run_id, row, profile, git_sha, renderer, device, "
        "timestamp, data) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
        [(name, run_id, i, profile, git_sha, renderer, device, timestamp, p)
         for i, p in enumerate(payloads)])


def _insert_report_run(conn: sqlite3.Connection, kind: str, name: str, *, profile: str,
                       run_id: str, git_sha: str, members: str) -> None:
    conn.execute("INSERT INTO report_runs (kind, name, profile, run_id, git_sha, timestamp, "
                 "members) VALUES (?, ?, ?, ?, ?, ?, ?)",
                 (kind, name, profile, run_id, git_sha, _utc_now(), members))


@dataclass(frozen=True)
class Batch:
    """Rows measured together elsewhere, with the record they came with.

    Attributes
    ----------
    run_id, profile, git_sha, renderer, device : str
        The run the rows join, and what they were measured with.
    timestamp : str
        When they were measured (the store's own format, :func:`_utc_now`).
    rows : sequence of dict
    """

    run_id: str
    profile: str
    git_sha: str
    renderer: str
    device: str
    timestamp: str
    rows: Sequence[Mapping[str, Any]]


def record_batches(name: str, batches: Sequence[Batch], *, results_path: str | Path | None,
                   completed: Sequence[tuple[str, str]] = ()) -> None:
    """Append ``batches`` to measurement table ``name`` and mark the report runs ``completed``
    ((run id, profile) pairs) complete, all in one transaction: a failure stores nothing.

    For rows carried over from an earlier record (:mod:`prtbench.stability.importing`): each
    batch keeps its own revision, renderer, device and time, where :func:`record` stamps now.
    """

    for batch in batches:
        _check_profile(batch.profile)
    encoded = [[json.dumps(strict(dict(r)), sort_keys=True, allow_nan=False) for r in b.rows]
               for b in batches]
    sha = current_sha()

    def insert(conn: sqlite3.Connection) -> None:
        for batch, payloads in zip(batches, encoded):
            _insert_rows(conn, name, batch.run_id, payloads, profile=batch.profile,
                         git_sha=batch.git_sha, renderer=batch.renderer, device=batch.device,
                         timestamp=batch.timestamp)
        for run_id, profile in completed:
            _insert_report_run(conn, "table", name, profile=profile, run_id=run_id,
                               git_sha=sha, members="{}")

    _write(results_path, insert)


def load(name: str, *, run_ids: Sequence[str] | None = None,
         results_path: str | Path | None = None):
    """Measurement table ``name`` as a DataFrame, in insertion order.

    Columns: ``run_id``, ``profile``, ``git_sha``, ``renderer``, ``device``, ``timestamp`` and
    every key of the stored rows (null reads back as None/NaN). Empty if nothing is stored.
    """
    import pandas as pd

    sql = ("SELECT run_id, profile, git_sha, renderer, device, timestamp, data FROM measurements "
           "WHERE name = ?")
    params: list[Any] = [name]
    if run_ids is not None:
        run_ids = list(run_ids)
        if not run_ids:
            return pd.DataFrame(columns=["run_id", "profile", "git_sha", "renderer", "device",
                                         "timestamp"])
        sql += f" AND run_id IN ({', '.join('?' for _ in run_ids)})"
        params += run_ids
    records = []
    for run_id, profile, sha, renderer, device, stamp, data in _read(results_path, sql + " ORDER BY id",
                                                                     params):
        records.append({"run_id": run_id, "profile": profile, "git_sha": sha,
                        "renderer": renderer, "device": device, "timestamp": stamp,
                        **json.loads(data)})
    columns = None if records else ["run_id", "profile", "git_sha", "renderer", "device",
                                    "timestamp"]
    frame = pd.DataFrame.from_records(records, columns=columns)
    _keep_integers(frame, records)
    return frame


def _keep_integers(frame, records: list[dict]) -> None:
    """Integer keys stored in only some rows read back as integers, not floats.

    pandas makes a column float64 when some rows lack its key (NaN for them), so a count such
    as a figure's ``pixels`` would print as 320.0. Such columns become object columns of
    Python ints, NaN where a row has no value: numeric reductions and ``x != x`` NaN tests
    work as before. Columns every row fills are int64 already.
    """

    import pandas as pd

    for column in frame.columns[frame.dtypes == "float64"]:
        present = [r[column] for r in records if r.get(column) is not None]
        if present and all(type(v) is int for v in present):
            frame[column] = pd.Series([r[column] if r.get(column) is not None else math.nan
                                       for r in records], index=frame.index, dtype=object)


def load_images(run_id: str, *, results_path: str | Path | None = None) -> dict[str, Any]:
    """The images stored under ``run_id``: key -> ndarray, in insertion order."""
    return {key: _decode_image(blob) for key, blob in _read(
        results_path, "SELECT key, data FROM measurement_images WHERE run_id = ? ORDER BY id",
        [run_id])}


@dataclass(frozen=True)
class ReportRun:
    """One complete regeneration of a table or figure, as stored.

    Attributes
    ----------
    kind, name, profile : str
    run_id : str
        Run id of its measurement rows and images.
    git_sha, timestamp : str
        Code version and UTC time when it completed.
    members : dict of str to dict
        Runner run id -> the cell label the formatter groups by (``{}`` for a table's own runs).
    results_path : Path
    """

    kind: str
    name: str
    profile: str
    run_id: str
    git_sha: str
    timestamp: str
    members: dict
    results_path: Path


def complete_report(kind: str, name: str, *, profile: str, run_id: str,
                    members: Mapping[str, Mapping[str, Any]], results_path: str | Path | None,
                    git_sha: str | None = None) -> ReportRun:
    """Mark a report run complete (every row stored); returns it as read back."""

    if kind not in REPORT_KINDS:
        raise InvalidInputError(f"report kind '{kind}'; accepted: {', '.join(REPORT_KINDS)}")
    payload = json.dumps(strict({k: dict(v) for k, v in members.items()}), allow_nan=False)
    sha = git_sha if git_sha is not None else current_sha()

    def insert(conn: sqlite3.Connection) -> None:
        _insert_report_run(conn, kind, name, profile=profile, run_id=run_id, git_sha=sha,
                           members=payload)

    _write(results_path, insert)
    report = latest_report(kind, name, profile=profile, results_path=results_path, run_id=run_id)
    assert report is not None  # just committed
    return report


def latest_report(kind: str, name: str, *, profile: str, results_path: str | Path | None = None,
                  run_id: str | None = None) -> ReportRun | None:
    """The newest complete report run of ``kind`` ``name`` for ``profile`` (or ``run_id``), or None."""
    sql = ("SELECT kind, name, profile, run_id, git_sha, timestamp, members FROM report_runs "
           "WHERE kind = ? AND name = ? AND profile = ?")
    params = [kind, name, profile]
    if run_id is not None:
        sql += " AND run_id = ?"
        params.append(run_id)
    found = _read(results_path, sql + " ORDER BY id DESC LIMIT 1", params)
    if not found:
        return None
    kind, name, profile, rid, sha, stamp, members = found[0]
    return ReportRun(kind, name, profile, rid, sha, stamp, json.loads(members),
                     store_path(results_path))


def require_report(kind: str, name: str, *, profile: str,
                   results_path: str | Path | None = None) -> ReportRun:
    """:func:`latest_report`, or a one-line error naming the command that fills the store."""
    report = latest_report(kind, name, profile=profile, results_path=results_path)
    if report is None:
        path = store_path(results_path)
        raise PrtbenchError(
            f"no complete run of {kind} '{name}' for profile '{profile}' in results store "
            f"'{path}'; measure it first with: prtbench {kind} {name} --profile {profile} "
            f"--results {path}")
    return report


def provenance(run_id: str, *, results_path: str | Path | None = None) -> list[dict[str, str]]:
    """The distinct (profile, git_sha, renderer, device) of the measurement rows of ``run_id``.

    What a report run that stored no result rows of its own (a figure of panels) was measured
    with; the comparison site prints it in the page's provenance footer.
    """
    found = _read(results_path, "SELECT DISTINCT profile, git_sha, renderer, device FROM "
                  "measurements WHERE run_id = ?", [run_id])
    return [dict(zip(("profile", "git_sha", "renderer", "device"), r)) for r in found]
