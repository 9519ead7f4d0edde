"""``prtbench figure``: regenerate a paper figure from our renders."""

from __future__ import annotations

import argparse
from pathlib import Path

from prtbench.api.profiles import get_profile
from prtbench.bench import outputs
from prtbench.bench.reproduction import FIGURES
from prtbench.store.results import default_path


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("name")
    p.add_argument("--profile", default="quick")
    p.add_argument("--results", default=None)
    p.add_argument("--reports", default="reports")
    p.add_argument("--from-store", action="store_true",
                   help="rebuild the report from the newest stored run (no measuring)")


def _check_report_outputs(args: argparse.Namespace) -> None:
    """``table``/``figure``: the profile, --reports, --results and the cache, before any work."""

    get_profile(args.profile)
    outputs.check_folder("--reports", Path(args.reports))
    outputs.check_results_store("--results", Path(args.results) if args.results else default_path())
    outputs.check_cache()


def run(args: argparse.Namespace) -> int:
    figure = FIGURES.get(args.name)
    _check_report_outputs(args)
    for p in figure.make(profile=args.profile, reports_dir=Path(args.reports),
                         results_path=Path(args.results) if args.results else None,
                         from_store=args.from_store):
        print(f"wrote {p}")
    return 0
