"""``prtbench run``: precompute, render, compare with the reference, store."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from prtbench.api.config import parse_overrides
from prtbench.bench import submit
from prtbench.bench.job import Job, Outputs
from prtbench.bench.runner import format_summary, parse_resolution
from prtbench.cli.parsing import integer
from prtbench.store.results import default_path


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--method", required=True)
    p.add_argument("--scene", required=True)
    p.add_argument("--variant", default="diffuse", help="material variant: diffuse or glossy")
    p.add_argument("--light", default=None, help="light name or .exr/.hdr path (default: the scene's)")
    p.add_argument("--views", type=integer("a whole number of views, 1 up to the scene's"), default=None,
                   help="number of trajectory views")
    p.add_argument("--res", default=None, help="WxH (default: the profile's)")
    p.add_argument("--profile", default="quick", help="smoke, quick or paper")
    p.add_argument("--reference", default="path", help="path or method:<name>")
    p.add_argument("--reference-bounces", type=integer("a whole number of bounces, 0 to 16"),
                   default=None, metavar="N", help="bounces of the path reference (default: the "
                   "method's bounces knob); one panel has one reference")
    p.add_argument("--set", action="append", metavar="KEY=VALUE", help="method config override")
    p.add_argument("--scene-param", action="append", metavar="KEY=VALUE", help="scene builder parameter")
    p.add_argument("--out", default="out", help="directory for EXR/PNG/FLIP images and summary.json")
    p.add_argument("--json", default=None, help="also write the JSON summary here")
    p.add_argument("--results", default=None, help="results database (default results/prtbench.sqlite)")
    p.add_argument("--no-store", action="store_true", help="do not append rows to the results store")
    p.add_argument("--quiet", action="store_true", help="no progress bars")


def run(args: argparse.Namespace) -> int:
    resolution = parse_resolution(args.res) if args.res is not None else None
    job = Job(method=args.method, scene=args.scene, variant=args.variant, light=args.light,
              views=args.views, resolution=resolution,
              profile=args.profile, reference=args.reference,
              reference_bounces=args.reference_bounces,
              overrides=parse_overrides(args.set or []),
              scene_params=parse_overrides(args.scene_param or []))
    outputs = Outputs(out_dir=Path(args.out), json_path=Path(args.json) if args.json else None)
    results = Path(args.results) if args.results else None
    # Everything is validated before anything is written; a refusal is one line, exit 2.
    result = submit.run(job, profile=args.profile, outputs=outputs, results_path=results,
                        store=not args.no_store, progress=not args.quiet)
    summary = result.summary
    print(format_summary(summary))
    out = Path(args.out) / summary.method / f"{summary.scene}-{summary.variant}" / summary.light
    print(f"images and summary.json: {out}")
    if not args.no_store:
        print(f"results store: {results or default_path()}")
    if summary.status != "ok":  # stored and written, but not a measurement to trust
        print(f"prtbench: {summary.status} result (stored with status '{summary.status}'): "
              f"{summary.status_reason}", file=sys.stderr)
        return 1
    return 0
