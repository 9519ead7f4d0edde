"""Precompute on every core it is given: chunks of ray work on a thread pool (DESIGN.md §8).

Embree releases the GIL while it traces, and so does numpy in its large array operations, so
threads (not processes) parallelise precompute: the scene's BVH is shared, nothing is pickled.
Every tracer user cuts its work into chunks of points whose boundaries depend only on the
problem (never on the thread count), computes each chunk with :func:`map_chunks` and reduces the
results in chunk order. A chunk's random numbers come from per-point or per-chunk seeds, so the
result is bit-identical whatever the number of threads and whichever thread ran a chunk.

The thread count comes from ``PRTBENCH_THREADS`` (default: every core this process may run
on). Sweep workers set it to their share of the machine, so that concurrent workers do not
oversubscribe the cores. Inside a worker thread, nested :func:`map_chunks` calls run inline:
a chunk function that calls the tracer does not start a second pool.

numpy's OpenBLAS is held to one thread meanwhile: its helper threads would compete with the
tracing threads for the (small) products and keep spinning after them.
"""

from __future__ import annotations

import ctypes
import glob
import os
import platform
import sys
import threading
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Sized
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import contextmanager
from functools import lru_cache
from typing import TypeVar

import numpy as np

from prtbench.api.errors import InvalidInputError

#: The environment variable holding the thread count.
THREADS_VARIABLE = "PRTBENCH_THREADS"

#: Largest accepted thread count (bounds the chunks held in memory at once).
MAX_THREADS = 256

T = TypeVar("T")
R = TypeVar("R")

_local = threading.local()


def available_cores() -> int:
    """Cores this process may run on (its CPU affinity; ``os.cpu_count()`` where unknown)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def thread_count() -> int:
    """Threads precompute may use: ``PRTBENCH_THREADS``, or :func:`available_cores` if unset.

    Raises
    ------
    InvalidInputError
        If the variable is set to anything but an integer 1..MAX_THREADS (an empty value
        counts as unset).
    """
    raw = os.environ.get(THREADS_VARIABLE)
    if raw is None or not raw.strip():
        return available_cores()
    text = raw.strip()
    value = int(text) if text.isdecimal() else None
    if value is None or not 1 <= value <= MAX_THREADS:
        raise InvalidInputError(
            f"{THREADS_VARIABLE}={raw!r}; accepted: an integer 1..{MAX_THREADS} (threads for "
            f"precompute ray tracing), or unset for all {available_cores()} usable cores")
    return value


def in_worker() -> bool:
    """Whether the calling thread is one of :func:`map_chunks`'s workers."""
    return getattr(_local, "worker", False)


# --- BLAS threads -------------------------------------------------------------------------------

@lru_cache(maxsize=1)
def _openblas_threads() -> tuple[Callable[[], int], Callable[[int], None]] | None:
    """(get, set) of the thread count of numpy's bundled OpenBLAS, or None if not found."""

    libs = os.path.join(os.path.dirname(np.__file__), os.pardir, "numpy.libs")
    for path in glob.glob(os.path.join(libs, "libscipy_openblas*.so*")):
        try:
            lib = ctypes.CDLL(path)  # the copy numpy already loaded: dlopen shares it
        except OSError:
            continue
        for suffix in ("64_", "", "_64_"):
            get = getattr(lib, f"scipy_openblas_get_num_threads{suffix}", None)
            put = getattr(lib, f"scipy_openblas_set_num_threads{suffix}", None)
            if get is not None and put is not None:
                get.restype, put.argtypes = ctypes.c_int, [ctypes.c_int]
                return get, put
    return None


_settings_lock = threading.Lock()
_blas_users = 0
_blas_previous: int | None = None
_switch_users = 0
_switch_previous: float | None = None

#: GIL switch interval (s) while a pool runs. A thread coming back from embree waits for the
#: GIL while another one runs numpy; at Python's default 5 ms it can wait that long per chunk.
POOL_SWITCH_INTERVAL = 0.0005


@contextmanager
def single_threaded_blas() -> Iterator[None]:
    """Run numpy's BLAS on one thread meanwhile (a no-op where it is not OpenBLAS).

    The setting is process-wide: overlapping uses (from several threads or nested) are counted,
    and the first one's previous thread count is restored when the last one ends.
    """
    global _blas_users, _blas_previous
    threads = _openblas_threads()
    if threads is None:
        yield
        return
    get, put = threads
    with _settings_lock:
        if _blas_users == 0:
            _blas_previous = get()
            put(1)
        _blas_users += 1
    try:
        yield
    finally:
        with _settings_lock:
            _blas_users -= 1
            if _blas_users == 0 and _blas_previous is not None:
                put(_blas_previous)
                _blas_previous = None


@contextmanager
def _short_switch_interval() -> Iterator[None]:
    """GIL switch interval at :data:`POOL_SWITCH_INTERVAL` meanwhile (counted, restored)."""
    global _switch_users, _switch_previous
    with _settings_lock:
        if _switch_users == 0:
            _switch_previous = sys.getswitchinterval()
            sys.setswitchinterval(min(_switch_previous, POOL_SWITCH_INTERVAL))
        _switch_users += 1
    try:
        yield
    finally:
        with _settings_lock:
            _switch_users -= 1
            if _switch_users == 0 and _switch_previous is not None:
                sys.setswitchinterval(_switch_previous)
                _switch_previous = None


