"""The cache's size: a cap enforced by least-recently-used eviction, and pruning.

Nothing in :mod:`prtbench.api.cache` ever removes an entry, and one ``make demo`` leaves about
1.2 GB behind. This module bounds it; what an entry and its last use are is
:mod:`prtbench.api.cache_scan`.

The cap
    ``$PRTBENCH_CACHE_MAX`` (default :data:`DEFAULT_CAP_BYTES`, 20 GiB; ``0`` or ``none``
    disables it) bounds every kind but :data:`~prtbench.api.cache_scan.PINNED_KINDS`
    (``assets``: pinned downloads, removed only by ``prtbench cache prune --kind assets``),
    which count toward neither the cap nor ``--max-size``. :func:`enforce_cap` runs once
    before the work of every submit and evicts least recently used entries until the rest fits.
Safety
    An entry is removed only while this process holds its lock, taken without waiting
    (:func:`prtbench.api.cache.try_entry_lock`); an entry another process holds (it is being
    computed) is kept, and so is one with a fresh temporary file (an unlocked writer, such as
    a run storing its renders, is at work) or one used since it was chosen. Files are unlinked
    whole, the data first and its sidecars after, so a reader finds a complete entry or none
    (a sidecar left alone by a kill is its own entry next time); a folder entry is renamed
    aside before it is deleted, so it is never seen half removed.
"""

from __future__ import annotations

import math
import os
import re
import shutil
import sys
import time
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from prtbench.api.cache import cache_root, try_entry_lock
from prtbench.api.cache_scan import (
    PINNED_KINDS,
    Entry,
    bytes_under,
    folder_entry,
    is_temp,
    list_kinds,
    scan,
)
from prtbench.api.config import format_bytes
from prtbench.api.errors import InvalidInputError, UnknownNameError

#: The variable that sets the cap.
CAP_VARIABLE = "PRTBENCH_CACHE_MAX"
#: The cap when the variable is unset: a few demos' worth (one ``make demo`` leaves ~1.2 GB).
DEFAULT_CAP_BYTES = 20 << 30
#: Values of the variable that disable the cap (besides a size of 0).
CAP_OFF = ("none", "off")
#: Size units and their bytes: decimal (kB = 1000) and binary (KiB = 1024), as the user writes
#: them; matched without regard to case.
SIZE_UNITS: dict[str, int] = {
    "B": 1, "kB": 10 ** 3, "MB": 10 ** 6, "GB": 10 ** 9, "TB": 10 ** 12,
    "KiB": 1 << 10, "MiB": 1 << 20, "GiB": 1 << 30, "TiB": 1 << 40}
_SIZE = re.compile(r"\s*(\d+(?:\.\d*)?|\.\d+)\s*([A-Za-z]*)\s*")


@dataclass
class Pruned:
    """What a prune or an eviction did.

    Attributes
    ----------
    removed : list of Entry
        Entries removed, in the order removed.
    kept : list of Entry
        Entries chosen but left in place: held by another process, being written, or used
        since they were chosen.
    """

    removed: list[Entry] = field(default_factory=list)
    kept: list[Entry] = field(default_factory=list)

    @property
    def bytes_removed(self) -> int:
        return sum(e.bytes for e in self.removed)


# --- sizes and the cap -------------------------------------------------------------------------

def parse_size(text: str, *, option: str) -> int:
    """Bytes of a size written as ``2GiB``, ``500MB``, ``1.5 GiB`` or ``1048576``.

    Parameters
    ----------
    text : str
        A non-negative number and an optional unit of :data:`SIZE_UNITS` (any case).
    option : str
        Where the value came from (``--max-size``, ``$PRTBENCH_CACHE_MAX``), for the message.

    Raises
    ------
    InvalidInputError
        Not such a size (one line naming ``text`` and what is accepted).
    """
    match = _SIZE.fullmatch(str(text))
    units = {u.lower(): factor for u, factor in SIZE_UNITS.items()}
    if match is None or (match.group(2) and match.group(2).lower() not in units):
        raise InvalidInputError(
            f"{option} '{text}'; accepted: a size such as 20GiB, 500MB or 1048576 (units "
            f"{', '.join(SIZE_UNITS)})")
    value = float(match.group(1)) * units[match.group(2).lower() or "b"]
    return round(value)


