"""``prtbench results``: print stored result rows."""

from __future__ import annotations

import argparse
from collections.abc import Callable, Iterable

from prtbench.api.errors import UnknownNameError
from prtbench.api.method import METHODS
from prtbench.api.profiles import PROFILES
from prtbench.scene.registry import SCENES
from prtbench.store.results import ResultRow, ResultsStore
from prtbench.store.table import format_rows


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--method", help="a method's name (`prtbench list methods`)")
    p.add_argument("--scene", help="a scene's name, as stored (`prtbench list scenes`)")
    p.add_argument("--profile", help="smoke, quick or paper")
    p.add_argument("--results", default=None,
                   help="results database (default results/prtbench.sqlite)")


def check_names(filters: dict[str, str | None], *,
                stored: Callable[[], Iterable[ResultRow]]) -> None:
    """Raise :class:`UnknownNameError` (with a did-you-mean) for a filter value that is
    neither registered nor in a stored row: a typo is a mistake, not "no results".

    Parameters
    ----------
    filters : dict
        ``method``, ``scene``, ``profile`` -> the value asked for (None: not filtered).
    stored : callable
        The store's rows, read only when a value is not registered (a row may name a
        method or scene that no longer is, or a scene read from a file).
    """
    registered = {"method": METHODS.names, "scene": SCENES.names, "profile": lambda: PROFILES}
    rows: list[ResultRow] | None = None
    for kind, value in filters.items():
        if value is None or value in registered[kind]():
            continue
        rows = list(stored()) if rows is None else rows
        seen = {getattr(row, kind) for row in rows}
        if value not in seen:
            raise UnknownNameError(kind, value, {*registered[kind](), *seen})


def run(args: argparse.Namespace) -> int:
    # Read-only: a query never creates a folder, a database or a migration.
    store = ResultsStore(args.results, readonly=True)
    filters = {"method": args.method, "scene": args.scene, "profile": args.profile}
    check_names(filters, stored=store.query)
    rows = store.query(**filters)
    print(format_rows(rows) if rows else "no results")
    return 0
