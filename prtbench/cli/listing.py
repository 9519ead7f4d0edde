"""``prtbench list``: list methods, scenes, lights, tables, profiles or assets."""

from __future__ import annotations

import argparse

from prtbench.api.method import METHODS
from prtbench.api.profiles import PROFILES
from prtbench.bench.reproduction import FIGURES, TABLES
from prtbench.io.assets import ASSETS
from prtbench.scene.registry import SCENES
from prtbench.transport.lights import LIGHTS

LIST_KINDS = ("methods", "scenes", "lights", "tables", "figures", "profiles", "assets")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("kind", choices=LIST_KINDS)


def run(args: argparse.Namespace) -> int:
    if args.kind == "methods":

        summaries = METHODS.summaries()
        width = max(map(len, summaries), default=0)
        names = [f"{name:<{width}}  {text}".rstrip() for name, text in summaries.items()]
    elif args.kind == "scenes":

        names = SCENES.names()
    elif args.kind == "lights":

        names = LIGHTS.names()
    elif args.kind == "tables":

        names = TABLES.names()
    elif args.kind == "figures":

        names = FIGURES.names()
    elif args.kind == "profiles":

        names = [f"{p.name}: {p.width}x{p.height}, {p.views} views, reference {p.reference_spp} spp"
                 for p in PROFILES.values()]
    else:

        names = list(ASSETS)
    print("\n".join(names))
    return 0
