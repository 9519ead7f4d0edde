"""Run sweep cells on Dask distributed; only the client writes the results store (DESIGN.md §15).

:func:`run_cells` validates every cell (:func:`prtbench.bench.runner.prepare`) and the results store
first, then skips the cells already measured (their rows carry the same :func:`cell_key` and
status ``ok`` or ``degenerate``), and runs the rest:

- ``workers=0``: one after the other in this process, no Dask;
- otherwise on an embedded ``LocalCluster`` (worker processes started with ``spawn``, so no
  worker inherits a GL context or a Mitsuba variant; one thread each; ``workers`` of them,
  default one per core), or on the existing cluster at ``scheduler`` (``tcp://HOST:PORT``),
  unchanged (the Dask side: :mod:`prtbench.bench.cluster`).

Every task runs one cell through the ordinary runner (:func:`measure_cell`: ``prepare`` +
``execute`` with no images and no store) and returns its rows, or the one-line error of a
failed cell, which never aborts the others. The client appends each finished cell's rows in
one transaction, so a killed client (or worker) loses only the cells in flight and a rerun
completes the sweep.

Rows record ``workers`` (concurrent workers: they share cores and distort frame times) and
``cell_key``. :func:`retime_serial` (``prtbench sweep --timing-serial``) re-runs, alone and
in this process, each finished cell that has no ``workers = 1`` row yet and appends those
rows: rows are append-only, so consumers take a cell's ``workers = 1`` row for timing.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from prtbench.api.errors import InvalidInputError
from prtbench.bench.cluster import (
    check_worker_threads,
    connect,
    cores,
    local_cluster,
    one_line,
    register_setup,
)
from prtbench.bench.reproduction import Cell
from prtbench.tradeoff.grid import prepare_cell

#: Statuses of stored rows that count as measured (failed cells store nothing).
MEASURED = ("ok", "degenerate")


@dataclass
class CellOutcome:
    """What became of one cell: ``done`` (measured now), ``skipped`` (in the store) or ``failed``."""

    cell: Cell
    key: str
    status: str
    error: str = ""
    rows: list = field(default_factory=list)
    #: Wall seconds the cell took on its worker (0 when skipped).
    seconds: float = 0.0


@dataclass
class SweepOutcome:
    """Per-cell outcomes, in the order of the cells given (duplicates removed)."""

    cells: list[CellOutcome]
    #: Workers that measured concurrently (1: serial; 0: nothing ran).
    workers: int
    wall_s: float
    scheduler: str | None = None

    def count(self, status: str) -> int:
        return sum(1 for c in self.cells if c.status == status)

    @property
    def failed(self) -> list[CellOutcome]:
        return [c for c in self.cells if c.status == "failed"]


def code_version() -> str:
    """The code version in cell keys: the full :func:`prtbench.store.results.git_sha`, ``+dirty``
    included, so results of a modified tree never pass for a clean commit's."""
    from prtbench.store.results import git_sha

    return git_sha()


