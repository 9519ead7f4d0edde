"""``prtbench sweep``: run a grid of methods and knobs (TOML file or options) on Dask."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from prtbench.api.config import parse_overrides
from prtbench.api.errors import PrtbenchError
from prtbench.cli.parsing import integer
from prtbench.store.results import default_path
from prtbench.tradeoff import grid
from prtbench.tradeoff.sweep import retime_serial, run_cells

RETIME_SETTLE_S = 90.0


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("file", nargs="?", default=None, help="sweep file (sweeps/*.toml)")
    p.add_argument("--scene", default=None, help="scene name(s), comma-separated")
    p.add_argument("--method", default=None, help="method name(s), comma-separated")
    p.add_argument("--grid", action="append", metavar="KNOB=V1,V2,...", help="a knob's values")
    p.add_argument("--set", action="append", metavar="KEY=VALUE", help="knob fixed in every cell")
    p.add_argument("--light", default=None, help="light name(s), comma-separated")
    p.add_argument("--variant", default=None, help="material variant: diffuse or glossy")
    p.add_argument("--views", type=integer("a whole number of views, 1 up to the scene's"), default=None,
                   help="number of trajectory views")
    p.add_argument("--scene-param", action="append", metavar="KEY=VALUE", help="scene builder parameter")
    p.add_argument("--reference-bounces", type=integer("a whole number of bounces, 0 to 16"),
                   default=None, metavar="N", help="bounces of the path reference, the same for "
                   "every method (default: each method's bounces knob)")
    p.add_argument("--profile", default=None, help="smoke, quick or paper (default: the file's, else quick)")
    p.add_argument("--workers", type=integer("a whole number of workers, 0 (serial, no Dask) or more"),
                   default=None, help="local Dask workers (default: cores; 0: serial, no Dask)")
    p.add_argument("--worker-threads", type=integer("a whole number of threads per worker"),
                   default=None, metavar="N",
                   help="tracing/llvmpipe threads per Dask worker (default: its share of the cores)")
    p.add_argument("--scheduler", default=None, help="existing Dask scheduler, tcp://HOST:PORT")
    p.add_argument("--force", action="store_true", help="measure cells already in the store again")
    p.add_argument("--timing-serial", action="store_true", help="then re-time finished cells one at a time")
    p.add_argument("--results", default=None, help="results database (default results/prtbench.sqlite)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    given = [o for o in ("scene", "method", "grid", "light", "set", "scene_param")
             if getattr(args, o)] + (["variant"] if args.variant is not None else []) + (
             ["views"] if args.views is not None else []) + (
             ["reference_bounces"] if args.reference_bounces is not None else [])
    if args.file and given:
        raise PrtbenchError(f"sweep: both a file and --{given[0].replace('_', '-')}; accepted: "
                            f"a sweep file, or --scene/--method/--grid options")
    if args.file:
        sweep = grid.load_sweep(args.file, profile=args.profile)
    elif args.scene and args.method:
        sweep = grid.from_options(
            scenes=grid.split_values(args.scene, option="--scene"),
            methods=grid.split_values(args.method, option="--method"),
            grid=args.grid or [], fixed=parse_overrides(args.set or []),
            lights=grid.split_values(args.light, option="--light") if args.light else [],
            variant=args.variant or "diffuse", views=args.views,
            reference_bounces=args.reference_bounces,
            scene_params=parse_overrides(args.scene_param or []), profile=args.profile or "quick")
    else:
        raise PrtbenchError("sweep: no grid; accepted: a sweep file (e.g. sweeps/plants-all.toml) "
                            "or --scene S --method M[,M...] [--grid KNOB=V1,V2,...]")
    results = Path(args.results) if args.results else None
    outcome = run_cells(list(sweep.cells), profile=sweep.profile, results_path=results,
                        workers=args.workers, scheduler=args.scheduler, force=args.force,
                        progress=not args.quiet, worker_threads=args.worker_threads)
    retimed = (retime_serial(outcome, profile=sweep.profile, results_path=results,
                             progress=not args.quiet, settle_s=RETIME_SETTLE_S)
               if args.timing_serial else [])
    failed = outcome.failed + [r for r in retimed if r.status == "failed"]
    for cell, reason in sweep.dropped:  # after the run: a user error stays one line
        print(f"prtbench: sweep: left out {cell.method} {cell.scene} {dict(cell.label)}: {reason}",
              file=sys.stderr)
    for item in failed:
        print(f"prtbench: cell failed: {item.job.describe()}: {item.error}", file=sys.stderr)

    print(f"sweep {sweep.source} ({sweep.profile}): {len(outcome.results)} cells: "
          f"{outcome.count('done')} done, {outcome.count('skipped')} skipped (already stored), "
          f"{outcome.count('failed')} failed"
          f"{f' on {outcome.workers} worker(s)' if outcome.workers else ''} in {outcome.wall_s:.1f} s"
          f"{f'; {len(retimed)} re-timed serially' if args.timing_serial else ''}; "
          f"results store: {results or default_path()}")
    return 1 if failed else 0
