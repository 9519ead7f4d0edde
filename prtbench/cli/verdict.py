"""``prtbench verdict``: PRT methods against the engine baselines at equal memory and equal work.

Measures the verdict grid's cells the store lacks (progress on stderr unless ``--quiet``), then
prints and writes, per scene, each method family's best configuration within 1, 8 and 64 MiB
and at the engine baseline's work, and a one-line conclusion (:mod:`prtbench.tradeoff.verdict`).
"""

from __future__ import annotations

import argparse
import shlex
from pathlib import Path

from prtbench.api.config import parse_overrides
from prtbench.cli.parsing import integer
from prtbench.tradeoff.verdict import verdict
from prtbench.tradeoff.verdict_report import summary_text


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scene", action="append", required=True,
                   help="a scene name or an asset file (repeat for several scenes)")
    p.add_argument("--light", default=None, help="light name (default: each scene's)")
    p.add_argument("--profile", default="quick", help="smoke, quick or paper (default quick)")
    p.add_argument("--results", default=None, help="results database (default "
                   "results/prtbench.sqlite); the measured rows are appended to it")
    p.add_argument("--reports", default="reports", help="folder of the verdict's .md and .csv")
    p.add_argument("--name", default=None, help="stem of the reports (default "
                   "verdict-<scenes>-<light>)")
    p.add_argument("--scene-param", action="append", metavar="KEY=VALUE",
                   help="scene builder parameter (file scenes: scale, up, ground)")
    p.add_argument("--views", type=integer("a whole number of views, 1 up to the scene's"),
                   default=None, help="views per configuration (default: the profile's)")
    p.add_argument("--workers", type=integer("a whole number of workers, 0 (serial, no Dask) "
                                             "or more"), default=None,
                   help="Dask workers of the measurement (default: cores; 0: serial)")
    p.add_argument("--method", action="append", default=None,
                   help="measure only this method's verdict cells (repeatable; default: all)")
    p.add_argument("--no-measure", action="store_true",
                   help="read the store only; measure nothing")
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")


def run(args: argparse.Namespace) -> int:
    result = verdict(scenes=args.scene, light=args.light, profile=args.profile,
                     results_path=args.results, reports_dir=args.reports, name=args.name,
                     scene_params=parse_overrides(args.scene_param or []),
                     measure=not args.no_measure, workers=args.workers, views=args.views,
                     methods=args.method,
                     command=_command(args), progress=not args.quiet,
                     echo=(lambda text: None) if args.quiet else None)
    print("\n".join(result.measured))
    print(summary_text(result))
    return 0


def _command(args: argparse.Namespace) -> str:
    """The command as the reports print it: no store or reports folder (machine paths), an
    asset file by its name."""
    words = ["prtbench", "verdict"]
    for scene in args.scene:
        words += ["--scene", Path(scene).name if "/" in scene else scene]
    for option in ("light", "profile", "name", "views"):
        if getattr(args, option) is not None:
            words += [f"--{option}", str(getattr(args, option))]
    for param in args.scene_param or []:
        words += ["--scene-param", param]
    return shlex.join(words)
