"""Where jobs run: in this process, on Dask workers, or each in a process of its own.

Every executor has one interface: :meth:`Executor.submit` a picklable task function and one
item, then :meth:`Executor.next_finished` for the next ``(handle, result)`` to finish (so a
driver can keep every worker busy and decide what to run next from what came back), and
:meth:`Executor.map` on top of them for a list of items. A task is expected to catch its own
errors (:func:`prtbench.bench.submit.measure` never raises); what an executor itself loses --
a Dask worker that died, a process that crashed or ran past its time -- comes back as a
:class:`Lost` in place of the result, so one lost job never aborts the others.

* :class:`SerialExecutor`: one task after another in this process (timings taken on a quiet
  machine, the CLI's ``run``, the paper tables' cells).
* :class:`DaskExecutor`: Dask distributed, on an embedded ``LocalCluster`` (one worker per core
  by default, spawned processes, one thread each: :mod:`prtbench.bench.cluster`) or on an
  existing scheduler (``--scheduler tcp://HOST:PORT``). Sweeps and ``advise``.
* :class:`SubprocessExecutor`: each task in a fresh spawned process with a timeout, so a crash
  or a hang is measured instead of taking the driver down (the stability matrix).
"""

from __future__ import annotations

import functools
import logging
import multiprocessing
import os
import signal
import threading
import time
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

from tqdm.std import TqdmDefaultWriteLock

from prtbench.api.errors import InvalidInputError
from prtbench.bench.cluster import (
    check_worker_threads,
    connect,
    cores,
    local_cluster,
    one_line,
    register_setup,
)

try:
    from distributed import WorkerPlugin as _WorkerPluginBase
except ImportError:  # Dask is needed only with workers >= 1
    _WorkerPluginBase = object


@dataclass(frozen=True)
class Lost:
    """A task whose result never came back: ``kind`` is ``worker``, ``crash`` or ``timeout``."""

    kind: str
    error: str
    seconds: float = 0.0


class Executor(ABC):
    """Runs tasks; see the module docstring."""

    #: Tasks that run at once (1: serial). Rows record it: concurrent workers share cores and
    #: distort frame times.
    workers: int = 1
    #: How the executor is described in progress lines and stored rows.
    kind: str = ""

    def start(self) -> int:
        """Start the workers (if not yet); returns how many run at once."""
        return self.workers

    @abstractmethod
    def submit(self, task: Callable[[Any], Any], item: Any) -> Any:
        """Start ``task(item)``; returns a handle that :meth:`next_finished` gives back."""

    @abstractmethod
    def next_finished(self) -> tuple[Any, Any]:
        """``(handle, result or Lost)`` of the next submitted task to finish (blocking)."""

    @property
    @abstractmethod
    def pending(self) -> int:
        """Tasks submitted and not yet returned by :meth:`next_finished`."""

    def map(self, task: Callable[[Any], Any], items: Sequence[Any]) -> Iterator[tuple[int, Any]]:
        """``(index, task(items[index]) or Lost)`` as each task finishes."""
        index_of = {}
        for index, item in enumerate(items):
            index_of[id(self.submit(task, item))] = index
        for _ in range(len(index_of)):
            handle, result = self.next_finished()
            yield index_of[id(handle)], result

    def close(self) -> None:
        """Release workers and connections (idempotent)."""

    def __enter__(self) -> "Executor":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class SerialExecutor(Executor):
    """Each task in this process, in order (a task runs when its result is asked for)."""

    workers = 1
    kind = "serial"

    def __init__(self) -> None:
        self._queue: list[tuple[object, Callable, Any]] = []

    def submit(self, task, item):
        handle = object()
        self._queue.append((handle, task, item))
        return handle

    def next_finished(self):
        handle, task, item = self._queue.pop(0)
        return handle, task(item)

    @property
    def pending(self) -> int:
        return len(self._queue)


