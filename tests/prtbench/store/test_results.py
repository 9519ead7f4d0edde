"""prtbench.store.results: round trips, filters, pandas view, concurrency and atomic batches."""

from __future__ import annotations

import math
import multiprocessing
import sqlite3
import subprocess

import numpy as np
import pytest

from prtbench.api.errors import InvalidInputError, UnknownNameError
from prtbench.store import results, table
from prtbench.store.results import ResultRow, ResultsStore


def _row(**overrides) -> ResultRow:
    fields = dict(method="vertex", scene="plants", config={"sh_bands": 4, "window": "none"},
                  light="studio", view=1, view_json={"eye": [0, 1, 3], "fov_y": 45.0},
                  width=64, height=48, metrics={"psnr": 31.5, "psnr_masked": 27.25, "ssim": 0.93},
                  frame_ms=1.25, frame_ms_p95=1.5, memory_bytes=123456, precompute_s=2.5,
                  renderer="llvmpipe / 4.5", device="cpu", git_sha="abc123", profile="smoke",
                  run_id="run-1", reference_spp=64, reference_noise=0.004)
    fields.update(overrides)
    return ResultRow(**fields)


def _append_rows(path: str, worker: int, count: int) -> None:
    """Spawned writer: one transaction per row, to interleave with the other writers."""
    store = ResultsStore(path)
    for i in range(count):
        store.append([_row(run_id=f"worker-{worker}", view=i, metrics={"psnr": float(i)})])


def test_round_trip_keeps_every_field(tmp_path):
    store = ResultsStore(tmp_path / "r.sqlite")
    rows = [_row(), _row(method="texture", reference_kind="method:vertex", view=2,
                         metrics={"psnr": math.inf, "flip_masked": math.nan, "mae": np.float32(0.25)},
                         frame_ms=None, memory_bytes=np.int64(7))]
    store.append(rows)
    back = store.query()
    assert back[0] == rows[0]
    # Strict JSON: non-finite metrics come back as None, and the reason keeps what they were.
    assert back[1].metrics["psnr"] is None and back[1].metrics["flip_masked"] is None
    assert back[1].status == "ok" and back[1].status_reason == "psnr=inf, flip_masked=nan stored as null"
    assert back[1].metrics["mae"] == 0.25 and back[1].memory_bytes == 7 and back[1].frame_ms is None
    assert back[1].reference_kind == "method:vertex"
    assert store.count() == 2


def test_store_is_wal_with_versioned_schema(tmp_path):
    path = tmp_path / "r.sqlite"
    ResultsStore(path).append([_row()])
    conn = sqlite3.connect(path)
    assert conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    assert conn.execute("SELECT value FROM meta WHERE key='schema_version'").fetchone()[0] == str(
        results.SCHEMA_VERSION)
    conn.execute("UPDATE meta SET value='999' WHERE key='schema_version'")
    conn.commit()
    conn.close()
    with pytest.raises(results.PrtbenchError, match="schema version 999"):
        ResultsStore(path).query()


