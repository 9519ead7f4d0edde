"""``prtbench sweep``: grid validation, Dask workers versus serial, resume after kill -9,
unreachable schedulers (issue #13 §1)."""

from __future__ import annotations

import contextlib
import os
import signal
import sqlite3
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from prtbench.bench.job import Job
from prtbench.cli import main
from prtbench.tradeoff import grid
from prtbench.tradeoff.sweep import retime_serial, run_cells

ROOT = Path(__file__).resolve().parents[3]
VALID = """
profile = "smoke"
scene = "plants"
light = "sky"

[[method]]
name = "vertex"
grid = { sh_bands = [3, 4] }
"""


def _sweep_file(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "sweep.toml"
    path.write_text(text)
    return path


def _error(capsys, argv: list[str]) -> str:
    """Run the CLI expecting a user error: exit 2, one stderr line; returns that line."""
    assert main(argv) == 2
    lines = [l for l in capsys.readouterr().err.splitlines() if l.strip()]
    assert len(lines) == 1 and lines[0].startswith("prtbench: error: "), lines
    return lines[0]


@pytest.mark.parametrize("text, expected", [
    (VALID.replace('grid = {', 'grid = {{'), ["malformed TOML", "line 8", "column"]),
    (VALID.replace('"vertex"', '"vertx"'), ["unknown method 'vertx'", "vertex", "texture-tpfl"]),
    (VALID.replace("sh_bands", "sh_band"), ["unknown knob 'sh_band'", "sh_bands", "rays_per_point"]),
    (VALID.replace('"plants"', '"plantz"'), ["unknown scene 'plantz'", "plants"]),
    (VALID.replace('"sky"', '"skyy"'), ["unknown light 'skyy'", "sky", "sunset"]),
    (VALID.replace("light =", "lihgt ="), ["unknown top-level key 'lihgt'", "light"]),
    (VALID.replace("[3, 4]", "[3, 99]"), ["99", "sh_bands", "[1, 8]"]),
    (VALID.replace("[3, 4]", "3"), ["sh_bands = 3", "a non-empty list"]),
    (VALID.replace('"vertex"', '"learnt-sdf"').replace("sh_bands", "hidden").replace("[3, 4]", "[8, 16]"),
     ["learnt-sdf", "no valid cell", "needs an SDF scene", "sdf-rabbit"]),
    ('profile = "smoke"\nscene = "plants"\n', ["no [[method]] tables"]),
])
def test_sweep_file_errors_are_one_line_and_write_nothing(tmp_path, capsys, text, expected):
    path = _sweep_file(tmp_path, text)
    results = tmp_path / "r.sqlite"
    line = _error(capsys, ["sweep", str(path), "--results", str(results), "--quiet"])
    for part in expected:
        assert part in line, line
    if "TOML" in expected[0]:
        assert str(path) in line
    assert not results.exists()


@pytest.mark.parametrize("argv, expected", [
    (["--grid", "sh_bands"], ["--grid 'sh_bands'", "KNOB=V1,V2"]),
    (["--grid", "sh_bandz=3,4"], ["unknown knob 'sh_bandz'", "sh_bands"]),
    (["--grid", "sh_bands=3,x"], ["sh_bands", "'x'"]),
    (["--workers", "-1"], ["--workers -1", "0 (serial"]),
    (["--worker-threads", "0"], ["--worker-threads 0", "1..256"]),
    (["--worker-threads", "1", "--workers", "0"], ["--worker-threads 1 with --workers 0",
                                                   "PRTBENCH_THREADS"]),
    (["--scheduler", "localhost:8786"], ["--scheduler 'localhost:8786'", "tcp://HOST:PORT"]),
])
def test_cli_grid_errors(tmp_path, capsys, argv, expected):
    results = tmp_path / "r.sqlite"
    line = _error(capsys, ["sweep", "--scene", "plants", "--method", "vertex", "--profile", "smoke",
                           "--results", str(results), "--quiet", *argv])
    for part in expected:
        assert part in line, line
    assert not results.exists()


def test_file_and_options_together_or_neither_are_errors(tmp_path, capsys):
    path = _sweep_file(tmp_path, VALID)
    assert "both a file and --scene" in _error(capsys, ["sweep", str(path), "--scene", "plants"])
    assert "no grid" in _error(capsys, ["sweep", "--method", "vertex"])


def test_unreachable_scheduler_fails_fast_and_writes_nothing(tmp_path, capsys):
    path = _sweep_file(tmp_path, VALID)
    results = tmp_path / "r.sqlite"
    start = time.monotonic()
    line = _error(capsys, ["sweep", str(path), "--scheduler", "tcp://127.0.0.1:9",
                           "--results", str(results), "--quiet"])
    assert time.monotonic() - start < 20.0
    assert "tcp://127.0.0.1:9" in line and "no Dask scheduler reachable" in line
    assert not results.exists()


def test_cli_grid_expands_to_typed_cells():
    sweep = grid.from_options(scenes=["plants"], methods=["vertex", "texture-tpfl"],
                              grid=["sh_bands=3,4,5", "rays_per_point=32,64"], lights=["sky"],
                              profile="smoke")
    assert len(sweep.cells) == 2 * 3 * 2
    first = sweep.cells[0]
    assert (first.method, first.scene, first.light) == ("vertex", "plants", "sky")
    assert first.label == {"sh_bands": 3, "rays_per_point": 32}  # parsed by the config: ints
    assert {c.method for c in sweep.cells} == {"vertex", "texture-tpfl"}
    assert grid.split_values("2,[2,1,2],3") == ["2", "[2,1,2]", "3"]


def test_shipped_sweep_files_cover_every_method():
    from prtbench.api.method import METHODS

    every = grid.load_sweep(ROOT / "sweeps" / "plants-all.toml", profile="smoke")
    per_method = Counter(c.method for c in every.cells)
    assert set(per_method) == set(METHODS.names())
    assert all(3 <= n <= 6 for n in per_method.values()), per_method
    assert not every.dropped
    assert {c.scene for c in every.cells if c.method != "learnt-sdf"} == {"plants"}
    assert {c.light for c in every.cells} == {"sky"}
    room = grid.load_sweep(ROOT / "sweeps" / "room-all.toml", profile="smoke")  # make pareto
    assert {c.method for c in room.cells} == set(METHODS.names()) and not room.dropped
    demo = grid.load_sweep(ROOT / "sweeps" / "demo.toml")  # make demo: every method, once or twice
    assert {c.method for c in demo.cells} == set(METHODS.names()) and not demo.dropped
    quick = grid.load_sweep(ROOT / "sweeps" / "plants-quick24.toml")
    assert quick.profile == "quick" and len(quick.cells) == 24


CELLS = [Job("vertex", "plants", {"sh_bands": 3}, light="sky", overrides={"sh_bands": 3}),
         Job("vertex", "plants", {"sh_bands": 4}, light="sky", overrides={"sh_bands": 4}),
         Job("irradiance-volume", "plants", {"resolution": 4}, light="sky",
              overrides={"resolution": 4})]


def _by_key(path: Path) -> dict[str, list]:
    from prtbench.store.results import ResultsStore

    out: dict[str, list] = {}
    for row in ResultsStore(path).query():
        out.setdefault(row.cell_key, []).append(row)
    return out


def test_two_workers_equal_serial_and_resume_skips(tmp_path, monkeypatch):
    """Separate caches, so both runs precompute and render their references themselves."""
    keys = {}
    for name, workers in (("serial", 0), ("dask", 2)):
        monkeypatch.setenv("PRTBENCH_CACHE", str(tmp_path / f"cache-{name}"))
        outcome = run_cells(CELLS, profile="smoke", results_path=tmp_path / f"{name}.sqlite",
                            workers=workers, progress=False)
        assert [c.status for c in outcome.results] == ["done"] * 3, [c.error for c in outcome.results]
        assert outcome.workers == max(1, workers)
        keys[name] = _by_key(tmp_path / f"{name}.sqlite")
    assert set(keys["serial"]) == set(keys["dask"]) and len(keys["serial"]) == 3
    for key, rows in keys["serial"].items():
        (serial,), (dask,) = rows, keys["dask"][key]
        assert serial.metrics == dask.metrics  # exactly
        assert (serial.status, serial.workers, dask.workers) == ("ok", 1, 2)
        assert serial.memory_bytes == dask.memory_bytes

    # The artifacts (and so the images) are bit-identical: vertex is deterministic.
    from prtbench.api.method import METHODS, load_or_precompute
    from prtbench.scene.registry import get_scene
    from prtbench.transport.lights import get_light

    method = METHODS.get("vertex")
    config = method.make_config({"sh_bands": 4}, profile="smoke")
    scene = get_scene("plants").with_views(1)
    images, arrays = [], []
    for name in ("serial", "dask"):
        monkeypatch.setenv("PRTBENCH_CACHE", str(tmp_path / f"cache-{name}"))
        artifact = load_or_precompute(method, scene, config, progress=False)
        assert artifact.cache_hit  # made by that run, not now
        arrays.append(artifact.arrays)
        renderer = method.renderer(scene, artifact, config, width=64, height=48)
        try:
            images.append(renderer.render(scene.trajectory.views[0], get_light("sky")))
        finally:
            renderer.release()
    assert arrays[0].keys() == arrays[1].keys()
    assert all(np.array_equal(arrays[0][k], arrays[1][k]) for k in arrays[0])
    assert images[0].std() > 0.01 and np.array_equal(images[0], images[1])

    # Resume: everything is stored, so nothing runs; --timing-serial adds one workers=1 row
    # per cell measured on 2 workers, with the same metrics.
    again = run_cells(CELLS, profile="smoke", results_path=tmp_path / "dask.sqlite", workers=2,
                      progress=False)
    assert [c.status for c in again.results] == ["skipped"] * 3 and again.workers == 0
    retimed = retime_serial(again, profile="smoke", results_path=tmp_path / "dask.sqlite",
                            progress=False)
    assert [c.status for c in retimed] == ["done"] * 3
    after = _by_key(tmp_path / "dask.sqlite")
    for key, rows in after.items():
        assert sorted(r.workers for r in rows) == [1, 2]
        assert rows[0].metrics == rows[1].metrics == keys["serial"][key][0].metrics
    assert retime_serial(again, profile="smoke", results_path=tmp_path / "dask.sqlite",
                         progress=False) == []


def test_failing_cell_is_reported_and_the_rest_run(tmp_path, capsys):
    # data-driven's smoke lightmap (128²) cannot pack plants' charts: fails in the precompute.
    results = tmp_path / "r.sqlite"
    rc = main(["sweep", "--scene", "plants", "--method", "vertex,data-driven", "--light", "sky",
               "--profile", "smoke", "--workers", "0", "--results", str(results), "--quiet"])
    err = capsys.readouterr().err
    assert rc == 1
    failed = [l for l in err.splitlines() if l.startswith("prtbench: cell failed: data-driven")]
    assert len(failed) == 1 and "lightmap" in failed[0], err
    rows = _by_key(results)
    assert len(rows) == 1 and next(iter(rows.values()))[0].method == "vertex"


def _rows_in(path: Path) -> int:
    # Closed explicitly: a sqlite3 connection left to the garbage collector (it sits in a
    # reference cycle) keeps this process's WAL index mapped after the writer deleted it,
    # and later connections of this process then read the store as malformed.
    try:
        with contextlib.closing(sqlite3.connect(f"file:{path}?mode=ro", uri=True,
                                                timeout=1)) as conn:
            return conn.execute("SELECT COUNT(*) FROM renders").fetchone()[0]
    except sqlite3.Error:
        return 0


RESUME = VALID.replace("[3, 4]", "[2, 3, 4, 5]") + """
[[method]]
name = "vertex-tpfl"
grid = { sh_bands = [3, 4] }
"""


@pytest.mark.parametrize("workers", [0, pytest.param(2, marks=pytest.mark.slow)])
def test_kill_9_mid_sweep_then_rerun_gives_the_uninterrupted_rows(tmp_path, workers):
    import psutil

    path = _sweep_file(tmp_path, RESUME)
    killed, clean = tmp_path / "killed.sqlite", tmp_path / "clean.sqlite"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    argv = [sys.executable, "-m", "prtbench", "sweep", str(path), "--workers", str(workers),
            "--quiet"]
    proc = subprocess.Popen([*argv, "--results", str(killed)], env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 240
    while _rows_in(killed) == 0 and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)
    children = psutil.Process(proc.pid).children(recursive=True) if proc.poll() is None else []
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    # The orphaned workers lose their scheduler and exit; never leave them behind.
    gone, alive = psutil.wait_procs(children, timeout=60)
    for child in alive:
        child.kill()
    assert not alive, f"{len(alive)} worker processes outlived the killed client"
    partial = _by_key(killed)
    assert 1 <= len(partial) < 6, "the kill did not land mid-sweep"

    done = subprocess.run([*argv, "--results", str(killed)], env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert f"{len(partial)} skipped" in done.stdout
    done = subprocess.run([*argv, "--results", str(clean)], env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    resumed, uninterrupted = _by_key(killed), _by_key(clean)
    assert set(resumed) == set(uninterrupted) and len(resumed) == 6
    for key, rows in resumed.items():
        assert len(rows) == 1  # no duplicated cell
        assert rows[0].metrics == uninterrupted[key][0].metrics


@pytest.mark.slow
def test_existing_scheduler_runs_the_sweep_unchanged(tmp_path):
    import dask
    from distributed import LocalCluster

    dask.config.set({"distributed.worker.multiprocessing-method": "spawn"})
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                      dashboard_address=":0") as cluster:
        outcome = run_cells(CELLS[:1], profile="smoke", results_path=tmp_path / "r.sqlite",
                            scheduler=cluster.scheduler_address, progress=False)
    assert [c.status for c in outcome.results] == ["done"] and outcome.workers == 1
    (rows,) = _by_key(tmp_path / "r.sqlite").values()
    assert rows[0].workers == 1 and rows[0].metrics["psnr_masked"] > 10.0


def _thread_settings() -> tuple[str, str]:
    return os.environ["PRTBENCH_THREADS"], os.environ["LP_NUM_THREADS"]


def test_worker_threads_fix_every_workers_share_of_the_cores():
    from distributed import Client

    from prtbench.bench.cluster import cores, local_cluster, register_setup

    # One worker gets every core by default; --worker-threads 1 holds it to one (the
    # configuration that measures Dask's own scaling, benchmarks/bench_sweep.py).
    with local_cluster(1) as cluster, Client(cluster) as client:
        assert register_setup(client) == 1
        assert list(client.run(_thread_settings).values()) == [(str(cores()),) * 2]
        assert register_setup(client, threads=1) == 1
        assert list(client.run(_thread_settings).values()) == [("1", "1")]


def test_settle_load_waits_for_the_parallel_phase_to_leave_the_load_average(monkeypatch):
    from prtbench.tradeoff import sweep as sweep_mod

    readings = iter([3.4, 3.0, 2.5, 1.9, 1.5])
    clock = {"t": 0.0}
    monkeypatch.setattr(sweep_mod.os, "getloadavg", lambda: (next(readings), 0.0, 0.0))
    monkeypatch.setattr(sweep_mod.time, "monotonic", lambda: clock["t"])
    monkeypatch.setattr(sweep_mod.time, "sleep", lambda s: clock.__setitem__("t", clock["t"] + s))
    assert sweep_mod.settle_load(target=2.0, max_wait_s=60, poll_s=2, progress=False) == 1.9
    assert clock["t"] == 6.0  # three polls: 3.0, 2.5, then 1.9 <= 2
    # Bounded: a machine that stays busy costs at most max_wait_s.
    monkeypatch.setattr(sweep_mod.os, "getloadavg", lambda: (5.0, 0.0, 0.0))
    clock["t"] = 0.0
    assert sweep_mod.settle_load(target=2.0, max_wait_s=10, poll_s=2, progress=False) == 5.0
    assert clock["t"] == 10.0
