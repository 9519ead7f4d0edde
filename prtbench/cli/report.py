"""``prtbench report``: the static HTML comparison site, from the results store."""

from __future__ import annotations

import argparse
from pathlib import Path

from prtbench.site.build import build
from prtbench.store.results import default_path


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--results", default=None, help="results database (default results/prtbench.sqlite)")
    p.add_argument("--out", default="reports/site", help="site folder (replaced when complete)")
    p.add_argument("--quiet", action="store_true", help="no per-page progress lines")


def run(args: argparse.Namespace) -> int:
    summary = build(results_path=Path(args.results) if args.results else default_path(),
                    out=Path(args.out), echo=not args.quiet)
    print(f"wrote {len(summary.pages)} pages to {summary.out} ({summary.images_made} images made, "
          f"{summary.images_reused} from the cache); open {summary.out / 'index.html'}")
    return 0
