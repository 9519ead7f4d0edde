"""``prtbench assets``: fetch pinned mesh/HDRI packages into the cache."""

from __future__ import annotations

import argparse

from prtbench.io import assets


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("action", choices=("fetch", "list"))
    p.add_argument("name", nargs="?", default=None, help="asset name (default: all)")
    p.add_argument("--force", action="store_true", help="fetch again even if present")


def run(args: argparse.Namespace) -> int:
    if args.action == "list":
        for name in assets.ASSETS:
            print(f"{name}\t{'fetched' if assets.is_fetched(name) else 'missing'}")
        return 0
    paths = assets.fetch(args.name, force=args.force)
    print(f"fetched {len(paths)} file(s) into {assets.assets_root()}")
    return 0
