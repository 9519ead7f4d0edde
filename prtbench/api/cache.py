"""Content-addressed artifact cache with atomic writes.

Artifacts (transfer vectors, projected lights, references, atlases) are stored under
``$PRTBENCH_CACHE`` (default ``~/.cache/prtbench``) at ``<kind>/<key>.<ext>`` where ``key`` is a
SHA-256 of everything the artifact depends on. Files are written to a temporary name in the same
directory and renamed into place, so an interrupted write never leaves a usable partial file.
NumPy artifacts are ``.npz`` files with a checksum entry that is verified on load; a corrupt
file is removed and recomputed, never used.

Concurrent processes (sweep workers, ``pytest -n 2`` workers sharing one cache) compute an
entry once: :func:`entry_lock` is an exclusive inter-process lock per entry, and a process
that finds an entry missing takes it, looks again, and only then computes.

Every hit marks its entry as used (:func:`record_use`, the file's mtime), so the size cap
of :mod:`prtbench.api.cache_size` evicts the least recently used entries first.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import tempfile
import threading
import time
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
from filelock import FileLock, Timeout


def cache_root() -> Path:
    """The cache directory (``$PRTBENCH_CACHE`` or ``~/.cache/prtbench``)."""
    return Path(os.environ.get("PRTBENCH_CACHE", Path.home() / ".cache" / "prtbench"))


def _canonical(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        return {"__ndarray__": hashlib.sha256(np.ascontiguousarray(obj).tobytes()).hexdigest(),
                "dtype": str(obj.dtype), "shape": list(obj.shape)}
    if isinstance(obj, Mapping):
        return {str(k): _canonical(v) for k, v in sorted(obj.items(), key=lambda kv: str(kv[0]))}
    if isinstance(obj, (list, tuple)):
        return [_canonical(v) for v in obj]
    if isinstance(obj, (np.floating, np.integer)):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    if hasattr(obj, "__dataclass_fields__"):
        return _canonical({k: getattr(obj, k) for k in obj.__dataclass_fields__})
    return obj


def content_key(*parts: Any) -> str:
    """SHA-256 hex digest of JSON-canonical ``parts`` (arrays hashed by their bytes)."""
    text = json.dumps(_canonical(list(parts)), sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


@contextmanager
def atomic_path(path: Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it into place only on success."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        os.replace(tmp_path, path)
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


def entry_key(file_name: str) -> str:
    """The key of the entry a file of that name belongs to: the name up to its first dot.

    An entry's file and its sidecars (``<key>.npz``, ``<key>.json`` build record,
    ``<key>.time.json`` compute time, ``.<key>.npz.*.tmp`` writes in progress) are one entry and
    share one lock. Keys never hold a dot (content keys are hexadecimal).
    """
    return file_name.lstrip(".").split(".", 1)[0]


def entry_name(path: Path) -> Path:
    """The entry ``path`` belongs to: its folder and :func:`entry_key` (a folder entry such as
    ``renders/<run_id>`` is named by itself)."""
    path = Path(path)
    return path.with_name(entry_key(path.name))


def _lock_path(path: Path) -> Path:
    """The lock file of the entry ``path`` belongs to, under ``<cache>/.locks/``."""
    entry = entry_name(Path(path).resolve())
    locks = cache_root().resolve() / ".locks"
    locks.mkdir(parents=True, exist_ok=True)
    return locks / f"{hashlib.sha256(str(entry).encode()).hexdigest()[:32]}.lock"


@contextmanager
def entry_lock(path: Path) -> Iterator[None]:
    """Hold the inter-process lock of the cache entry at ``path`` (blocking).

    One lock per entry (:func:`entry_name`: a file and its sidecars together). Lock files live
    apart from the entries, under ``<cache>/.locks/`` (named by a hash of the entry's path),
    and are removed on release; a reader that does not lock still sees either no entry or a
    complete one (atomic rename). filelock does not take a lock file that was unlinked while it
    waited (it opens the new one), so one process at a time holds an entry; with an older
    filelock, at worst an entry is computed twice and renamed into place twice, never read
    half-written.
    """
    lock_path = _lock_path(path)
    try:
        with FileLock(str(lock_path)):
            yield
    finally:
        _unlink_quietly(lock_path)


@contextmanager
def try_entry_lock(path: Path) -> Iterator[bool]:
    """The lock of the entry at ``path`` if no other process holds it (never waits).

    Yields True while it holds the lock, False (holding nothing) when another process holds
    it: the entry is being computed or removed, and the caller leaves it alone. Eviction
    (:mod:`prtbench.api.cache_size`) removes an entry only while holding this.
    """
    lock_path = _lock_path(path)
    lock = FileLock(str(lock_path), timeout=0)
    try:
        lock.acquire()
    except Timeout:
        yield False
        return
    try:
        yield True
    finally:
        lock.release()
        _unlink_quietly(lock_path)


def _unlink_quietly(lock_path: Path) -> None:
    try:
        lock_path.unlink()
    except OSError:  # another process holds it again, or has removed it
        pass


def record_use(path: Path) -> None:
    """Mark the cache entry file ``path`` as used now (its mtime), for LRU eviction.

    One ``utime`` call per cache hit; the access time is not used because ``noatime`` and
    ``relatime`` mounts do not keep it. A read-only cache is used as it is.
    """
    try:
        os.utime(path)
    except OSError:
        pass


def _digest(arrays: Mapping[str, np.ndarray]) -> str:
    h = hashlib.sha256()
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(name.encode())
        h.update(str(a.dtype).encode())
        h.update(str(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()


def save_arrays(path: Path, arrays: Mapping[str, np.ndarray]) -> None:
    """Atomically write ``arrays`` to an ``.npz`` with an embedded checksum."""
    arrays = {k: np.asarray(v) for k, v in arrays.items()}
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, __checksum__=np.array(_digest(arrays)), **arrays)


def load_arrays(path: Path) -> dict[str, np.ndarray] | None:
    """Load an ``.npz`` written by :func:`save_arrays`; ``None`` if missing or corrupt.

    A good load marks the entry as used (:func:`record_use`).
    """
    path = Path(path)
    if not path.exists():
        return None
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files if k != "__checksum__"}
            checksum = str(data["__checksum__"])
    except Exception:  # noqa: BLE001 - any read failure means a corrupt file
        path.unlink(missing_ok=True)
        return None
    if checksum != _digest(arrays):
        path.unlink(missing_ok=True)
        return None
    record_use(path)
    return arrays


class ComputeCredit:
    """Original compute time of the cached sub-steps a precompute reused (see
    :func:`credit_cached_compute`)."""

    def __init__(self) -> None:
        self.credited_s = 0.0
        #: Cache hits whose compute time was never recorded (entries from before the record).
        self.unknown = 0


#: Open credits, innermost last. A precompute runs its cached sub-steps on the calling thread,
#: one precompute at a time per process, so one stack (under a lock) is enough.
_CREDITS: list[ComputeCredit] = []
_CREDITS_LOCK = threading.Lock()


@contextmanager
def credit_cached_compute() -> Iterator[ComputeCredit]:
    """Collect, while open, the recorded compute time of every :func:`cached_arrays` hit.

    A precompute whose transfer (or another sub-step) comes from the cache finishes in a
    fraction of its cost; its true cost from scratch is its wall time plus these credits,
    which is what ``precompute_s`` must report (a stored row never shows the assembly time
    of cached parts as a precompute time).
    """
    credit = ComputeCredit()
    with _CREDITS_LOCK:
        _CREDITS.append(credit)
    try:
        yield credit
    finally:
        with _CREDITS_LOCK:
            _CREDITS.remove(credit)
            if _CREDITS:  # a nested precompute's reuse is its parent's reuse too
                _CREDITS[-1].credited_s += credit.credited_s
                _CREDITS[-1].unknown += credit.unknown


def _credit(seconds: float | None) -> None:
    with _CREDITS_LOCK:
        if _CREDITS:
            if seconds is None:
                _CREDITS[-1].unknown += 1
            else:
                _CREDITS[-1].credited_s += seconds


def _read_compute_time(path: Path) -> float | None:
    try:
        value = float(json.loads(path.read_text())["compute_s"])
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return value if math.isfinite(value) and value >= 0 else None


def cached_arrays(kind: str, key: str, compute: Callable[[], Mapping[str, np.ndarray]], *,
                  use_cache: bool = True) -> dict[str, np.ndarray]:
    """Return the arrays cached under ``kind/key``, computing and storing them if absent.

    The compute time (its wall time plus that of the cached sub-steps it reused) is recorded
    beside the entry (``<key>.time.json``), and a hit credits it to the open
    :func:`credit_cached_compute`, so a precompute built from cached parts reports what it
    costs from scratch.
    """
    path = cache_root() / kind / f"{key}.npz"
    time_path = path.with_name(f"{key}.time.json")
    if not use_cache:
        return _compute_entry(compute, path, time_path, store=False)
    hit = load_arrays(path)
    if hit is None:
        with entry_lock(path):  # another process may be computing it: wait, then look again
            hit = load_arrays(path)
            if hit is None:
                return _compute_entry(compute, path, time_path, store=True)
    _credit(_read_compute_time(time_path))
    return hit


def _compute_entry(compute: Callable[[], Mapping[str, np.ndarray]], path: Path, time_path: Path,
                   *, store: bool) -> dict[str, np.ndarray]:
    with credit_cached_compute() as inner:
        start = time.perf_counter()
        arrays = {k: np.asarray(v) for k, v in compute().items()}
        elapsed = time.perf_counter() - start + inner.credited_s
        unknown = inner.unknown
    if store:
        # The time first: a process that sees the entry (without the lock) finds its time too.
        if not unknown:  # a time missing parts would understate the entry's cost
            with atomic_path(time_path) as tmp:
                tmp.write_text(json.dumps({"compute_s": elapsed}))
        save_arrays(path, arrays)
    return arrays
