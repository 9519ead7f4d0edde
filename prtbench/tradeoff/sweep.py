"""Run a sweep's jobs on Dask (or serially), resumable; only the client writes the store.

A sweep is the jobs of a grid (:mod:`prtbench.tradeoff.grid`) submitted through the one submit
path, :func:`prtbench.bench.submit.submit`, with ``resume``: every job is validated and the
results store checked first, jobs already measured for this code version (rows with the same
:func:`prtbench.bench.submit.job_key` and status ``ok`` or ``degenerate``) are skipped, and
the rest run on the executor of ``--workers`` / ``--scheduler``:

- ``workers=0``: one after the other in this process, no Dask;
- otherwise on an embedded ``LocalCluster`` (worker processes started with ``spawn``, so no
  worker inherits a GL context or a Mitsuba variant; one thread each; ``workers`` of them,
  default one per core), or on the existing cluster at ``scheduler`` (``tcp://HOST:PORT``),
  unchanged (:class:`prtbench.bench.executors.DaskExecutor`).

A failed job never aborts the others; the client appends each finished job's rows in one
transaction, so a killed client (or worker) loses only the jobs in flight and a rerun
completes the sweep.

Rows record ``workers`` (concurrent workers: they share cores and distort frame times) and
``cell_key``. :func:`retime_serial` (``prtbench sweep --timing-serial``) re-runs, alone and
in this process, each finished job that has no ``workers = 1`` row yet and appends those
rows: rows are append-only, so consumers take a job's ``workers = 1`` row for timing.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from prtbench.bench.cluster import cores
from prtbench.bench.executors import SerialExecutor, make_executor
from prtbench.bench.job import Job
from prtbench.bench.submit import JobResult, Submission, stored_keys, submit


def run_cells(cells: Sequence[Job], *, profile: str, results_path: Path | None = None,
              workers: int | None = None, scheduler: str | None = None, force: bool = False,
              progress: bool = True, worker_threads: int | None = None) -> Submission:
    """Run ``cells`` in ``profile``, appending each finished job's rows to the store.

    Parameters
    ----------
    cells : sequence of Job
        Duplicates (same job key) run once.
    profile : str
    results_path : Path, optional
        The results store (default :func:`prtbench.store.results.default_path`).
    workers : int, optional
        Local Dask workers (default: one per core); 0 runs serially in this process without
        Dask. Ignored with ``scheduler``.
    scheduler : str, optional
        Address of an existing Dask scheduler (``tcp://HOST:PORT``).
    force : bool
        Measure jobs already in the store again.
    progress : bool
        Show the progress bar (stderr).
    worker_threads : int, optional
        ``PRTBENCH_THREADS`` / ``LP_NUM_THREADS`` of every Dask worker (default: each
        worker's share of its host's cores). Not accepted with ``workers=0``: the serial run
        uses this process's own ``PRTBENCH_THREADS``.

    Raises
    ------
    PrtbenchError
        An invalid job, an unusable results store or an unreachable scheduler, before any
        work and with nothing written.
    """
    with make_executor(workers=workers, scheduler=scheduler, threads=worker_threads) as executor:
        return submit(cells, profile=profile, executor=executor, results_path=results_path,
                      resume=not force, progress=progress, desc="sweep")


def settle_load(*, target: float, max_wait_s: float, poll_s: float = 2.0,
                progress: bool = True) -> float:
    """Wait (at most ``max_wait_s``) for the 1-minute load average to fall to ``target``.

    The load average lags the machine by about a minute: right after the parallel phase of a
    sweep it still reads the workers' load, and every row stores it (``load_average``), so the
    first serially timed jobs would be flagged busy for load that has already gone. Returns
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


def retime_serial(outcome: Submission, *, profile: str, results_path: Path | None = None,
                  progress: bool = True, settle_s: float = 0.0) -> list[JobResult]:
    """Re-run, one at a time in this process, each finished job without a ``workers = 1`` row.

    Appends the new rows (``workers = 1``, same key): frame times measured with the machine
    to itself. Returns the results of the re-runs (failures included). ``settle_s`` > 0
    first waits that long at most for the load of the parallel phase to leave the 1-minute
    load average (:func:`settle_load`, to the core count).
    """
    stored = stored_keys(results_path, profile)
    todo = [r.job for r in outcome.results if r.status in ("done", "skipped")
            and 1 not in stored.get(r.key, set())]
    if not todo:
        return []
    if settle_s > 0:
        settle_load(target=float(cores()), max_wait_s=settle_s, progress=progress)
    return submit(todo, profile=profile, executor=SerialExecutor(), results_path=results_path,
                  progress=progress, desc="timing (serial)").results
