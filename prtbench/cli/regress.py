"""``prtbench regress``: golden-metric regression of every method (smoke profile)."""

from __future__ import annotations

import argparse
from pathlib import Path

from prtbench.bench.cluster import cores
from prtbench.bench.regress import case_names, regress


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--update", action="store_true", help="rewrite the baselines (explicit only)")
    p.add_argument("--method", action="append", help="only these methods")
    p.add_argument("--baselines", default=None, help="baseline file (default tests/baselines/metrics.json)")
    p.add_argument("--cache", default=None, metavar="DIR",
                   help="artifact cache to reuse (default: a fresh temporary one, so stale "
                        "artifacts cannot pass)")
    p.add_argument("--workers", type=int, default=None,
                   help="cases measured at once on Dask workers (default: one per core, at "
                        "most one per case; 0: one after another in this process)")


def run(args: argparse.Namespace) -> int:
    cases = args.method or case_names()
    workers = args.workers if args.workers is not None else (
        min(cores(), len(cases)) if len(cases) > 1 else 0)
    ok = regress(update=args.update, methods=args.method or None,
                 baseline_path=Path(args.baselines) if args.baselines else None,
                 cache=Path(args.cache) if args.cache else None, workers=workers)
    return 0 if ok else 1