@contextmanager
def _children_ignore_sigint() -> Iterator[None]:
    """Ignore SIGINT while the block starts worker processes, which inherit the ignoring.

    Ctrl-C reaches the terminal's whole process group. Dask's worker processes would each
    answer it with a ``KeyboardInterrupt`` traceback and die under their running cell;
    ignoring it, they are stopped by the client, which alone handles the interrupt (one
    line, exit 130, see :func:`prtbench.cli.main`). An ignored disposition survives ``spawn``
    (fork + exec) and Python then installs no SIGINT handler of its own; a handler or a
    blocked mask would not survive. The client's own handler is back once the workers run.
    """
    if threading.current_thread() is not threading.main_thread():  # only it may set handlers
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler if previous is None else previous)


class _SilentOnceClosing(logging.Filter):
    """Drops a worker's log records once it is closing (see :class:`QuietOnInterrupt`)."""

    def __init__(self, worker) -> None:
        super().__init__()
        self.worker = worker

    def filter(self, record: logging.LogRecord) -> bool:
        return self.worker.status.name not in ("closing", "closed", "failed")


class QuietOnInterrupt(_WorkerPluginBase):
    """Lets a Dask worker be stopped mid-cell by the client without a word on stderr.

    Ctrl-C interrupts the client (one line, exit 130: :func:`prtbench.cli.main`), which
    closes the cluster under the running cells; the workers then must say nothing:

    * SIGINT is ignored (as it is from birth for the workers the client starts, see
      :func:`_children_ignore_sigint`; this covers workers a nanny restarts later);
    * a closing worker's log records are dropped: its heartbeats and comms to a scheduler
      that is closing too fail then, logged as tracebacks that concern no user;
    * tqdm's progress bars get no inter-process lock: a spawned worker shares it with no
      other process, and the named semaphore behind it, still held when the shutdown kills
      the worker under its cell, made multiprocessing's resource tracker warn of a "leaked
      semaphore" after prtbench's last line. tqdm's thread lock stays.
    """

    name = "prtbench-quiet-on-interrupt"

    def setup(self, worker) -> None:
        if threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGINT, signal.SIG_IGN)
        silent = _SilentOnceClosing(worker)
        for handler in logging.getLogger("distributed").handlers:
            handler.addFilter(silent)
        if not hasattr(TqdmDefaultWriteLock, "mp_lock"):  # tqdm makes it once, if absent
            TqdmDefaultWriteLock.mp_lock = None


class DaskExecutor(Executor):
    """Tasks on Dask workers.

    Parameters
    ----------
    workers : int, optional
        Workers of the embedded ``LocalCluster`` (default: one per core). Ignored with
        ``scheduler``.
    scheduler : str, optional
        Address of an existing Dask scheduler (``tcp://HOST:PORT``), checked on creation.
    threads : int, optional
        ``PRTBENCH_THREADS`` / ``LP_NUM_THREADS`` of every worker (default: each worker's share
        of its host's cores).
    """

    kind = "dask"

    def __init__(self, *, workers: int | None = None, scheduler: str | None = None,
                 threads: int | None = None):
        if workers is not None and workers < 1:
            raise InvalidInputError(f"--workers {workers}; accepted: 1 or more Dask workers "
                                    "(0 runs serially, without Dask)")
        self.threads = check_worker_threads(threads)
        self.scheduler = scheduler
        self._requested = workers
        self._client = connect(scheduler) if scheduler else None  # fails before any work
        self._cluster = None
        self._finished = None
        self._pending = 0
        self.workers = 0

    def start(self) -> int:
        if self._client is None:
            from distributed import Client

            with _children_ignore_sigint():
                self._cluster = local_cluster(self._requested or cores(), threads=self.threads)
            self._client = Client(self._cluster)
        if not self.workers:
            self.workers = register_setup(self._client, threads=self.threads)
            if self._cluster is not None:  # our own workers; never another's --scheduler's
                self._client.register_plugin(QuietOnInterrupt())
        return self.workers

    def submit(self, task, item):
        from distributed import as_completed

        self.start()
        # A unique key: Dask would otherwise merge equal tasks across calls.
        future = self._client.submit(task, item, pure=False,
                                     key=f"prtbench-{os.urandom(8).hex()}")
        if self._finished is None:
            self._finished = as_completed()
        self._finished.add(future)
        self._pending += 1
        return future

    def next_finished(self):
        future = next(self._finished)
        self._pending -= 1
        try:
            result = future.result()
        except Exception as exc:  # noqa: BLE001 - a worker died (KilledWorker) or similar
            result = Lost("worker", f"worker lost: {one_line(exc)}")
        return future, result

    @property
    def pending(self) -> int:
        return self._pending

    def close(self) -> None:
        self._finished, self._pending = None, 0
        if self._client is not None:
            self._client.close()
            self._client = None
        if self._cluster is not None:
            self._cluster.close()
            self._cluster = None


