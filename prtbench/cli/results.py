"""``prtbench results``: print stored result rows."""

from __future__ import annotations

import argparse

from prtbench.api.profiles import get_profile
from prtbench.store.results import ResultsStore, format_rows


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--method")
    p.add_argument("--scene")
    p.add_argument("--profile")
    p.add_argument("--results", default=None)


def run(args: argparse.Namespace) -> int:
    if args.profile is not None:
        get_profile(args.profile)  # an unknown profile is a mistake, not "no results"
    # Read-only: a query never creates a folder, a database or a migration.
    rows = ResultsStore(args.results, readonly=True).query(method=args.method, scene=args.scene,
                                                           profile=args.profile)
    print(format_rows(rows) if rows else "no results")
    return 0
