"""``prtbench advise``: the cheapest configuration meeting a target, verified by a run.

Progress goes to stderr (each step -- loading the scene, analysis, pruning, screening, search,
verification -- with its wall time, and each measured cell) unless ``--quiet``; the report goes to stdout and
``--json`` records the step times (``steps``, ``total_s``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from prtbench.api import strict_json
from prtbench.api.cache import atomic_path
from prtbench.api.config import parse_overrides
from prtbench.bench import outputs
from prtbench.cli.parsing import integer
from prtbench.tradeoff.advice_text import format_advice
from prtbench.tradeoff.advise import advise


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scene", required=True)
    p.add_argument("--light", default=None, help="light name (default: the scene's)")
    p.add_argument("--variant", default="diffuse", help="material variant: diffuse or glossy")
    p.add_argument("--target", required=True, help='accuracy, e.g. "psnr_masked>=28,flip_masked<=0.1"')
    p.add_argument("--budget", default="", help='costs, e.g. "frame_ms<=33,memory<=256MiB"')
    p.add_argument("--cost", default="frame_ms", help="what cheapest means: frame_ms, memory, precompute or ops")
    p.add_argument("--profile", default="quick", help="profile of the answer (screening runs at smoke)")
    p.add_argument("--light-changes", default="none", help="how the lights will change (for the analysis)")
    p.add_argument("--method", action="append", help="only these methods (default: all)")
    p.add_argument("--reference-bounces", type=integer("a whole number of bounces, 0 to 16"),
                   default=1, metavar="N", help="bounces of the path reference every candidate "
                   "is scored against (default 1)")
    p.add_argument("--band-margin", type=integer("a whole number of SH bands"), default=2,
                   help="SH bands searched above the required count")
    p.add_argument("--workers", type=integer("a whole number of workers, 0 (serial, no Dask) or more"),
                   default=None,
                   help="Dask workers of the screening runs (default: cores; 0: serial, no Dask)")
    p.add_argument("--json", default=None, help="write the answer as JSON here")
    p.add_argument("--results", default=None, help="results database of the verification run")
    p.add_argument("--quiet", action="store_true",
                   help="no progress on stderr (each step with its wall time, each cell)")
    p.add_argument("--scene-param", action="append", metavar="KEY=VALUE", help="scene builder parameter")


def run(args: argparse.Namespace) -> int:
    if args.json:
        outputs.check_file("--json", Path(args.json))  # before any work
    advice = advise(args.scene, args.light, target=args.target, budget=args.budget,
                    cost=args.cost, profile=args.profile, variant=args.variant,
                    light_changes=args.light_changes, methods=args.method or None,
                    scene_params=parse_overrides(args.scene_param or []),
                    results_path=Path(args.results) if args.results else None,
                    band_margin=args.band_margin, workers=args.workers,
                    reference_bounces=args.reference_bounces, echo=not args.quiet)
    print(format_advice(advice))
    if args.json:
        with atomic_path(Path(args.json)) as tmp:
            tmp.write_text(strict_json.dumps(advice.to_json(), indent=2))
        print(f"wrote {args.json}")
    if not advice.met:
        print(f"prtbench: target not reached; {advice.hint}", file=sys.stderr)
        return 1
    return 0