def _child(conn, task, item) -> None:
    """Body of a spawned process: run the task, send its result back."""
    conn.send(task(item))
    conn.close()


class SubprocessExecutor(Executor):
    """Each task in a fresh spawned process, killed after its timeout.

    Parameters
    ----------
    timeout_s : float or callable
        Seconds each task may take, or a function of the item giving them.
    """

    workers = 1
    kind = "subprocess"

    def __init__(self, *, timeout_s: float | Callable[[Any], float]):
        self.timeout_of = timeout_s if callable(timeout_s) else (lambda item: float(timeout_s))
        self._queue: list[tuple[object, Callable, Any]] = []

    def submit(self, task, item):
        handle = object()
        self._queue.append((handle, task, item))
        return handle

    def next_finished(self):
        handle, task, item = self._queue.pop(0)
        return handle, self.run_one(task, item, timeout_s=self.timeout_of(item))

    @property
    def pending(self) -> int:
        return len(self._queue)

    @staticmethod
    def run_one(task, item, *, timeout_s: float):
        """``task(item)`` in a spawned process; a :class:`Lost` if it died or ran too long."""
        ctx = multiprocessing.get_context("spawn")  # never fork a process holding a GL context
        parent, child = ctx.Pipe(duplex=False)
        process = ctx.Process(target=_child, args=(child, task, item), daemon=True)
        start = time.perf_counter()
        process.start()
        child.close()
        result = None
        try:
            if parent.poll(timeout_s):
                try:
                    result = parent.recv()
                except EOFError:
                    result = None
        finally:
            process.join(5.0 if result is not None else 0.1)
            if process.is_alive():
                process.kill()
                process.join()
            parent.close()
        wall = time.perf_counter() - start
        if result is not None:
            return result
        if wall >= timeout_s:
            return Lost("timeout", f"no answer after {timeout_s:g} s (killed)", wall)
        return Lost("crash", f"process died with exit code {process.exitcode}", wall)


def make_executor(*, workers: int | None = None, scheduler: str | None = None,
                  threads: int | None = None) -> Executor:
    """The executor of the ``--workers`` / ``--scheduler`` / ``--worker-threads`` options:
    serial for ``workers=0`` without a scheduler, else Dask."""
    if workers is not None and workers < 0:
        raise InvalidInputError(f"--workers {workers}; accepted: 0 (serial, no Dask) or more")
    if workers == 0 and not scheduler:
        if threads is not None:
            raise InvalidInputError(f"--worker-threads {threads} with --workers 0; accepted: "
                                    "--worker-threads with Dask workers (the serial run uses "
                                    "PRTBENCH_THREADS)")
        return SerialExecutor()
    return DaskExecutor(workers=workers, scheduler=scheduler, threads=threads)


def bind(task: Callable, /, **kwargs) -> Callable:
    """``task`` with keyword arguments fixed, picklable for Dask and spawned processes."""
    return functools.partial(task, **kwargs)
