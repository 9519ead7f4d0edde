"""``prtbench cache``: what the cache holds (``info``) and removing entries (``prune``).

``info`` prints, per kind (top-level folder of ``$PRTBENCH_CACHE``), the entries, their size
and their oldest and newest last use, the total and the cap in force (``$PRTBENCH_CACHE_MAX``).
``prune`` removes entries by age, by size (least recently used first) or by kind and prints
each one it removed; entries another process holds are kept and listed. See
:mod:`prtbench.api.cache_scan` and :mod:`prtbench.api.cache_size`.
"""

from __future__ import annotations

import argparse
import math
import time

from prtbench.api.cache import cache_root
from prtbench.api.cache_scan import PINNED_KINDS, Entry, list_kinds, scan, usage
from prtbench.api.cache_size import (
    CAP_VARIABLE,
    cache_cap,
    describe_cap,
    parse_size,
    prune,
)
from prtbench.api.config import format_bytes
from prtbench.api.errors import InvalidInputError

HELP = "the cache: size per kind (info) and removing entries (prune)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    actions = p.add_subparsers(dest="action", required=True, metavar="ACTION")
    info = actions.add_parser("info", help="size, entries and last use per kind; the cap",
                              description="size, entries and last use per kind; the cap")
    info.add_argument("--bytes", action="store_true", help="sizes in exact bytes")
    text = ("remove entries: last used more than DAYS ago, least recently used ones until "
            "SIZE is left, or a whole KIND; with no option, down to the cap "
            f"(${CAP_VARIABLE}). Assets go only with --kind assets.")
    rm = actions.add_parser("prune", help="remove entries by age, size or kind", description=text)
    rm.add_argument("--max-size", metavar="SIZE",
                    help="evict least recently used entries until SIZE is left (2GiB, 500MB)")
    rm.add_argument("--older-than", metavar="DAYS",
                    help="remove entries last used more than DAYS days ago")
    rm.add_argument("--kind", metavar="KIND",
                    help="only this kind (a top-level folder of the cache; assets included)")
    rm.add_argument("--bytes", action="store_true", help="sizes in exact bytes")


def _size(n: int, exact: bool) -> str:
    return str(int(n)) if exact else format_bytes(n)


def _when(t: float | None) -> str:
    return time.strftime("%Y-%m-%d %H:%M", time.localtime(t)) if t is not None else "-"


def _info(args: argparse.Namespace) -> int:
    cap = cache_cap()  # a bad $PRTBENCH_CACHE_MAX is an error here too
    root = cache_root()
    kinds = usage(scan(root=root), kinds=list_kinds(root=root))
    print(f"cache: {root}")
    print(f"{'kind':<20} {'entries':>8} {'size':>12}  {'oldest use':<16}  newest use")
    for k in kinds:
        name = f"{k.kind} (pinned)" if k.pinned else k.kind
        print(f"{name:<20} {k.entries:>8} {_size(k.bytes, args.bytes):>12}  "
              f"{_when(k.oldest_use):<16}  {_when(k.newest_use)}")
    used = [k for k in kinds if k.entries]
    print(f"{'total':<20} {sum(k.entries for k in kinds):>8} "
          f"{_size(sum(k.bytes for k in kinds), args.bytes):>12}  "
          f"{_when(min((k.oldest_use for k in used), default=None)):<16}  "
          f"{_when(max((k.newest_use for k in used), default=None))}")
    capped = sum(k.bytes for k in kinds if not k.pinned)
    pinned = ", ".join(PINNED_KINDS)
    print(f"cap: {describe_cap(cap)}; counted against it: {_size(capped, args.bytes)} "
          f"(every kind but {pinned})")
    return 0


def _days(text: str | None) -> float | None:
    if text is None:
        return None
    try:
        days = float(text)
    except ValueError:
        days = math.nan
    if not math.isfinite(days) or days < 0:
        raise InvalidInputError(f"--older-than '{text}'; accepted: a number of days, 0 or more "
                                "(e.g. 30 or 0.5)")
    return days


def _count(n: int) -> str:
    return f"{n} entr{'y' if n == 1 else 'ies'}"


def _name(entry: Entry) -> str:
    return entry.name + ("/" if entry.folder else "")


def _prune(args: argparse.Namespace) -> int:
    # Every value is checked before anything is removed (prune checks the kind first too).
    max_bytes = parse_size(args.max_size, option="--max-size") if args.max_size is not None else None
    days = _days(args.older_than)
    done = prune(max_bytes=max_bytes, older_than_days=days, kind=args.kind)
    for entry in done.removed:
        print(f"removed {_name(entry)}  {_size(entry.bytes, args.bytes)}, last used "
              f"{_when(entry.last_use)}")
    for entry in done.kept:
        print(f"kept {_name(entry)}: in use by another process")
    left = sum(k.bytes for k in usage(scan()))
    print(f"removed {_count(len(done.removed))} ({_size(done.bytes_removed, args.bytes)}); "
          f"the cache holds {_size(left, args.bytes)}")
    return 0


def run(args: argparse.Namespace) -> int:
    return _info(args) if args.action == "info" else _prune(args)
