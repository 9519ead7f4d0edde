"""``prtbench answer``: what to use on this scene, in plain language (the demo's last word)."""

from __future__ import annotations

import argparse
from pathlib import Path

from prtbench.tradeoff.answer import answer


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--analysis", required=True, help="the JSON `prtbench analyze --json` wrote")
    p.add_argument("--advice", required=True, help="the JSON `prtbench advise --json` wrote")
    p.add_argument("--target", default="", help="the target the advice was asked for (shown)")
    p.add_argument("--profile", default="quick", help="profile of the stored rows (the front)")
    p.add_argument("--results", default=None, help="results database (default results/prtbench.sqlite)")
    p.add_argument("--site", default=None, help="the built site's index.html (shown)")


def run(args: argparse.Namespace) -> int:
    print(answer(analysis_path=Path(args.analysis), advice_path=Path(args.advice),
                 results_path=Path(args.results) if args.results else None,
                 profile=args.profile, target=args.target,
                 site=Path(args.site) if args.site else None))
    return 0
