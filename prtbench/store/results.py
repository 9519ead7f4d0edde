"""The results store: one SQLite row per measured render (DESIGN.md §10).

Tables and figures are generated only from this store. It is a single SQLite file (default
``results/prtbench.sqlite`` under the current directory, ``$PRTBENCH_RESULTS`` overrides) in WAL
mode with a busy timeout, so several sweep processes can append at once; every append is one
transaction, so a failure never leaves half a batch. Dict-valued fields (config, view, metrics)
are stored as strict JSON text (a non-finite metric is ``null``; the row's ``status`` says why);
:func:`load` flattens the metrics into ``metric_<name>`` columns.

Other modules may keep auxiliary tables in the same file: the schema check looks only at
``meta`` and ``renders``. A store written by an older prtbench is migrated on its first append
(schema 2 → 3 adds ``status``, ``status_reason`` and ``precompute_rebuilt`` and rewrites
``NaN``/``Infinity`` tokens as ``null``); read-only queries read it without changing it.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import os
import sqlite3
import subprocess
import time
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

from prtbench.api import strict_json
from prtbench.api.errors import InvalidInputError, PrtbenchError, UnknownNameError
from prtbench.store import schema as store_schema
from prtbench.store.schema import SCHEMA_VERSION

PROFILES = ("smoke", "quick", "paper")
#: ok: a measurement; degenerate: measured, but meaningless (black image, empty mask,
#: non-finite masked metric: see status_reason); failed: the measurement did not complete.
STATUSES = ("ok", "degenerate", "failed")
_BUSY_TIMEOUT_S = 60.0
_JSON_FIELDS = ("config", "view_json", "metrics", "scene_params", "frame_components",
                "memory_breakdown")


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
    metrics : dict of str to float or None
        What :func:`prtbench.bench.metrics.compute_metrics` returned; a non-finite value is stored
        (and read back) as None.
    frame_ms, frame_ms_p95 : float or None
        Median and 95th-percentile GPU frame time.
    memory_bytes : int or None
        What the method keeps resident to render.
    precompute_s : float or None
        Wall time of the precompute that built the artifact (a cache hit reports the original
        time; so does a rebuild of a corrupt artifact whose time was recorded).
    renderer, device : str
        GL renderer string and the machine's description.
    load_average : float or None
        The machine's 1-minute load average when the row was measured (the run itself
        counts about 1): a value well above the core count means the frame times were taken
        on a busy machine. None where unknown (rows from before schema 5).
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
        ``timer-query`` (GPU) or ``wall+finish`` (software rasteriser), see prtbench.render.gl.
    status : str
        ``ok``, ``degenerate`` or ``failed`` (:data:`STATUSES`).
    status_reason : str
        Why a row is not ``ok``, and which values were stored as null; empty when there is
        nothing to say.
    precompute_rebuilt : bool
        The artifact was rebuilt because its cache file was corrupt or missing; when its
        original time was recorded ``precompute_s`` is that time, else the rebuild's.
    covered_pixels : int or None
        Pixels of the view covered by geometry (the masked metrics' support); the
        operation-count cost model scales per-pixel work by it.
    scene_vertices : int or None
        Vertex count of the rendered scene (per-vertex work of the cost model).
    workers : int
        How many workers measured concurrently when this row was measured (1 for a plain
        ``prtbench run``): concurrent workers on few cores distort frame times.
    cell_key : str
        The key of the job this row measures (:func:`prtbench.bench.submit.job_key`).
    reference_bounces : int or None
        Interreflection bounces of the path reference (None: a method reference, or unknown).
    panel : str
        Which rows may be ranked together (docs/PROTOCOL.md): scene, variant, light,
        resolution, the view set and the reference (kind, bounces, spp).
    light_class : str
        ``relight`` (any light), ``family`` (lights of a declared family) or ``fixed`` (one
        baked light), for this config (:meth:`prtbench.api.method.Method.light_class_of`).
    split : str
        ``held-out`` (the light and view were never trained or fitted on), ``in-family``
        (the light is of the family the method fitted) or ``trained``.
    psnr_masked_lo, psnr_masked_hi, flip_masked_lo, flip_masked_hi : float or None
        The 95 % interval of the masked metric allowed by the reference's Monte Carlo noise
        (:func:`prtbench.bench.intervals.metric_interval`).
    frame_components : dict of str to float
        Milliseconds of each part of the frame (GPU draw, CPU relighting, readback, network,
        ...), medians over the timed frames.
    memory_breakdown : dict of str to int
        Bytes of each resident part (:meth:`prtbench.api.method.Renderer.memory_breakdown`);
        they sum to ``memory_bytes``.
    light_change_ms : float or None
        The work a new light costs before its first frame (SH projection, per-light matrices,
        cubemap resampling, ...), timed from scratch; None where the method does none.
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
    status: str = "ok"
    status_reason: str = ""
    precompute_rebuilt: bool = False
    covered_pixels: int | None = None
    scene_vertices: int | None = None
    workers: int = 1
    cell_key: str = ""
    load_average: float | None = None
    reference_bounces: int | None = None
    panel: str = ""
    light_class: str = ""
    split: str = ""
    psnr_masked_lo: float | None = None
    psnr_masked_hi: float | None = None
    flip_masked_lo: float | None = None
    flip_masked_hi: float | None = None
    frame_components: dict = field(default_factory=dict)
    memory_breakdown: dict = field(default_factory=dict)
    light_change_ms: float | None = None

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
        if self.status not in STATUSES:
            raise UnknownNameError("result status", self.status, STATUSES)
        self.status_reason = self.status_reason or ""
        self.precompute_rebuilt = bool(self.precompute_rebuilt)  # SQLite gives 0/1
        self.workers = int(self.workers) if self.workers is not None else 1
        self.cell_key = self.cell_key or ""


_SQL_TYPES = {"view": "INTEGER", "width": "INTEGER", "height": "INTEGER", "memory_bytes": "INTEGER",
              "reference_spp": "INTEGER", "scene_triangles": "INTEGER", "frame_ms": "REAL", "frame_ms_p95": "REAL",
              "precompute_s": "REAL", "reference_noise": "REAL", "precompute_rebuilt": "INTEGER",
              "covered_pixels": "INTEGER", "scene_vertices": "INTEGER", "workers": "INTEGER"}
COLUMNS = tuple(f.name for f in dataclasses.fields(ResultRow))


def _to_json(value) -> str:
    return strict_json.dumps(value, sort_keys=True)


def _column_sql(name: str) -> str:
    if name in store_schema.ADDED_COLUMNS:
        return f"{name} {store_schema.ADDED_COLUMNS[name]}"
    return f"{name} {_SQL_TYPES.get(name, 'TEXT')}" + (" NOT NULL" if name in ("method", "scene") else "")


def default_path() -> Path:
    """``$PRTBENCH_RESULTS`` or ``results/prtbench.sqlite`` under the current directory."""
    return Path(os.environ.get("PRTBENCH_RESULTS") or Path.cwd() / "results" / "prtbench.sqlite")


class ResultsStore:
    """An SQLite results file, safe for concurrent appending processes.

    Parameters
    ----------
    path : str or Path, optional
        Default :func:`default_path`. Created (with its folder) on first append.
    readonly : bool
        Never create, migrate or write: a missing file or folder is an error, and a store of
        an older schema is read as it is (``prtbench results``).
    """

    def __init__(self, path: str | Path | None = None, *, readonly: bool = False):
        self.path = Path(path) if path is not None else default_path()
        self.readonly = readonly
        self._schema_checked = False
        self._columns: tuple[str, ...] = COLUMNS

    def _connect(self) -> sqlite3.Connection:
        if self.path.is_dir():
            raise InvalidInputError(f"results store '{self.path}' is a folder; accepted: an SQLite "
                                    f"file path (e.g. {self.path / 'prtbench.sqlite'})")
        store_schema.check_header(self.path)
        if self.readonly:
            if not self.path.is_file():
                raise PrtbenchError(f"no results store at '{self.path}'; `prtbench run` fills it")
            # A read-only connection to a WAL file creates its -wal/-shm files (and cannot open
            # it at all in a read-only folder). With no -wal file there is no writer and no
            # uncheckpointed data, so open it immutable: nothing is created. Otherwise the
            # files exist already and a plain read-only connection sees the writers' data.
            wal = self.path.with_name(self.path.name + "-wal").exists()
            target = f"{self.path.resolve().as_uri()}?mode=ro{'' if wal else '&immutable=1'}"
            options = {"uri": True}
        else:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            target, options = self.path, {}
        # Autocommit mode: transactions are explicit BEGIN IMMEDIATE ... COMMIT below.
        conn = sqlite3.connect(target, timeout=_BUSY_TIMEOUT_S, isolation_level=None, **options)
        try:
            conn.execute(f"PRAGMA busy_timeout = {int(_BUSY_TIMEOUT_S * 1000)}")
            if not self._schema_checked:
                if self.readonly:
                    self._columns = self._read_schema(conn)
                else:
                    self._ensure_schema(conn)
                self._schema_checked = True
        except sqlite3.DatabaseError as exc:
            conn.close()
            raise InvalidInputError(f"results store '{self.path}' is not a usable SQLite file: {exc}") from None
        except BaseException:
            conn.close()
            raise
        return conn

    def check(self) -> None:
        """Raise a PrtbenchError unless the store is absent or an SQLite file of our schema.

        Writes nothing (the file is opened read-only), so :func:`prtbench.bench.runner.prepare` can
        call it before any work; a store of an older schema passes (it is migrated on append).
        """
        if self.path.is_dir() or self.path.exists():
            ResultsStore(self.path, readonly=True)._connect().close()

    def _read_schema(self, conn: sqlite3.Connection) -> tuple[str, ...]:
        version = store_schema.stored_version(conn, self.path)
        if version is None:
            return COLUMNS  # an empty file: no rows
        return store_schema.render_columns(conn, self.path, version=version, columns=COLUMNS)

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
        columns = ", ".join(_column_sql(name) for name in COLUMNS)
        conn.execute("BEGIN IMMEDIATE")  # outside the try: a failed BEGIN has nothing to roll back
        try:
            version = store_schema.stored_version(conn, self.path)
            conn.execute("CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL)")
            conn.execute(f"CREATE TABLE IF NOT EXISTS renders (id INTEGER PRIMARY KEY AUTOINCREMENT, {columns})")
            conn.execute("CREATE INDEX IF NOT EXISTS renders_by_name ON renders (method, scene, profile)")
            conn.execute("CREATE INDEX IF NOT EXISTS renders_by_run ON renders (run_id)")
            if version is None:
                conn.execute("INSERT INTO meta VALUES ('schema_version', ?)", (str(SCHEMA_VERSION),))
            else:
                store_schema.render_columns(conn, self.path, version=version, columns=COLUMNS)
                if version != SCHEMA_VERSION:
                    store_schema.migrate(conn, json_fields=_JSON_FIELDS, to_json=_to_json)
            conn.execute("COMMIT")
        except BaseException:
            conn.execute("ROLLBACK")
            raise

    def append(self, rows: Sequence[ResultRow]) -> None:
        """Insert ``rows`` in one transaction: all of them or, on any error, none."""
        if self.readonly:
            raise PrtbenchError(f"results store '{self.path}' was opened read-only")
        rows = list(rows)
        if not rows:
            return
        values = [_row_values(row, number) for number, row in enumerate(rows)]  # before connecting
        insert = (f"INSERT INTO renders ({', '.join(COLUMNS)}) "
                  f"VALUES ({', '.join('?' for _ in COLUMNS)})")
        with self.transaction() as conn:
            for value in values:
                conn.execute(insert, value)

    @contextlib.contextmanager
    def transaction(self) -> Iterator[sqlite3.Connection]:
        """One ``BEGIN IMMEDIATE`` ... ``COMMIT`` on this store: all statements or, on any error, none.

        The connection has WAL, the busy timeout and a checked ``renders`` schema; other tables
        (the measurement tables of :mod:`prtbench.store.measurements`) share the file and the lock.
        """
        if self.readonly:
            raise PrtbenchError(f"results store '{self.path}' was opened read-only")
        conn = self._connect()
        try:
            conn.execute("BEGIN IMMEDIATE")  # outside the try: a failed BEGIN has nothing to roll back
            try:
                yield conn
                conn.execute("COMMIT")
            except BaseException:
                conn.execute("ROLLBACK")
                raise
        finally:
            conn.close()

    def query(self, *, method: str | None = None, scene: str | None = None,
              profile: str | None = None, run_id: str | None = None,
              status: str | None = None) -> list[ResultRow]:
        """Rows matching every given filter, in insertion order."""
        if status is not None and status not in STATUSES:
            raise UnknownNameError("result status", status, STATUSES)
        conn = self._connect()
        try:
            columns = self._columns
            filters = {"method": method, "scene": scene, "profile": profile, "run_id": run_id,
                       "status": status}
            where = [(f"{name} = ?", value) for name, value in filters.items() if value is not None]
            if status is not None and "status" not in columns:  # an unmigrated store: all 'ok'
                if status != "ok":
                    return []
                where = [w for w in where if not w[0].startswith("status")]
            sql = f"SELECT {', '.join(columns)} FROM renders"
            if where:
                sql += " WHERE " + " AND ".join(clause for clause, _ in where)
            if not conn.execute("SELECT 1 FROM sqlite_master WHERE name = 'renders'").fetchone():
                return []  # an empty file opened read-only
            records = conn.execute(sql + " ORDER BY id", [value for _, value in where]).fetchall()
        finally:
            conn.close()
        return [ResultRow(**dict(zip(columns, record))) for record in records]

    def count(self) -> int:
        """Number of stored rows."""
        conn = self._connect()
        try:
            if not conn.execute("SELECT 1 FROM sqlite_master WHERE name = 'renders'").fetchone():
                return 0
            return conn.execute("SELECT COUNT(*) FROM renders").fetchone()[0]
        finally:
            conn.close()


def _row_values(row: ResultRow, number: int) -> tuple:
    if not isinstance(row, ResultRow):
        raise InvalidInputError(f"results row {number} is a {type(row).__name__}; accepted: ResultRow")
    values = []
    # A non-finite metric is written as null; keep what it was (nan or ±inf) in the reason.
    null_metrics = strict_json.non_finite_keys(row.metrics) if isinstance(row.metrics, Mapping) else []
    for name in COLUMNS:
        value = getattr(row, name)
        if name == "status_reason" and null_metrics and not value:
            value = f"{', '.join(null_metrics)} stored as null"
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
    wherever the command runs. Untracked files do not count (like ``git describe --dirty``),
    nor do the generated reports under ``reports/``: a table written by one command must not
    mark the next command's rows as measured on modified code.
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
    status = git("status", "--porcelain", "--untracked-files=no", "--", ":(top)",
                 ":(top,exclude)reports")
    return f"{sha}+dirty" if status else sha
