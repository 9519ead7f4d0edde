"""``prtbench pareto``: Pareto fronts over (error, cost) from the results store."""

from __future__ import annotations

import argparse

from prtbench.api.config import parse_overrides
from prtbench.tradeoff.pareto import pareto
from prtbench.tradeoff.pareto_report import summary_text


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scene", required=True, help="a scene name or an asset file")
    p.add_argument("--scene-param", action="append", metavar="KEY=VALUE",
                   help="scene parameter the rows were measured with (file scenes: scale, up, ground)")
    p.add_argument("--light", default=None, help="one light (default: every stored light)")
    p.add_argument("--error", default="psnr_masked", help="psnr_masked or flip_masked")
    p.add_argument("--cost", default="frame_ms", help="frame_ms, memory, precompute or ops")
    p.add_argument("--profile", default="quick")
    p.add_argument("--results", default=None)
    p.add_argument("--reports", default="reports")


def run(args: argparse.Namespace) -> int:
    results = pareto(scene=args.scene, light=args.light, error=args.error, cost=args.cost,
                     profile=args.profile, results_path=args.results, reports_dir=args.reports,
                     scene_params=parse_overrides(args.scene_param or []))
    print("\n".join(summary_text(r) for r in results))
    return 0