def cache_cap() -> int | None:
    """The cap in force, in bytes (``$PRTBENCH_CACHE_MAX``, default 20 GiB); None: no cap.

    Raises
    ------
    InvalidInputError
        The variable holds neither a size nor ``none``.
    """
    text = os.environ.get(CAP_VARIABLE, "").strip()
    if not text:
        return DEFAULT_CAP_BYTES
    if text.lower() in CAP_OFF:
        return None
    try:
        value = parse_size(text, option=f"${CAP_VARIABLE}")
    except InvalidInputError as exc:
        raise InvalidInputError(f"{exc}, or 0 or none for no cap") from None
    return value or None


def describe_cap(cap: int | None) -> str:
    """The cap for a person: ``20.0 GiB (default)``, ``none ($PRTBENCH_CACHE_MAX=0)``."""
    set_to = os.environ.get(CAP_VARIABLE, "").strip()
    source = (f"${CAP_VARIABLE}={set_to}" if set_to
              else f"default; ${CAP_VARIABLE} sets it, 0 or none for no cap")
    return f"{format_bytes(cap) if cap is not None else 'none'} ({source})"


# --- removing ----------------------------------------------------------------------------------

def _removal_order(path: Path) -> int:
    # The data first, then its records, then leftover temporary files: a reader that does not
    # lock finds a complete entry (data and records) or no data at all.
    if is_temp(path.name):
        return 2
    return 1 if path.name.endswith(".json") else 0


def _used_since(entry: Entry) -> bool:
    """An entry file was touched (a hit) or rewritten after the entry was chosen."""
    if entry.folder:
        current = folder_entry(entry.kind, entry.path.parent, entry.path, time.time())
        return current is not None and current.last_use > entry.last_use
    for path in entry.files:
        try:
            if path.stat(follow_symlinks=False).st_mtime > entry.last_use:
                return True
        except OSError:
            continue
    return False


def _delete(entry: Entry) -> None:
    if entry.folder:
        folder = entry.path
        # Renamed aside first (atomic): nobody sees a half-removed folder under its name, and
        # a kill midway leaves a hidden leftover that the next eviction removes.
        aside = folder if folder.name.startswith(".") else \
            folder.with_name(f".{folder.name}.evicting.tmp")
        try:
            if aside != folder:
                os.replace(folder, aside)
        except FileNotFoundError:
            return
        shutil.rmtree(aside, ignore_errors=True)
        return
    for path in sorted(entry.files, key=_removal_order):
        path.unlink(missing_ok=True)


def remove_entry(entry: Entry) -> bool:
    """Remove ``entry`` if no other process holds it; False (nothing removed) otherwise.

    Taken under its lock without waiting; an entry being written or used since it was
    scanned is left in place.
    """
    if entry.writing:
        return False
    with try_entry_lock(entry.path) as held:
        if not held or _used_since(entry):
            return False
        _delete(entry)
    return True


def evict_lru(entries: Sequence[Entry], *, max_bytes: int,
              held: Iterable[Entry] = ()) -> Pruned:
    """Remove least recently used ``entries`` until those left take at most ``max_bytes``.

    Entries that cannot be removed now (:func:`remove_entry`) are kept and the next least
    recently used is taken instead, so the total may stay above ``max_bytes`` only when what
    is left is in use. ``held``: entries among them already found in use (counted, not tried
    again).
    """
    pruned = Pruned()
    total = sum(e.bytes for e in entries)
    skip = {e.name for e in held}
    for entry in sorted(entries, key=lambda e: (e.last_use, e.name)):
        if total <= max_bytes:
            break
        if entry.name in skip:
            continue
        if remove_entry(entry):
            pruned.removed.append(entry)
            total -= entry.bytes
        else:
            pruned.kept.append(entry)
    return pruned


