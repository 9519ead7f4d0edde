"""``prtbench reference``: render (and cache) Mitsuba path-traced references."""

from __future__ import annotations

import argparse

from prtbench.api.config import parse_overrides
from prtbench.api.errors import PrtbenchError
from prtbench.api.profiles import get_profile
from prtbench.bench.outputs import check_cache
from prtbench.bench.runner import parse_resolution, resolve_views
from prtbench.cli.parsing import integer
from prtbench.render.reference import render_references
from prtbench.scene.registry import get_scene
from prtbench.transport.lights import get_light


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scene", required=True)
    p.add_argument("--scene-param", action="append", metavar="KEY=VALUE",
                   help="scene builder parameter")
    p.add_argument("--variant", default="diffuse")
    p.add_argument("--light", default=None, help="light name or .exr/.hdr path (default: the scene's)")
    p.add_argument("--views", type=integer("a whole number of views, 1 up to the scene's"), default=None,
                   help="number of trajectory views")
    p.add_argument("--spp", type=integer("a whole number of samples per pixel, 1 or more"),
                   default=None, help="samples per pixel (default: the profile's)")
    p.add_argument("--bounces", type=integer("a whole number of bounces, 0 or more"), default=0,
                   help="indirect bounces (0: direct light only)")
    p.add_argument("--res", default=None, help="WxH (default: the profile's)")
    p.add_argument("--profile", default="quick")


def run(args: argparse.Namespace) -> int:
    profile = get_profile(args.profile)
    scene = get_scene(args.scene, variant=args.variant, **parse_overrides(args.scene_param or []))
    light = get_light(args.light or scene.default_light)
    scene = resolve_views(scene, profile, args.views)  # the validator `run` uses
    width, height = (parse_resolution(args.res) if args.res is not None
                     else (profile.width, profile.height))
    if args.spp is not None and args.spp < 1:
        raise PrtbenchError(f"--spp {args.spp}; accepted: a positive integer")
    if args.bounces < 0:
        raise PrtbenchError(f"--bounces {args.bounces}; accepted: 0 or more")
    check_cache()
    refs = render_references(scene, light, scene.trajectory.views, width=width, height=height,
                             spp=args.spp or profile.reference_spp, bounces=args.bounces)
    for i, ref in enumerate(refs):
        print(f"view {i}: {ref.path} (spp {ref.spp}, variant {ref.variant}, "
              f"noise rmse (display) {ref.noise_rmse_display:.5f}, {ref.seconds:.1f} s)")
    return 0