def cell_key(prepared, *, code: str) -> str:
    """SHA-256 of everything a cell's measurement depends on.

    Parameters
    ----------
    prepared : prtbench.bench.runner.PreparedRun
        The cell's validated run: method, full config (defaults and profile overrides
        resolved), scene, variant, scene parameters, light, view count, resolution, profile
        and reference.
    code : str
        :func:`code_version`.
    """
    from prtbench.api.config import to_dict

    req = prepared.request
    identity = {
        "method": prepared.method_cls.name, "config": to_dict(prepared.config),
        "scene": prepared.scene.name, "variant": prepared.scene.variant,
        "scene_params": dict(prepared.scene.params), "light": prepared.light.name,
        "views": len(prepared.scene.trajectory), "resolution": [prepared.width, prepared.height],
        "profile": prepared.profile.name, "reference": req.reference, "code": code}
    text = json.dumps(identity, sort_keys=True, default=str, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def measure_cell(cell: Cell, *, profile: str, cell_key: str, workers: int) -> dict[str, Any]:
    """Run one cell through the ordinary runner; never raises.

    Returns
    -------
    dict
        ``{"key", "rows"}`` (the :func:`prtbench.bench.runner.summary_rows`, recording ``workers``
        and ``key``) or ``{"key", "error"}`` with the one-line error.
    """
    from prtbench.bench.runner import execute, summary_rows

    key = cell_key
    start = time.perf_counter()
    try:
        prepared = prepare_cell(cell, profile=profile)
        summary = execute(prepared, progress=False, echo=False)
        rows = summary_rows(summary, prepared.scene, workers=workers, cell_key=key)
    except Exception as exc:  # noqa: BLE001 - a failing cell is reported, never fatal
        return {"key": key, "error": one_line(exc), "seconds": time.perf_counter() - start}
    return {"key": key, "rows": rows, "seconds": time.perf_counter() - start}


def _stored_keys(results_path: Path | None, profile: str) -> dict[str, set[int]]:
    """cell key → the ``workers`` values of its measured rows in the store."""
    from prtbench.store.results import ResultsStore, default_path

    path = Path(results_path) if results_path is not None else default_path()
    if not path.exists():
        return {}
    out: dict[str, set[int]] = {}
    for row in ResultsStore(path, readonly=True).query(profile=profile):
        if row.cell_key and row.status in MEASURED:
            out.setdefault(row.cell_key, set()).add(int(row.workers or 1))
    return out


def _validate(cells: Sequence[Cell], profile: str, results_path: Path | None
              ) -> list[tuple[Cell, str]]:
    """(cell, key) of every distinct cell; raises on the first invalid cell, writing nothing."""
    from prtbench.bench.outputs import check_results_store
    from prtbench.store.results import default_path

    check_results_store("--results", Path(results_path) if results_path else default_path())
    code = code_version()
    seen: set[str] = set()
    keyed = []
    for cell in cells:
        key = cell_key(prepare_cell(cell, profile=profile, reuse=True), code=code)
        if key not in seen:
            seen.add(key)
            keyed.append((cell, key))
    return keyed


class _Progress:
    """tqdm over cells with done / running / failed / skipped counts."""

    def __init__(self, total: int, skipped: int, *, enabled: bool):
        from tqdm import tqdm

        self.bar = tqdm(total=total, initial=skipped, unit="cell", desc="sweep",
                        disable=not enabled, file=sys.stderr, dynamic_ncols=True)
        self.done = self.failed = 0
        self.skipped, self.running = skipped, 0

    def update(self, *, running: int, finished: str | None = None) -> None:
        if finished == "done":
            self.done += 1
        elif finished == "failed":
            self.failed += 1
        self.running = running
        self.bar.set_postfix(done=self.done, running=self.running, failed=self.failed,
                             skipped=self.skipped, refresh=False)
        self.bar.update(1 if finished else 0)

    def close(self) -> None:
        self.bar.close()


def run_cells(cells: Sequence[Cell], *, profile: str, results_path: Path | None = None,
              workers: int | None = None, scheduler: str | None = None, force: bool = False,
              progress: bool = True, worker_threads: int | None = None) -> SweepOutcome:
    """Run ``cells`` in ``profile``, appending each finished cell's rows to the store.

    Parameters
    ----------
    cells : sequence of Cell
        Duplicates (same :func:`cell_key`) run once.
    profile : str
    results_path : Path, optional
        The results store (default :func:`prtbench.store.results.default_path`).
    workers : int, optional
        Local Dask workers (default: one per core); 0 runs serially in this process without
        Dask. Ignored with ``scheduler``.
    scheduler : str, optional
        Address of an existing Dask scheduler (``tcp://HOST:PORT``).
    force : bool
        Measure cells already in the store again.
    progress : bool
        Show the progress bar (stderr).
    worker_threads : int, optional
        ``PRTBENCH_THREADS`` / ``LP_NUM_THREADS`` of every Dask worker (default: each
        worker's share of its host's cores). Not accepted with ``workers=0``: the serial run
        uses this process's own ``PRTBENCH_THREADS``.

    Returns
    -------
    SweepOutcome

    Raises
    ------
    PrtbenchError
        An invalid cell, an unusable results store or an unreachable scheduler, before any
        work and with nothing written.
    """
    from prtbench.store.results import ResultsStore

    if workers is not None and workers < 0:
        raise InvalidInputError(f"--workers {workers}; accepted: 0 (serial, no Dask) or more")
    check_worker_threads(worker_threads)
    if worker_threads is not None and workers == 0 and not scheduler:
        raise InvalidInputError(f"--worker-threads {worker_threads} with --workers 0; accepted: "
                                f"--worker-threads with Dask workers (the serial run uses "
                                f"PRTBENCH_THREADS)")
    start = time.perf_counter()
    keyed = _validate(cells, profile, results_path)
    client = connect(scheduler) if scheduler else None  # before anything is written
    try:
        stored = {} if force else _stored_keys(results_path, profile)
        outcomes = {key: CellOutcome(cell, key, "skipped") for cell, key in keyed if key in stored}
        todo = [(cell, key) for cell, key in keyed if key not in outcomes]
        store = ResultsStore(results_path)
        bar = _Progress(len(keyed), len(outcomes), enabled=progress)

        def finish(cell: Cell, result: Mapping[str, Any]) -> str:
            key = result["key"]
            seconds = float(result.get("seconds", 0.0))
            if "error" in result:
                outcomes[key] = CellOutcome(cell, key, "failed", result["error"], seconds=seconds)
                return "failed"
            store.append(result["rows"])  # one transaction per cell: all its views or none
            outcomes[key] = CellOutcome(cell, key, "done", rows=list(result["rows"]),
                                        seconds=seconds)
            return "done"

        n_workers = 0  # none ran yet
        try:
            if todo and workers == 0 and client is None:
                n_workers = 1
                for cell, key in todo:
                    bar.update(running=1)
                    status = finish(cell, measure_cell(cell, profile=profile, cell_key=key, workers=1))
                    bar.update(running=0, finished=status)
            elif todo:
                cluster = None
                if client is None:
                    from distributed import Client

                    cluster = local_cluster(workers or cores(), threads=worker_threads)
                    client = Client(cluster)
                n_workers = register_setup(client, threads=worker_threads)
                try:
                    _run_dask(client, todo, profile, n_workers, finish, bar)
                finally:
                    if cluster is not None:
                        client.close()
                        cluster.close()
                        client = None
        finally:
            bar.close()
    finally:
        if client is not None:
            client.close()
    return SweepOutcome([outcomes[key] for _, key in keyed], n_workers,
                        time.perf_counter() - start, scheduler)


def _run_dask(client, todo, profile: str, n_workers: int, finish, bar: _Progress) -> None:
    from distributed import as_completed

    futures = {}
    for cell, key in todo:
        # A partial: submit() has keywords of its own (``workers``, ``key``, ...).
        task = functools.partial(measure_cell, profile=profile, cell_key=key, workers=n_workers)
        future = client.submit(task, cell, pure=False,
                               key=f"prtbench-cell-{key[:16]}-{os.urandom(4).hex()}")
        futures[future] = (cell, key)
    pending = len(futures)
    bar.update(running=min(n_workers, pending))
    for future in as_completed(futures):
        cell, key = futures[future]
        try:
            result = future.result()
        except Exception as exc:  # noqa: BLE001 - a worker died (KilledWorker) or similar
            result = {"key": key, "error": f"worker lost: {one_line(exc)}"}
        status = finish(cell, result)
        pending -= 1
        bar.update(running=min(n_workers, pending), finished=status)


def settle_load(*, target: float, max_wait_s: float, poll_s: float = 2.0,
                progress: bool = True) -> float:
    """Wait (at most ``max_wait_s``) for the 1-minute load average to fall to ``target``.

    The load average lags the machine by about a minute: right after the parallel phase of a
    sweep it still reads the workers' load, and every row stores it (``load_average``), so the
    first serially timed cells would be flagged busy for load that has already gone. Returns
    the load average it stopped at.
    """
    start = time.monotonic()
    load = os.getloadavg()[0]
    shown = False
    while load > target and time.monotonic() - start < max_wait_s:
        if progress and not shown:
            print(f"timing (serial): waiting up to {max_wait_s:.0f} s for the 1-min load average "
                  f"({load:.2f}) to settle to {target:.2f}", file=sys.stderr, flush=True)
            shown = True
        time.sleep(poll_s)
        load = os.getloadavg()[0]
    return load


def retime_serial(outcome: SweepOutcome, *, profile: str, results_path: Path | None = None,
                  progress: bool = True, settle_s: float = 0.0) -> list[CellOutcome]:
    """Re-run, one at a time in this process, each finished cell without a ``workers = 1`` row.

    Appends the new rows (``workers = 1``, same ``cell_key``): frame times measured with the
    machine to itself. Returns the outcomes of the re-runs (failures included). ``settle_s``
    > 0 first waits that long at most for the load of the parallel phase to leave the
    1-minute load average (:func:`settle_load`, to the core count).
    """
    from tqdm import tqdm

    from prtbench.bench.cluster import cores
    from prtbench.store.results import ResultsStore

    stored = _stored_keys(results_path, profile)
    todo = [c for c in outcome.cells if c.status in ("done", "skipped")
            and 1 not in stored.get(c.key, set())]
    if todo and settle_s > 0:
        settle_load(target=float(cores()), max_wait_s=settle_s, progress=progress)
    store = ResultsStore(results_path)
    results = []
    for item in tqdm(todo, desc="timing (serial)", unit="cell", disable=not progress,
                     file=sys.stderr):
        result = measure_cell(item.cell, profile=profile, cell_key=item.key, workers=1)
        if "error" in result:
            results.append(CellOutcome(item.cell, item.key, "failed", result["error"]))
            continue
        store.append(result["rows"])
        results.append(CellOutcome(item.cell, item.key, "done", rows=list(result["rows"])))
    return results
