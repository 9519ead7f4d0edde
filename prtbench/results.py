"""The results store: one SQLite row per measured render (DESIGN.md §10).

Tables and figures are generated only from this store. It is a single SQLite file (default
``results/prtbench.sqlite`` under the current directory, ``$PRTBENCH_RESULTS`` overrides) in WAL
mode with a busy timeout, so several sweep processes can append at once; every append is one
transaction, so a failure never leaves half a batch. Dict-valued fields (config, view, metrics)
are stored as JSON text; :func:`load` flattens the metrics into ``metric_<name>`` columns.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import sqlite3
import subprocess
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

from .errors import InvalidInputError, PrtbenchError, UnknownNameError

SCHEMA_VERSION = 2
PROFILES = ("smoke", "quick", "paper")
_BUSY_TIMEOUT_S = 60.0
_JSON_FIELDS = ("config", "view_json", "metrics", "scene_params")


def _utc_now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


@dataclass(kw_only=True)
class ResultRow:
    """One measured render.

    Attributes
    ----------
    method, scene : str
        Registry names.
    config : dict
        The method's full config (every knob, defaults included).
    scene_variant, light : str
        Scene variant (e.g. a decimation level) and light name.
    view : int
        Index of the view in the scene; ``view_json`` holds the camera itself.
    width, height : int
        Render resolution in pixels.
    reference_kind : str
        ``"path"`` (Mitsuba) or ``"method:<name>"``.
    metrics : dict of str to float
        What :func:`prtbench.metrics.compute_metrics` returned (inf/NaN allowed).
    frame_ms, frame_ms_p95 : float or None
        Median and 95th-percentile GPU frame time.
    memory_bytes : int or None
        What the method keeps resident to render.
    precompute_s : float or None
        Wall time of the (possibly cached) precompute.
    renderer, device : str
        GL renderer string and the machine's description.
    git_sha : str
        Code version (:func:`git_sha`).
    profile : str
        ``smoke``, ``quick`` or ``paper``.
    run_id : str
        Groups the rows of one sweep.
    timestamp : str
        UTC ISO 8601, set at creation.
    reference_spp : int or None
        Samples per pixel of the reference; ``reference_noise`` its own display-space noise RMSE.
    scene_triangles : int or None
        Triangle count of the rendered scene (tessellation sweeps group by it).
    scene_params : dict
        The scene builder's parameters (e.g. ``ground_subdivisions``).
    timing_source : str
        ``timer-query`` (GPU) or ``wall+finish`` (software rasteriser), see prtbench.gl.
    """

    method: str
    scene: str
    config: dict = field(default_factory=dict)
    scene_variant: str = ""
    light: str = ""
    view: int = 0
    view_json: dict = field(default_factory=dict)
    width: int = 0
    height: int = 0
    reference_kind: str = "path"
    metrics: dict = field(default_factory=dict)
    frame_ms: float | None = None
    frame_ms_p95: float | None = None
    memory_bytes: int | None = None
    precompute_s: float | None = None
    renderer: str = ""
    device: str = ""
    git_sha: str = ""
    profile: str = "quick"
    run_id: str = ""
    timestamp: str = field(default_factory=_utc_now)
    reference_spp: int | None = None
    reference_noise: float | None = None
    scene_triangles: int | None = None
    scene_params: dict = field(default_factory=dict)
    timing_source: str = ""

    def __post_init__(self) -> None:
        for name in _JSON_FIELDS:  # rows read back from text, or built by hand from JSON
            value = getattr(self, name)
            if isinstance(value, str):
                setattr(self, name, json.loads(value) if value else {})
        kind = self.reference_kind
        if kind != "path" and not (kind.startswith("method:") and len(kind) > len("method:")):
            raise InvalidInputError(f"reference_kind '{kind}'; accepted: 'path' or 'method:<name>'")
        if self.profile not in PROFILES:
            raise UnknownNameError("profile", self.profile, PROFILES)


_SQL_TYPES = {"view": "INTEGER", "width": "INTEGER", "height": "INTEGER", "memory_bytes": "INTEGER",
              "reference_spp": "INTEGER", "scene_triangles": "INTEGER", "frame_ms": "REAL", "frame_ms_p95": "REAL",
              "precompute_s": "REAL", "reference_noise": "REAL"}
COLUMNS = tuple(f.name for f in dataclasses.fields(ResultRow))


def _json_default(value):
    import numpy as np  # only reached for numpy values, which imply numpy is loaded

    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} is not JSON-serialisable")


def _to_json(value) -> str:
    return json.dumps(value, sort_keys=True, default=_json_default)


def default_path() -> Path:
    """``$PRTBENCH_RESULTS`` or ``results/prtbench.sqlite`` under the current directory."""
    return Path(os.environ.get("PRTBENCH_RESULTS") or Path.cwd() / "results" / "prtbench.sqlite")


class ResultsStore:
    """An SQLite results file, safe for concurrent appending processes.

    Parameters
    ----------
    path : str or Path, optional
        Default :func:`default_path`. Created (with its folder) on first use.
    """

    def __init__(self, path: str | Path | None = None):
        self.path = Path(path) if path is not None else default_path()
        self._schema_checked = False

    def _connect(self) -> sqlite3.Connection:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        # Autocommit mode: transactions are explicit BEGIN IMMEDIATE ... COMMIT below.
        conn = sqlite3.connect(self.path, timeout=_BUSY_TIMEOUT_S, isolation_level=None)
        try:
            conn.execute(f"PRAGMA busy_timeout = {int(_BUSY_TIMEOUT_S * 1000)}")
            if not self._schema_checked:
                self._ensure_schema(conn)
                self._schema_checked = True
        except sqlite3.DatabaseError as exc:
            conn.close()
            raise InvalidInputError(f"results store '{self.path}' is not a usable SQLite file: {exc}") from None
        except BaseException:
            conn.close()
            raise
        return conn

    def _ensure_schema(self, conn: sqlite3.Connection) -> None:
        # The busy timeout does not cover every lock met here: switching a new file to WAL
        # while another process opens it fails at once with "database is locked" (seen in 5
        # of 40 races of 8 processes on a new file). The setup is idempotent, so retry it.
        deadline = time.monotonic() + _BUSY_TIMEOUT_S
        delay = 0.005
        while True:
            try:
                return self._create_schema(conn)
            except sqlite3.OperationalError as exc:
                if "locked" not in str(exc) or time.monotonic() > deadline:
                    raise
                time.sleep(delay)
                delay = min(2.0 * delay, 0.25)

    def _create_schema(self, conn: sqlite3.Connection) -> None:
        if conn.execute("PRAGMA journal_mode").fetchone()[0].lower() != "wal":
            conn.execute("PRAGMA journal_mode = WAL")  # persistent: readers never block writers
        columns = ", ".join(
            f"{name} {_SQL_TYPES.get(name, 'TEXT')}" + (" NOT NULL" if name in ("method", "scene") else "")
            for name in COLUMNS)
        conn.execute("BEGIN IMMEDIATE")  # outside the try: a failed BEGIN has nothing to roll back
        try:
            conn.execute("CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL)")
            conn.execute(f"CREATE TABLE IF NOT EXISTS renders (id INTEGER PRIMARY KEY AUTOINCREMENT, {columns})")
            conn.execute("CREATE INDEX IF NOT EXISTS renders_by_name ON renders (method, scene, profile)")
            conn.execute("CREATE INDEX IF NOT EXISTS renders_by_run ON renders (run_id)")
            conn.execute("INSERT OR IGNORE INTO meta VALUES ('schema_version', ?)", (str(SCHEMA_VERSION),))
            version = conn.execute("SELECT value FROM meta WHERE key = 'schema_version'").fetchone()[0]
            conn.execute("COMMIT")
        except BaseException:
            conn.execute("ROLLBACK")
            raise
        if int(version) != SCHEMA_VERSION:
            raise PrtbenchError(f"results store '{self.path}' has schema version {version}; this prtbench "
                                f"reads version {SCHEMA_VERSION} (move the file aside or use --results)")

    def append(self, rows: Sequence[ResultRow]) -> None:
        """Insert ``rows`` in one transaction: all of them or, on any error, none."""
        rows = list(rows)
        if not rows:
            return
        insert = (f"INSERT INTO renders ({', '.join(COLUMNS)}) "
                  f"VALUES ({', '.join('?' for _ in COLUMNS)})")
        conn = self._connect()
        try:
            conn.execute("BEGIN IMMEDIATE")
            try:
                for number, row in enumerate(rows):
                    conn.execute(insert, _row_values(row, number))
                conn.execute("COMMIT")
            except BaseException:
                conn.execute("ROLLBACK")
                raise
        finally:
            conn.close()

    def query(self, *, method: str | None = None, scene: str | None = None,
              profile: str | None = None, run_id: str | None = None) -> list[ResultRow]:
        """Rows matching every given filter, in insertion order."""
        filters = {"method": method, "scene": scene, "profile": profile, "run_id": run_id}
        where = [(f"{name} = ?", value) for name, value in filters.items() if value is not None]
        sql = f"SELECT {', '.join(COLUMNS)} FROM renders"
        if where:
            sql += " WHERE " + " AND ".join(clause for clause, _ in where)
        conn = self._connect()
        try:
            records = conn.execute(sql + " ORDER BY id", [value for _, value in where]).fetchall()
        finally:
            conn.close()
        return [ResultRow(**dict(zip(COLUMNS, record))) for record in records]

    def count(self) -> int:
        """Number of stored rows."""
        conn = self._connect()
        try:
            return conn.execute("SELECT COUNT(*) FROM renders").fetchone()[0]
        finally:
            conn.close()


def _row_values(row: ResultRow, number: int) -> tuple:
    if not isinstance(row, ResultRow):
        raise InvalidInputError(f"results row {number} is a {type(row).__name__}; accepted: ResultRow")
    values = []
    for name in COLUMNS:
        value = getattr(row, name)
        if name in _JSON_FIELDS:
            try:
                value = _to_json(value)
            except (TypeError, ValueError) as exc:
                raise InvalidInputError(f"results row {number}: {name} is not JSON-serialisable ({exc})") from None
        elif value is not None and name in _SQL_TYPES:
            value = int(value) if _SQL_TYPES[name] == "INTEGER" else float(value)
        values.append(value)
    return tuple(values)


def load(path: str | Path | None = None, **filters):
    """The store as a pandas DataFrame, one row per render.

    ``config``, ``view_json`` and ``metrics`` are JSON text columns; every metric is also a
    float column ``metric_<name>`` (NaN where a row lacks it). ``filters`` are those of
    :meth:`ResultsStore.query`.
    """
    import pandas as pd

    rows = ResultsStore(path).query(**filters)
    records = []
    for row in rows:
        record = dataclasses.asdict(row)
        for name in _JSON_FIELDS:
            record[name] = _to_json(record[name])
        for key, value in row.metrics.items():
            record[f"metric_{key}"] = float(value) if value is not None else math.nan
        records.append(record)
    frame = pd.DataFrame.from_records(records, columns=None if records else list(COLUMNS))
    return frame


def git_sha(cwd: str | Path | None = None) -> str:
    """The commit of the source tree, ``+dirty`` if tracked files changed; ``unknown`` outside git.

    ``cwd`` defaults to this package's folder, so results record the code that produced them
    wherever the command runs. Untracked files do not count (like ``git describe --dirty``).
    """
    cwd = Path(cwd) if cwd is not None else Path(__file__).resolve().parent

    def git(*args: str) -> str | None:
        try:
            done = subprocess.run(["git", *args], cwd=cwd, capture_output=True, text=True, timeout=20)
        except (OSError, subprocess.SubprocessError):
            return None
        return done.stdout.strip() if done.returncode == 0 else None

    sha = git("rev-parse", "HEAD")
    if not sha:
        return "unknown"
    status = git("status", "--porcelain", "--untracked-files=no")
    return f"{sha}+dirty" if status else sha


DEFAULT_COLUMNS = ("method", "scene", "light", "view", "size", "profile", "psnr", "psnr_masked",
                   "ssim_masked", "flip_masked", "frame_ms", "memory_bytes")


def _format_value(value) -> str:
    if value is None:
        return "-"
    if isinstance(value, bool) or isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return f"{value:.0f}" if abs(value) >= 1e5 else f"{value:.4g}"
    if isinstance(value, Mapping):
        return _to_json(value)
    return str(value)


def format_rows(rows: Sequence[ResultRow], *, columns: Sequence[str] | None = None) -> str:
    """A plain-text table of ``rows`` for ``prtbench results``.

    ``columns`` name row fields, ``size`` (``WxH``) or metric keys (``psnr``, ``ssim_masked``);
    a metric a row lacks prints ``-``. Numbers are right-aligned; inf prints as ``inf``.
    """
    columns = list(columns or DEFAULT_COLUMNS)
    metric_keys = {key for row in rows for key in row.metrics}
    known = set(COLUMNS) | {"size"} | metric_keys | set(DEFAULT_COLUMNS)
    for column in columns:
        if column not in known:
            raise UnknownNameError("results column", column, known)
    if not rows:
        return "(no results)"

    def cell(row: ResultRow, column: str):
        if column == "size":
            return f"{row.width}x{row.height}"
        if column in COLUMNS:
            return getattr(row, column)
        value = row.metrics.get(column)
        return float(value) if value is not None else None

    raw = [[cell(row, column) for column in columns] for row in rows]
    numeric = [all(isinstance(r[i], (int, float)) or r[i] is None for r in raw) for i in range(len(columns))]
    text = [[_format_value(v) for v in r] for r in raw]
    widths = [max(len(columns[i]), *(len(r[i]) for r in text)) for i in range(len(columns))]

    def line(cells: Sequence[str]) -> str:
        return "  ".join(c.rjust(w) if num else c.ljust(w)
                         for c, w, num in zip(cells, widths, numeric)).rstrip()

    return "\n".join([line(columns), line(["-" * w for w in widths]), *(line(r) for r in text)])