def test_default_path_follows_env_and_cwd(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("PRTBENCH_RESULTS", raising=False)
    assert results.default_path() == tmp_path / "results" / "prtbench.sqlite"
    monkeypatch.setenv("PRTBENCH_RESULTS", str(tmp_path / "elsewhere.sqlite"))
    ResultsStore().append([_row()])
    assert (tmp_path / "elsewhere.sqlite").is_file()
    assert not (tmp_path / "results").exists()


def test_filters(tmp_path):
    store = ResultsStore(tmp_path / "r.sqlite")
    store.append([_row(method="vertex", scene="plants", profile="smoke", run_id="a"),
                  _row(method="vertex", scene="room", profile="quick", run_id="a"),
                  _row(method="texture", scene="plants", profile="quick", run_id="b")])
    assert [r.scene for r in store.query(method="vertex")] == ["plants", "room"]
    assert [r.method for r in store.query(scene="plants")] == ["vertex", "texture"]
    assert len(store.query(profile="quick", run_id="a")) == 1
    assert store.query(method="vertex", scene="plants", profile="paper") == []


def test_load_flattens_metrics(tmp_path):
    path = tmp_path / "r.sqlite"
    ResultsStore(path).append([_row(), _row(method="texture", metrics={"psnr": math.inf, "flip": 0.1})])
    frame = results.load(path)
    assert len(frame) == 2
    assert list(frame["method"]) == ["vertex", "texture"]
    assert frame["metric_psnr"].iloc[0] == 31.5 and math.isnan(frame["metric_psnr"].iloc[1])  # stored as null
    assert frame["status"].tolist() == ["ok", "ok"]
    assert frame["metric_ssim"].iloc[0] == 0.93 and math.isnan(frame["metric_ssim"].iloc[1])
    assert frame["metric_flip"].iloc[1] == 0.1
    assert frame["frame_ms"].iloc[0] == 1.25 and frame["width"].iloc[0] == 64
    assert isinstance(frame["config"].iloc[0], str)  # JSON text: hashable, groupable
    only = results.load(path, method="texture")
    assert only["method"].tolist() == ["texture"]
    empty = results.load(tmp_path / "empty.sqlite")
    assert len(empty) == 0 and "frame_ms" in empty.columns


def test_concurrent_writers_lose_nothing(tmp_path):
    path = str(tmp_path / "shared.sqlite")
    spawn = multiprocessing.get_context("spawn")
    workers = [spawn.Process(target=_append_rows, args=(path, w, 25)) for w in range(4)]
    for worker in workers:
        worker.start()
    for worker in workers:
        worker.join(timeout=120)
    assert [worker.exitcode for worker in workers] == [0, 0, 0, 0]
    rows = ResultsStore(path).query()
    assert len(rows) == 100
    assert sorted((r.run_id, r.view) for r in rows) == sorted(
        (f"worker-{w}", i) for w in range(4) for i in range(25))


def _open_store(path: str, barrier) -> None:
    barrier.wait()  # all processes open the new file at once
    ResultsStore(path)._connect().close()


def test_processes_racing_to_create_a_store_all_succeed(tmp_path):
    # Switching a new file to WAL fails at once with "database is locked" while another
    # process does the same (the busy timeout does not apply). Without the retry this test
    # failed 3 of 3 runs (a looser race of 8 processes failed 5 times in 40).
    fork = multiprocessing.get_context("fork")
    for trial in range(10):
        path = str(tmp_path / f"race{trial}.sqlite")
        barrier = fork.Barrier(8)
        workers = [fork.Process(target=_open_store, args=(path, barrier)) for _ in range(8)]
        for worker in workers:
            worker.start()
        for worker in workers:
            worker.join(timeout=60)
        assert [worker.exitcode for worker in workers] == [0] * 8, trial


def test_failed_append_writes_nothing(tmp_path):
    store = ResultsStore(tmp_path / "r.sqlite")
    store.append([_row()])
    bad = _row(config={"not_json": object()})
    with pytest.raises(InvalidInputError, match="row 1: config"):
        store.append([_row(view=5), bad, _row(view=6)])  # row 0 was inserted before row 1 failed
    assert [r.view for r in store.query()] == [1]


def test_row_validation():
    with pytest.raises(InvalidInputError, match="reference_kind"):
        _row(reference_kind="mitsuba")
    with pytest.raises(InvalidInputError, match="reference_kind"):
        _row(reference_kind="method:")
    with pytest.raises(UnknownNameError, match="did you mean 'quick'"):
        _row(profile="quik")
    assert _row(config='{"a": 1}').config == {"a": 1}  # JSON text is accepted too
    assert _row().timestamp.endswith("+00:00")


def test_not_a_database_is_a_user_error(tmp_path):
    path = tmp_path / "junk.sqlite"
    path.write_bytes(b"this is not sqlite" * 100)
    with pytest.raises(InvalidInputError, match="not a usable SQLite file"):
        ResultsStore(path).query()


def test_git_sha(tmp_path):
    assert results.git_sha(tmp_path) == "unknown"
    git = ["git", "-c", "user.name=t", "-c", "user.email=t@t", "-c", "commit.gpgsign=false"]
    subprocess.run([*git, "init", "-q"], cwd=tmp_path, check=True)
    (tmp_path / "f.txt").write_text("one")
    (tmp_path / "reports").mkdir()
    (tmp_path / "reports" / "table-x.md").write_text("old table")
    (tmp_path / "pkg").mkdir()
    subprocess.run([*git, "add", "f.txt", "reports"], cwd=tmp_path, check=True)
    subprocess.run([*git, "commit", "-q", "-m", "c"], cwd=tmp_path, check=True)
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=tmp_path, capture_output=True,
                          text=True, check=True).stdout.strip()
    (tmp_path / "untracked.txt").write_text("x")
    assert results.git_sha(tmp_path) == head
    # A regenerated report is an output, not a code change (asked from a subfolder, as the
    # package asks from its own folder).
    (tmp_path / "reports" / "table-x.md").write_text("new table")
    assert results.git_sha(tmp_path / "pkg") == head
    (tmp_path / "f.txt").write_text("two")
    assert results.git_sha(tmp_path / "pkg") == head + "+dirty"
    assert results.git_sha(tmp_path) == head + "+dirty"


def test_format_rows():
    rows = [_row(metrics={"psnr": math.inf, "psnr_masked": 27.25}),
            _row(method="texture", memory_bytes=None, metrics={"psnr": 30.123456})]
    text = table.format_rows(rows, columns=["method", "size", "psnr", "psnr_masked", "memory_bytes"])
    lines = text.splitlines()
    assert len(lines) == 4
    assert lines[0].split() == ["method", "size", "psnr", "psnr_masked", "memory_bytes"]
    assert lines[2].split() == ["vertex", "64x48", "inf", "27.25", "123456"]
    assert lines[3].split() == ["texture", "64x48", "30.12", "-", "-"]
    assert "psnr" in table.format_rows(rows)  # default columns
    assert table.format_rows([]) == "(no results)"
    with pytest.raises(UnknownNameError):
        table.format_rows(rows, columns=["methd"])