class Scratch:
    """Reusable per-thread work buffers for the chunks of one :func:`map_chunks` loop.

    Fresh large arrays for every chunk cost page faults (and the kernel serialises them between
    threads); each thread here keeps its own buffers, grown as needed, until the object goes.
    A buffer is only valid until the same thread asks for the same name again: never return it.
    """

    def __init__(self) -> None:
        self._local = threading.local()

    def get(self, name: str, shape: tuple[int, ...], dtype) -> np.ndarray:
        """An uninitialised array of ``shape`` and ``dtype``, this thread's buffer ``name``."""
        dtype = np.dtype(dtype)
        size = int(np.prod(shape))
        buf = getattr(self._local, name, None)
        if buf is None or buf.dtype != dtype or buf.size < size:
            buf = np.empty(size, dtype)
            setattr(self._local, name, buf)
        return buf[:size].reshape(shape)


def repeat_rows(rows: np.ndarray, count: int, *, out: np.ndarray) -> np.ndarray:
    """``np.repeat(rows, count, axis=0)`` written into ``out`` (shape (len(rows)·count, C)).

    Rows are copied as opaque records, which is faster than numpy's broadcasting copy.
    """
    rows = np.ascontiguousarray(rows)
    record = np.dtype((np.void, rows.dtype.itemsize * rows.shape[1]))
    target = out.reshape(len(rows), count, rows.shape[1])
    target.view(record)[..., 0] = rows.view(record)
    return out


# --- freed memory --------------------------------------------------------------------------------

#: glibc's mallopt parameters and the values its adaptive thresholds grow to on 64-bit Linux.
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
_MMAP_THRESHOLD_BYTES, _TRIM_THRESHOLD_BYTES = 32 << 20, 64 << 20


@lru_cache(maxsize=1)
def keep_freed_memory() -> bool:
    """Let glibc reuse freed chunk arrays instead of returning them to the kernel (once).

    Every chunk allocates and frees arrays of a few MB. glibc maps such blocks afresh and
    unmaps them on free, or trims them off the heap, so each chunk pays a page fault per 4 KiB
    (expensive under virtualisation: 12 % of the CPU time of a transfer chunk on this machine,
    twice that with two threads). glibc raises these thresholds itself as it sees large blocks
    freed, up to 32 MiB (mmap) and 64 MiB (trim); this pins them there from the start, for
    every thread's arena. Returns whether it applied (glibc only; a no-op elsewhere).
    """

    if platform.system() != "Linux" or platform.libc_ver()[0] != "glibc":
        return False
    try:
        mallopt = ctypes.CDLL("libc.so.6").mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    return bool(mallopt(_M_MMAP_THRESHOLD, _MMAP_THRESHOLD_BYTES)
                and mallopt(_M_TRIM_THRESHOLD, _TRIM_THRESHOLD_BYTES))


# --- chunks on a pool ---------------------------------------------------------------------------

def _run_as_worker(fn: Callable[[T], R], item: T) -> R:
    _local.worker = True
    try:
        return fn(item)
    finally:
        _local.worker = False


def map_chunks(fn: Callable[[T], R], chunks: Iterable[T], *,
               threads: int | None = None) -> Iterator[R]:
    """``fn(chunk)`` for every chunk, computed on a thread pool, yielded in chunk order.

    At most two chunks per thread are in flight (submitted or finished but not yet consumed),
    which bounds memory while keeping every thread busy. With one thread, a single chunk, or
    when called from a worker thread of another :func:`map_chunks`, chunks run inline in the
    calling thread (a single chunk's own tracer queries are then split across the threads).
    numpy's BLAS runs single-threaded until the iterator is exhausted or closed.

    Parameters
    ----------
    fn : callable
        Computes one chunk. It must not depend on which thread runs it or on the order in
        which chunks run (seed per chunk or per point), so the results are those of one thread.
    chunks : iterable
        The chunk descriptions (typically slices of points), consumed lazily.
    threads : int, optional
        Pool size (default: :func:`thread_count`, from ``PRTBENCH_THREADS``).

    Yields
    ------
    ``fn(chunk)`` for each chunk, in the order of ``chunks``.

    Raises
    ------
    The first exception raised by ``fn``, in chunk order; chunks not yet started are
    cancelled and running ones are waited for.
    """
    n = thread_count() if threads is None else int(threads)  # bad values fail here, eagerly
    if isinstance(chunks, Sized) and len(chunks) <= 1:
        n = 1  # one chunk: run it here, so that the tracer inside it may use the threads
    return _mapped(fn, chunks, n)


def _mapped(fn: Callable[[T], R], chunks: Iterable[T], n: int) -> Iterator[R]:
    keep_freed_memory()
    with single_threaded_blas():
        if n <= 1 or in_worker():
            for chunk in chunks:
                yield fn(chunk)
            return
        upcoming = iter(chunks)
        queued: deque[Future] = deque()
        with _short_switch_interval(), \
                ThreadPoolExecutor(max_workers=n, thread_name_prefix="prtbench-trace") as pool:
            def submit() -> None:
                chunk = next(upcoming, _END)
                if chunk is not _END:
                    queued.append(pool.submit(_run_as_worker, fn, chunk))

            try:
                for _ in range(2 * n):
                    submit()
                while queued:
                    result = queued.popleft().result()
                    submit()
                    yield result
            finally:
                for future in queued:
                    future.cancel()


_END = object()


def parallel_chunks(n_items: int, items_per_chunk: int) -> list[slice]:
    """Consecutive slices of at most ``items_per_chunk`` items covering ``range(n_items)``.

    The boundaries depend only on the two counts, never on the thread count.
    """
    step = max(1, int(items_per_chunk))
    return [slice(s, min(s + step, n_items)) for s in range(0, int(n_items), step)]
