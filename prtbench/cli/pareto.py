"""``prtbench pareto``: Pareto fronts over (error, cost) from the results store, or with
``--at KIND=VALUE`` each method's best configuration within that budget."""

from __future__ import annotations

import argparse

from prtbench.api.config import parse_overrides
from prtbench.tradeoff import budget as budget_mod
from prtbench.tradeoff.pareto import pareto
from prtbench.tradeoff.pareto_report import summary_text


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scene", required=True, help="a scene name or an asset file")
    p.add_argument("--scene-param", action="append", metavar="KEY=VALUE",
                   help="scene parameter the rows were measured with (file scenes: scale, up, ground)")
    p.add_argument("--light", default=None, help="one light (default: every stored light)")
    p.add_argument("--error", default="psnr_masked", help="psnr_masked or flip_masked")
    # None, not frame_ms: --at must tell a --cost the user gave from the default.
    p.add_argument("--cost", default=None, help="frame_ms (default), memory, precompute or ops")
    p.add_argument("--at", default=None, metavar="KIND=VALUE",
                   help="an equal-budget table instead of fronts: each method's best "
                        "configuration within memory=64MiB, frame_ms=16.7, ops=2e9 or "
                        "precompute=600 (sets the cost)")
    p.add_argument("--profile", default="quick")
    p.add_argument("--results", default=None)
    p.add_argument("--reports", default="reports")


def run(args: argparse.Namespace) -> int:
    scene_params = parse_overrides(args.scene_param or [])
    if args.at is not None:
        budget = budget_mod.parse_budget(args.at, cost=args.cost)
        tables = budget_mod.budget_tables(
            scene=args.scene, budget=budget, light=args.light, error=args.error,
            profile=args.profile, results_path=args.results, reports_dir=args.reports,
            scene_params=scene_params)
        print("\n".join(budget_mod.summary_text(t) for t in tables))
        return 0
    results = pareto(scene=args.scene, light=args.light, error=args.error,
                     cost=args.cost or "frame_ms", profile=args.profile,
                     results_path=args.results, reports_dir=args.reports,
                     scene_params=scene_params)
    print("\n".join(summary_text(r) for r in results))
    return 0
