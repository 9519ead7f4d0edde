"""What the cache holds: its kinds, its entries, their sizes and last use.

Kinds and entries
    A *kind* is a top-level folder of the cache (``artifacts``, ``transfer``, ``references``,
    ``renders``, ``site-images``, ``assets``, ...). An *entry* is what is removed as one: a
    file together with its sidecars (``<key>.npz`` and its ``<key>.time.json``, an artifact's
    ``<key>.npz`` and its ``<key>.json`` build record, leftover ``.<key>.npz.*.tmp`` writes),
    grouped by :func:`prtbench.api.cache.entry_key`; or a folder directly under its kind (one
    run's ``renders/<run_id>/``, one asset, one set of generated shader includes).
    ``artifacts/`` has one more level, a folder per method, whose files are the entries.
    ``.locks/`` is bookkeeping, not an entry; files directly in the cache root are no kind's.
Last use
    An entry's last use is the newest mtime of its files: set when it is written and touched
    on every hit (:func:`prtbench.api.cache.record_use`).

Removing entries and the size cap are :mod:`prtbench.api.cache_size`.
"""

from __future__ import annotations

import os
import time
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from prtbench.api.cache import cache_root, entry_key, entry_name

#: Kinds the cap never evicts (pinned downloads: fetching them again needs the network).
PINNED_KINDS = ("assets",)
#: Kinds with one level of folders (one per method) above their entries.
NAMESPACED_KINDS = ("artifacts",)
#: A temporary file younger than this is a write in progress (writes rename their file into
#: place within seconds, the largest in well under a minute); an older one is a leftover of
#: a killed process and goes with its entry.
TEMP_GRACE_S = 3600.0


@dataclass(frozen=True)
class Entry:
    """One removable unit of the cache.

    Attributes
    ----------
    kind : str
        Its top-level folder.
    name : str
        Its path under the cache root, up to the first dot (``transfer/<key>``,
        ``artifacts/<method>/<key>``, ``renders/<run_id>``).
    path : Path
        What its lock is named after (:func:`prtbench.api.cache.entry_name`; a folder entry's
        folder).
    files : tuple of Path
        Its files; a folder entry: the folder alone.
    bytes : int
        Apparent size of its files, in bytes.
    last_use : float
        Newest mtime of its files, seconds since the epoch.
    writing : bool
        It has a temporary file younger than :data:`TEMP_GRACE_S`: a write is in progress.
    folder : bool
        A folder entry (removed whole).
    """

    kind: str
    name: str
    path: Path
    files: tuple[Path, ...]
    bytes: int
    last_use: float
    writing: bool = False
    folder: bool = False


@dataclass(frozen=True)
class KindUsage:
    """What one kind holds.

    Attributes
    ----------
    kind : str
    entries : int
    bytes : int
    oldest_use, newest_use : float or None
        Last use of its least and most recently used entries (None: no entries).
    pinned : bool
        Never evicted by the cap (:data:`PINNED_KINDS`).
    """

    kind: str
    entries: int
    bytes: int
    oldest_use: float | None
    newest_use: float | None
    pinned: bool


def is_temp(name: str) -> bool:
    """A write in progress (or left by a killed process): :func:`atomic_path`'s names."""
    return name.startswith(".") and name.endswith(".tmp")


def _file_entry(kind: str, folder: Path, prefix: str, stem: str,
                files: list[tuple[str, os.stat_result]], now: float) -> Entry:
    return Entry(
        kind=kind, name=f"{prefix}{stem}", path=folder / stem,
        files=tuple(folder / name for name, _ in sorted(files, key=lambda f: f[0])),
        bytes=sum(st.st_size for _, st in files), last_use=max(st.st_mtime for _, st in files),
        writing=any(is_temp(name) and now - st.st_mtime < TEMP_GRACE_S for name, st in files))