def prune(*, max_bytes: int | None = None, older_than_days: float | None = None,
          kind: str | None = None, root: Path | None = None, now: float | None = None) -> Pruned:
    """Remove entries by age, by size (least recently used first) or by kind.

    Parameters
    ----------
    max_bytes : int, optional
        Evict least recently used entries in scope until the scope takes at most this.
    older_than_days : float, optional
        Remove the entries in scope last used more than this many days ago (first).
    kind : str, optional
        The scope: one kind (``assets`` included). Default: every kind but
        :data:`PINNED_KINDS`.
    root : Path, optional
        The cache root (default :func:`prtbench.api.cache.cache_root`).
    now : float, optional
        The time ages are counted from (default: now).

    With neither ``max_bytes`` nor ``older_than_days``, a ``kind`` is removed whole and
    without one the cap in force applies (:func:`cache_cap`; nothing when it is off).

    Raises
    ------
    InvalidInputError, UnknownNameError
        A negative or non-finite value, a kind not in the cache, or a bad cap; checked before
        anything is removed.
    """
    if max_bytes is not None and max_bytes < 0:
        raise InvalidInputError(f"max size {max_bytes}; accepted: 0 bytes or more")
    if older_than_days is not None and not (math.isfinite(older_than_days)
                                            and older_than_days >= 0):
        raise InvalidInputError(f"older than {older_than_days} days; accepted: a number of "
                                "days, 0 or more")
    if max_bytes is None and older_than_days is None:
        max_bytes = 0 if kind is not None else cache_cap()
        if max_bytes is None:
            return Pruned()
    now = time.time() if now is None else now
    entries = scan(root=root, now=now)
    if kind is not None:
        known = list_kinds(root=root)
        if kind not in known:
            raise UnknownNameError("cache kind", kind, known)
        scope = [e for e in entries if e.kind == kind]
    else:
        scope = [e for e in entries if e.kind not in PINNED_KINDS]
    pruned = Pruned()
    if older_than_days is not None:
        cutoff = now - older_than_days * 86400.0
        for entry in sorted(scope, key=lambda e: (e.last_use, e.name)):
            if entry.last_use < cutoff:
                (pruned.removed if remove_entry(entry) else pruned.kept).append(entry)
    if max_bytes is not None:
        gone = {e.name for e in pruned.removed}
        by_size = evict_lru([e for e in scope if e.name not in gone], max_bytes=max_bytes,
                            held=pruned.kept)
        pruned.removed += by_size.removed
        pruned.kept += by_size.kept
    return pruned


def enforce_cap(*, root: Path | None = None) -> Pruned:
    """Evict least recently used entries until the cache fits the cap (:func:`cache_cap`).

    What every submit calls once before its work; says on stderr, in one line, what it
    evicted (nothing when the cache fits or the cap is off).

    Raises
    ------
    InvalidInputError
        ``$PRTBENCH_CACHE_MAX`` is not a size (nothing is removed).
    """
    cap = cache_cap()
    if cap is None:
        return Pruned()
    root = Path(root) if root is not None else cache_root()
    capped = [kind for kind in list_kinds(root=root) if kind not in PINNED_KINDS]
    # Sizes alone first: most runs find the cache under its cap.
    if sum(bytes_under(str(root / kind)) for kind in capped) <= cap:
        return Pruned()
    entries = [e for e in scan(root=root) if e.kind not in PINNED_KINDS]
    total = sum(e.bytes for e in entries)
    pruned = evict_lru(entries, max_bytes=cap)
    left = total - pruned.bytes_removed
    held = f"; {len(pruned.kept)} in use kept" if pruned.kept else ""
    count = len(pruned.removed)
    print(f"[prtbench] cache {format_bytes(total)} over its cap {describe_cap(cap)}: evicted "
          f"the {count} least recently used entr{'y' if count == 1 else 'ies'} "
          f"({format_bytes(pruned.bytes_removed)}), {format_bytes(left)} left{held}",
          file=sys.stderr, flush=True)
    return pruned
