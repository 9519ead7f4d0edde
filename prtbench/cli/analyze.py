"""``prtbench analyze``: what a scene requires: bands, glossy, shadows,  textures, bounces, light changes."""

from __future__ import annotations

import argparse
from pathlib import Path

from prtbench.api.cache import atomic_path
from prtbench.api.config import parse_overrides
from prtbench.api.errors import PrtbenchError
from prtbench.api.strict_json import dumps
from prtbench.bench import outputs
from prtbench.scene.registry import get_scene
from prtbench.tradeoff.analyze import analyze_scene, check_light_changes, format_analysis
from prtbench.transport.lights import get_light


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scene", required=True)
    p.add_argument("--variant", default="diffuse", help="material variant: diffuse or glossy")
    p.add_argument("--light", default=None, help="light name or .exr/.hdr path (default: the scene's)")
    p.add_argument("--light-changes", default="none", help="none, rotate or family")
    p.add_argument("--target", default="0.01", help="target relative lighting error (default 0.01)")
    p.add_argument("--scene-param", action="append", metavar="KEY=VALUE", help="scene builder parameter")
    p.add_argument("--no-render", action="store_true", help="skip the Mitsuba interreflection renders")
    p.add_argument("--json", default=None, help="also write the analysis here (strict JSON)")
    p.add_argument("--quiet", action="store_true", help="no per-measurement progress lines")


def run(args: argparse.Namespace) -> int:
    # Every input is checked before any measurement runs or anything is written.
    check_light_changes(args.light_changes)
    try:
        target = float(args.target)
    except ValueError:
        target = float("nan")
    if not 0.0 < target < 1.0:  # NaN fails too
        raise PrtbenchError(f"--target {args.target}; accepted: a relative error in (0, 1), e.g. 0.01")
    scene = get_scene(args.scene, variant=args.variant,
                      **parse_overrides(args.scene_param or []))
    light = get_light(args.light or scene.default_light)
    if args.json:
        outputs.check_file("--json", Path(args.json))
    if not args.no_render:
        outputs.check_cache()
    analysis = analyze_scene(scene, light, light_changes=args.light_changes, target=target,
                             render_bounces=not args.no_render, progress=not args.quiet)
    print(format_analysis(analysis))
    if args.json:
        with atomic_path(Path(args.json)) as tmp:
            Path(tmp).write_text(dumps(analysis.to_json(), indent=2) + "\n")
        print(f"analysis: {args.json}")
    return 0
