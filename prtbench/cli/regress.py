"""``prtbench regress``: golden-metric regression of every method (smoke profile), or of a
cases file's own cases; ``--junit FILE`` writes the verdicts as JUnit XML for CI."""

from __future__ import annotations

import argparse
from pathlib import Path

from prtbench.bench.regress import regress


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--update", action="store_true", help="rewrite the baselines (explicit only)")
    p.add_argument("--method", action="append",
                   help="only these cases: method names or method:variant (with --cases: "
                        "names of the file's cases)")
    p.add_argument("--baselines", default=None,
                   help="baseline file (default tests/baselines/metrics.json; required with "
                        "--cases)")
    p.add_argument("--cases", default=None, metavar="FILE",
                   help="a TOML file of [[case]] tables (name, method, scene: a name or a file, "
                        "variant, light, scene_params, overrides) replacing the built-in cases; "
                        "see docs/ci.md")
    p.add_argument("--junit", default=None, metavar="FILE",
                   help="write every verdict as JUnit XML (one test case per case and metric, "
                        "one per case for the trivial-image gate), also when cases fail")
    p.add_argument("--cache", default=None, metavar="DIR",
                   help="artifact cache to reuse (default: a fresh temporary one, so stale "
                        "artifacts cannot pass)")
    p.add_argument("--workers", type=int, default=None,
                   help="cases measured at once on Dask workers (default: one per core, at "
                        "most one per case; 0: one after another in this process)")


def run(args: argparse.Namespace) -> int:
    ok = regress(update=args.update, methods=args.method or None,
                 baseline_path=Path(args.baselines) if args.baselines else None,
                 cache=Path(args.cache) if args.cache else None, workers=args.workers,
                 cases_path=Path(args.cases) if args.cases else None,
                 junit_path=Path(args.junit) if args.junit else None)
    return 0 if ok else 1