def folder_entry(kind: str, root: Path, folder: Path, now: float) -> Entry | None:
    """The folder entry ``folder`` of ``kind`` (named relative to ``root``), as it is now;
    None if it is gone."""
    size, newest, writing = 0, None, False
    for parent, _, names in os.walk(folder):
        for name in names:
            try:
                st = os.lstat(os.path.join(parent, name))
            except OSError:  # removed meanwhile
                continue
            size += st.st_size
            newest = st.st_mtime if newest is None else max(newest, st.st_mtime)
            writing = writing or (is_temp(name) and now - st.st_mtime < TEMP_GRACE_S)
    if newest is not None:
        last_use = newest
    else:  # an empty folder: when it was made (or emptied)
        try:
            last_use = folder.stat(follow_symlinks=False).st_mtime
        except OSError:  # removed meanwhile
            return None
    return Entry(kind=kind, name=entry_name(folder).relative_to(root).as_posix(), path=folder,
                 files=(folder,), bytes=size, last_use=last_use, writing=writing, folder=True)


def _scan_folder(kind: str, root: Path, folder: Path, *, namespaced: bool,
                 now: float) -> list[Entry]:
    """The entries of one kind folder (or, for :data:`NAMESPACED_KINDS`, of one namespace)."""
    entries: list[Entry] = []
    # Grouped by name strings, not Paths: a cache holds tens of thousands of files.
    groups: dict[str, list[tuple[str, os.stat_result]]] = {}
    prefix = folder.relative_to(root).as_posix() + "/"
    try:
        items = sorted(os.scandir(folder), key=lambda item: item.name)
    except OSError:
        return entries
    for item in items:
        try:
            if item.is_dir(follow_symlinks=False):
                if namespaced:
                    entries += _scan_folder(kind, root, Path(item.path), namespaced=False, now=now)
                elif (entry := folder_entry(kind, root, Path(item.path), now)) is not None:
                    entries.append(entry)
                continue
            st = item.stat(follow_symlinks=False)
        except OSError:  # removed meanwhile
            continue
        groups.setdefault(entry_key(item.name), []).append((item.name, st))
    entries += [_file_entry(kind, folder, prefix, stem, files, now)
                for stem, files in groups.items()]
    return entries


def bytes_under(path: str) -> int:
    """Apparent size of the files under ``path``: a third of a full :func:`scan`'s time (the
    fast path of :func:`prtbench.api.cache_size.enforce_cap`)."""
    total = 0
    try:
        with os.scandir(path) as items:
            for item in items:
                try:
                    if item.is_dir(follow_symlinks=False):
                        total += bytes_under(item.path)
                    else:
                        total += item.stat(follow_symlinks=False).st_size
                except OSError:  # removed meanwhile
                    continue
    except OSError:
        pass
    return total


def list_kinds(*, root: Path | None = None) -> list[str]:
    """The kinds of the cache: its top-level folders (``.locks`` and other hidden ones left
    out), in name order, empty ones included."""
    root = Path(root) if root is not None else cache_root()
    try:
        return sorted(p.name for p in root.iterdir()
                      if not p.name.startswith(".") and p.is_dir() and not p.is_symlink())
    except OSError:  # no cache yet
        return []


def scan(*, root: Path | None = None, now: float | None = None) -> list[Entry]:
    """Every entry of the cache, by kind and name (``.locks/`` and root files left out).

    Parameters
    ----------
    root : Path, optional
        The cache root (default :func:`prtbench.api.cache.cache_root`).
    now : float, optional
        The time temporary files are aged against (default: now).
    """
    root = Path(root) if root is not None else cache_root()
    now = time.time() if now is None else now
    entries: list[Entry] = []
    for kind in list_kinds(root=root):
        entries += _scan_folder(kind, root, root / kind, namespaced=kind in NAMESPACED_KINDS,
                                now=now)
    return sorted(entries, key=lambda e: (e.kind, e.name))


def usage(entries: Iterable[Entry], *, kinds: Iterable[str] = ()) -> list[KindUsage]:
    """Per kind, in name order: entry count, bytes, oldest and newest last use.

    ``kinds`` adds kinds that may hold no entry (:func:`list_kinds`), listed with zeros.
    """
    by_kind: dict[str, list[Entry]] = {kind: [] for kind in kinds}
    for entry in entries:
        by_kind.setdefault(entry.kind, []).append(entry)
    return [KindUsage(kind, len(group), sum(e.bytes for e in group),
                      min((e.last_use for e in group), default=None),
                      max((e.last_use for e in group), default=None), kind in PINNED_KINDS)
            for kind, group in sorted(by_kind.items())]
