"""Output locations checked before any work (DESIGN.md §10).

A run writes to its ``--out`` folder, its ``--json`` file, the results store and the cache;
a table or figure to ``--reports`` and the store. Each is checked here, before the precompute,
so a bad location is a one-line error (naming the option, the path and the reason) instead of
a traceback after minutes of work. The checks write nothing that stays: writability is
proven by creating and removing a small temporary file in the nearest existing folder, which
catches read-only and full file systems that permission bits (ignored by root) do not.
"""

from __future__ import annotations

import errno
import os
import tempfile
from pathlib import Path

from prtbench.api.cache import cache_root
from prtbench.api.errors import InvalidInputError, PrtbenchError
from prtbench.store.results import ResultsStore

#: Bytes the write probe writes and syncs: enough to meet ENOSPC on a full file system.
_PROBE_BYTES = 4096


def _nearest_existing(path: Path) -> Path:
    """``path`` or its closest ancestor that exists (a relative path ends at the cwd)."""
    path = Path(os.path.abspath(path))
    while not path.exists() and path != path.parent:
        path = path.parent
    return path


def _probe_write(option: str, shown: Path, folder: Path) -> None:
    """Create, write, sync and remove a temporary file in ``folder``."""
    try:
        fd, name = tempfile.mkstemp(prefix=".prtbench-probe-", dir=folder)
    except OSError as exc:
        raise InvalidInputError(f"{option} '{shown}': cannot create files in '{folder}' "
                                f"({os.strerror(exc.errno or errno.EIO)})") from None
    try:
        os.write(fd, b"\0" * _PROBE_BYTES)
        os.fsync(fd)
    except OSError as exc:
        raise InvalidInputError(f"{option} '{shown}': cannot write in '{folder}' "
                                f"({os.strerror(exc.errno or errno.EIO)})") from None
    finally:
        os.close(fd)
        os.unlink(name)
    # The probe can succeed where later writes would not (an access rule for new names).
    if not os.access(folder, os.W_OK | os.X_OK):
        raise InvalidInputError(f"{option} '{shown}': folder '{folder}' is not writable")


def _check_folder(option: str, shown: Path, path: Path) -> None:
    existing = _nearest_existing(path)
    if not existing.is_dir():
        where = ("is a file" if existing == Path(os.path.abspath(path)) and shown == path
                 else f"is under the file '{existing}'")
        raise InvalidInputError(f"{option} '{shown}' {where}; accepted: "
                                f"{'a folder (existing or creatable)' if shown == path else 'a path in a folder'}")
    _probe_write(option, shown, existing)


def check_folder(option: str, path: str | Path) -> None:
    """Raise :class:`InvalidInputError` unless ``path`` is, or can be created as, a writable folder.

    Parameters
    ----------
    option : str
        How the user gave it (``--out``, ``$PRTBENCH_CACHE``), for the message.
    path : str or Path
        The folder; missing folders are not created here.
    """
    _check_folder(option, Path(path), Path(path))


def check_file(option: str, path: str | Path) -> None:
    """Raise :class:`InvalidInputError` unless ``path`` can be written as a file.

    The file is written atomically (a temporary file renamed into place), so what must be
    writable is its folder; a folder at ``path`` itself is an error.
    """
    path = Path(path)
    if path.is_dir():
        raise InvalidInputError(f"{option} '{path}' is a folder; accepted: a file path in a writable folder")
    _check_folder(option, path, Path(os.path.abspath(path)).parent)


def check_file_clear_of(option: str, path: str | Path, *, folder_option: str,
                        folder: str | Path) -> None:
    """Raise :class:`InvalidInputError` if the file ``path`` is the folder ``folder`` that the
    command makes before it writes the file, or a folder above it.

    Each passes its own check while neither exists (:func:`check_file`, :func:`check_folder`);
    then the file's write meets a folder, after all the work.
    """
    file, made = Path(os.path.realpath(path)), Path(os.path.realpath(folder))
    if file == made or file in made.parents:
        where = "is" if file == made else "is above"
        raise InvalidInputError(f"{option} '{path}' {where} the {folder_option} folder "
                                f"'{folder}', which the command makes for its files; accepted: "
                                f"a file path, e.g. '{Path(folder) / 'run.json'}'")


def check_results_store(option: str, path: str | Path) -> None:
    """``path`` can hold the results store: writable, and absent or a store of our schema."""

    check_file(option, path)
    try:
        ResultsStore(path).check()
    except PrtbenchError as exc:
        raise InvalidInputError(f"{option}: {exc}") from None


def check_cache() -> None:
    """The cache root (``$PRTBENCH_CACHE`` or ``~/.cache/prtbench``) is a writable folder."""

    option = "$PRTBENCH_CACHE" if os.environ.get("PRTBENCH_CACHE") else "the cache folder"
    check_folder(option, cache_root())
