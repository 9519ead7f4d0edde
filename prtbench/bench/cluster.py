"""Dask distributed for sweeps: the embedded LocalCluster, connecting to an existing
scheduler, and the worker plugin that sets every worker up (DESIGN.md §15).

Workers are separate processes started with ``spawn`` (a fresh interpreter: no inherited GL
context or Mitsuba variant; each builds its own lazily on its first cell), one thread each,
with BLAS/OpenMP/torch capped at one thread and ``PRTBENCH_THREADS`` / ``LP_NUM_THREADS``
set to the worker's share of its host's cores.
"""

from __future__ import annotations

import logging
import os
import sys
from collections.abc import Mapping
from urllib.parse import urlparse

from prtbench.api.errors import InvalidInputError, PrtbenchError
from prtbench.transport.parallel import MAX_THREADS

#: Seconds to wait for an existing scheduler before ``--scheduler`` is an error.
CONNECT_TIMEOUT_S = 5.0
#: Thread-count variables capped in every worker (BLAS, OpenMP, torch).
_THREAD_VARS = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS",
                "NUMEXPR_NUM_THREADS", "VECLIB_MAXIMUM_THREADS", "BLIS_NUM_THREADS")


def one_line(exc: BaseException) -> str:
    """A failure as one line: the PrtbenchError message, else ``Type: first line``."""
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    if isinstance(exc, PrtbenchError):
        return text
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def cores() -> int:
    """Cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def _worker_env(threads: int) -> dict[str, str]:
    # LP_NUM_THREADS: llvmpipe's rasteriser threads (default: every core, per context).
    return {**{name: "1" for name in _THREAD_VARS}, "PRTBENCH_THREADS": str(threads),
            "LP_NUM_THREADS": str(threads)}


try:
    from distributed import WorkerPlugin as _PluginBase
except ImportError:  # Dask is needed only with workers >= 1
    _PluginBase = object


class WorkerSetup(_PluginBase):
    """Sets a Dask worker up for prtbench cells.

    Caps BLAS/OpenMP/torch threads at 1 and sets ``PRTBENCH_THREADS`` (precompute tracing)
    and ``LP_NUM_THREADS`` (llvmpipe) to the worker's share of its host's cores. The
    worker's EGL context and Mitsuba variant are made lazily by the first cell it runs, in
    its own process: workers are started with ``spawn`` and never inherit a parent's one.

    Parameters
    ----------
    shares : mapping
        Worker address → threads; workers not in it get ``default``.
    default : int
    """

    name = "prtbench-worker-setup"

    def __init__(self, shares: Mapping[str, int] | None = None, *, default: int = 1):
        self.shares, self.default = dict(shares or {}), default

    def setup(self, worker) -> None:
        threads = int(self.shares.get(worker.address, self.default))
        os.environ.update(_worker_env(threads))
        if "torch" in sys.modules:  # already imported: the environment came too late for it
            sys.modules["torch"].set_num_threads(1)


def check_worker_threads(threads: int | None) -> int | None:
    """``threads`` if it is a valid per-worker thread count (or None); else a one-line error."""

    if threads is not None and (isinstance(threads, bool) or not isinstance(threads, int)
                                or not 1 <= threads <= MAX_THREADS):
        raise InvalidInputError(f"--worker-threads {threads!r}; accepted: an integer "
                                f"1..{MAX_THREADS} (threads per Dask worker), or unset for each "
                                f"worker's share of its host's cores")
    return threads


def local_cluster(n_workers: int, *, threads: int | None = None):
    """An embedded ``LocalCluster`` of ``n_workers`` processes (one Dask thread each).

    ``threads`` (default: this host's cores // ``n_workers``) is each worker's
    ``PRTBENCH_THREADS`` / ``LP_NUM_THREADS``.
    """

    import dask
    from distributed import LocalCluster

    # Spawned worker processes start from a fresh interpreter: no inherited GL context.
    dask.config.set({"distributed.worker.multiprocessing-method": "spawn"})
    threads = check_worker_threads(threads) or max(1, cores() // n_workers)
    # A free port for its HTTP server: several sweeps may run on one machine.
    return LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True,
                        dashboard_address=":0", silence_logs=logging.ERROR,
                        env=_worker_env(threads))


def connect(scheduler: str, *, timeout_s: float = CONNECT_TIMEOUT_S):
    """A Dask ``Client`` of the scheduler at ``scheduler``; one-line error if unreachable."""
    from distributed import Client

    if "://" not in scheduler:
        raise InvalidInputError(f"--scheduler '{scheduler}'; accepted: a Dask scheduler address "
                                f"such as tcp://HOST:PORT")
    try:
        return Client(scheduler, timeout=timeout_s)
    except (OSError, TimeoutError, ValueError) as exc:
        reason = one_line(exc)
        raise InvalidInputError(f"--scheduler '{scheduler}': no Dask scheduler reachable within "
                                f"{timeout_s:g} s ({reason}); accepted: the address of a running "
                                f"scheduler, tcp://HOST:PORT") from None


def register_setup(client, *, threads: int | None = None) -> int:
    """Install :class:`WorkerSetup` on the cluster's workers; returns their number.

    ``threads`` fixes every worker's thread count; by default each gets its share of its
    host's cores (cores // workers on that host).
    """

    threads = check_worker_threads(threads)
    host_cores = client.run(cores)  # worker address -> cores of that worker's host
    per_host: dict[str, int] = {}
    for address in host_cores:
        host = urlparse(address).hostname or address
        per_host[host] = per_host.get(host, 0) + 1
    shares = {a: threads or max(1, n // per_host[urlparse(a).hostname or a])
              for a, n in host_cores.items()}
    client.register_plugin(WorkerSetup(shares))
    return max(1, len(host_cores))
