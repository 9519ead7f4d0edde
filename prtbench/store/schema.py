"""The results store's schema: versions, the foreign-file checks and the migrations (2 → … → 6).

:mod:`prtbench.store.results` owns the rows; this module owns what makes an SQLite file *ours*:
a ``meta`` table holding ``schema_version`` and a ``renders`` table with our columns. Other
tables (auxiliary measurement tables of other modules) are allowed and never looked at.
"""

from __future__ import annotations

import json
import sqlite3
from collections.abc import Callable, Sequence
from pathlib import Path

from prtbench.api import strict_json
from prtbench.api.errors import InvalidInputError, PrtbenchError

SCHEMA_VERSION = 6
#: Older schema versions this prtbench reads and migrates.
MIGRATABLE = (2, 3, 4, 5)
#: Columns added after schema 2, with the values old rows get. Schema 3: the status columns;
#: schema 4: what the trade-off needs (covered pixels and vertex count for the operation-count
#: cost model, the sweep's worker count and cell key); schema 5: the machine's load average
#: while timing (old rows: unknown); schema 6: the protocol (docs/PROTOCOL.md): the reference's
#: bounces, the panel, the method's light class and the row's split, the intervals of the
#: masked metrics, the frame's components, the resident memory's parts and the per-light work
#: (old rows: unknown, which rankings treat as not meeting the protocol).
ADDED_COLUMNS = {"status": "TEXT NOT NULL DEFAULT 'ok'",
                 "status_reason": "TEXT NOT NULL DEFAULT ''",
                 "precompute_rebuilt": "INTEGER NOT NULL DEFAULT 0",
                 "covered_pixels": "INTEGER",
                 "scene_vertices": "INTEGER",
                 "workers": "INTEGER NOT NULL DEFAULT 1",
                 "cell_key": "TEXT NOT NULL DEFAULT ''",
                 "load_average": "REAL",
                 "reference_bounces": "INTEGER",
                 "panel": "TEXT NOT NULL DEFAULT ''",
                 "light_class": "TEXT NOT NULL DEFAULT ''",
                 "split": "TEXT NOT NULL DEFAULT ''",
                 "psnr_masked_lo": "REAL",
                 "psnr_masked_hi": "REAL",
                 "flip_masked_lo": "REAL",
                 "flip_masked_hi": "REAL",
                 "frame_components": "TEXT NOT NULL DEFAULT '{}'",
                 "memory_breakdown": "TEXT NOT NULL DEFAULT '{}'",
                 "light_change_ms": "REAL"}
_SQLITE_HEADER = b"SQLite format 3\x00"


def check_header(path: Path) -> None:
    """A non-empty file that is not SQLite is an error: SQLite itself would silently take a
    file shorter than its header for an empty database and overwrite it."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(len(_SQLITE_HEADER))
    except (FileNotFoundError, IsADirectoryError, NotADirectoryError):
        return
    except OSError as exc:
        raise InvalidInputError(f"results store '{path}' cannot be read ({exc.strerror})") from None
    if head and head != _SQLITE_HEADER:
        raise InvalidInputError(f"results store '{path}' is not a usable SQLite file: "
                                f"it does not start with the SQLite header")


def _foreign(path: Path, what: str) -> PrtbenchError:
    return PrtbenchError(f"results store '{path}' is an SQLite file but not a prtbench "
                         f"results store ({what}); use another --results path")


def stored_version(conn: sqlite3.Connection, path: Path) -> int | None:
    """The schema version of the open file, None when it has no tables; raises for a foreign
    database or a version this prtbench cannot read."""
    tables = {r[0] for r in conn.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
    if not tables:
        return None
    if "meta" not in tables:
        raise _foreign(path, f"tables {', '.join(sorted(tables))}, no 'meta'")
    row = conn.execute("SELECT value FROM meta WHERE key = 'schema_version'").fetchone()
    if row is None:
        raise _foreign(path, "its 'meta' table has no schema_version")
    version = int(row[0])
    if version != SCHEMA_VERSION and version not in MIGRATABLE:
        raise PrtbenchError(
            f"results store '{path}' has schema version {version}; this prtbench reads "
            f"versions {', '.join(map(str, (*MIGRATABLE, SCHEMA_VERSION)))} (move the file "
            f"aside or use --results)")
    return version


def render_columns(conn: sqlite3.Connection, path: Path, *, version: int,
                   columns: Sequence[str]) -> tuple[str, ...]:
    """Those of ``columns`` that ``renders`` has; raises if one a schema-``version`` store
    must have is missing."""
    present = {r[1] for r in conn.execute("PRAGMA table_info(renders)")}
    expected = columns if version == SCHEMA_VERSION else [c for c in columns if c not in ADDED_COLUMNS]
    missing = [c for c in expected if c not in present]
    if missing:
        raise _foreign(path, f"table 'renders' lacks {', '.join(missing)}")
    return tuple(c for c in columns if c in present)


def migrate(conn: sqlite3.Connection, *, json_fields: Sequence[str],
            to_json: Callable[[object], str]) -> None:
    """Schema 2, 3, 4 or 5 → 6 inside the caller's transaction.

    Adds the missing columns (old rows 'ok', one worker, no cell key, unknown coverage) and,
    for schema 2, rewrites JSON holding NaN/Infinity tokens as
    strict JSON (``to_json``); a row whose masked metrics were non-finite becomes
    'degenerate', as the runner now flags such rows, and the reason keeps the old values.
    """
    present = {r[1] for r in conn.execute("PRAGMA table_info(renders)")}
    for name, sql in ADDED_COLUMNS.items():
        if name not in present:
            conn.execute(f"ALTER TABLE renders ADD COLUMN {name} {sql}")
    invalid = " OR ".join(f"json_valid({name}) = 0" for name in json_fields)
    for record in conn.execute(f"SELECT id, {', '.join(json_fields)} FROM renders WHERE {invalid}"
                               ).fetchall():
        fields = {name: json.loads(text) if text else {} for name, text in zip(json_fields, record[1:])}
        bad = strict_json.non_finite_keys(fields.get("metrics") or {})
        masked = [b for b in bad if b.split("=")[0].endswith("_masked")]
        status = "degenerate" if masked else "ok"
        reason = (f"migrated from schema 2: {', '.join(masked)} (masked metric not finite)" if masked
                  else f"migrated from schema 2: {', '.join(bad)} stored as null" if bad else "")
        conn.execute(f"UPDATE renders SET {', '.join(f'{n} = ?' for n in json_fields)}, status = ?, "
                     f"status_reason = ? WHERE id = ?",
                     [*(to_json(fields[n]) for n in json_fields), status, reason, record[0]])
    conn.execute("UPDATE meta SET value = ? WHERE key = 'schema_version'", (str(SCHEMA_VERSION),))
