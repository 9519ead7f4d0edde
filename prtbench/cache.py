"""Content-addressed artifact cache with atomic writes.

Artifacts (transfer vectors, projected lights, references, atlases) are stored under
``$PRTBENCH_CACHE`` (default ``~/.cache/prtbench``) at ``<kind>/<key>.<ext>`` where ``key`` is a
SHA-256 of everything the artifact depends on. Files are written to a temporary name in the same
directory and renamed into place, so an interrupted write never leaves a usable partial file.
NumPy artifacts are ``.npz`` files with a checksum entry that is verified on load; a corrupt
file is removed and recomputed, never used.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np


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
    """Load an ``.npz`` written by :func:`save_arrays`; ``None`` if missing or corrupt."""
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
    return arrays


def cached_arrays(kind: str, key: str, compute: Callable[[], Mapping[str, np.ndarray]], *,
                  use_cache: bool = True) -> dict[str, np.ndarray]:
    """Return the arrays cached under ``kind/key``, computing and storing them if absent."""
    path = cache_root() / kind / f"{key}.npz"
    if use_cache:
        hit = load_arrays(path)
        if hit is not None:
            return hit
    arrays = {k: np.asarray(v) for k, v in compute().items()}
    if use_cache:
        save_arrays(path, arrays)
    return arrays
