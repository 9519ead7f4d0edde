"""The ``prtbench`` command: one module per subcommand.

Each ``prtbench.cli.<module>`` defines ``HELP`` (one line), ``add_arguments(parser)`` and
``run(args) -> int``. :data:`COMMANDS` maps every subcommand to its module, and only the module
of the subcommand given is imported, so ``prtbench list`` loads neither the runner nor any
backend. User mistakes print one line (``prtbench: error: …``) and exit with status 2.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from prtbench.api.errors import PrtbenchError
from prtbench.cli.parsing import Parser

#: subcommand -> (module under prtbench.cli, one line of help). The help is repeated here so
#: that ``prtbench --help`` lists every command without importing any of them.
COMMANDS: dict[str, tuple[str, str]] = {
    "list": ("listing", "list methods, scenes, lights, tables, figures, profiles or assets"),
    "describe": ("describe", "a method's summary, paper and knobs (type, default, range)"),
    "assets": ("assets", "fetch pinned mesh/HDRI packages into the cache"),
    "cache": ("cache", "the cache: size per kind (info) and removing entries (prune)"),
    "scene": ("scene", "inspect an asset file (or a built-in scene) as a prtbench scene"),
    "run": ("run", "precompute, render, compare with the reference, store"),
    "reference": ("reference", "render (and cache) Mitsuba path-traced references"),
    "results": ("results", "print stored result rows"),
    "sweep": ("sweep", "run a grid of methods and knobs (TOML file or options) on Dask"),
    "analyze": ("analyze", "what a scene requires: bands, glossy, shadows, textures, bounces, "
                           "light changes"),
    "advise": ("advise", "the cheapest configuration meeting a target, verified by a run"),
    "answer": ("answer", "what to use on a scene, in plain words, from the analysis, the "
                         "advice and the store"),
    "pareto": ("pareto", "Pareto fronts over (error, cost) from the results store"),
    "verdict": ("verdict", "does a PRT method beat the engine baselines at equal memory and "
                           "work? best per family per budget, measured where the store lacks it"),
    "report": ("report", "the static HTML comparison site, from the results store"),
    "table": ("table", "regenerate a paper table from our measurements"),
    "figure": ("figure", "regenerate a paper figure from our renders"),
    "claims": ("claims", "every checkable claim of the papers: reproduced, contradicted, ... "
                         "from the results store"),
    "regress": ("regress", "golden-metric regression of every method (smoke profile)"),
    "stability": ("stability", "every method at the extremes of its knobs, lights and scenes: "
                               "ok/degraded/refused/failed"),
}

DESCRIPTION = ("prtbench: a benchmark and reproduction harness for Precomputed Radiance "
               "Transfer. Every method renders the same scenes, lights and views and is compared "
               "with a Mitsuba 3 path-traced reference. Run `prtbench COMMAND --help` for the "
               "options of a command.")


def command_module(name: str):
    """The module of subcommand ``name`` (imported now)."""
    return importlib.import_module(f"prtbench.cli.{COMMANDS[name][0]}")


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser; the arguments of ``command`` only (None: of every command). Its errors
    are one line, ``prtbench: error: …``, exit status 2 (:class:`prtbench.cli.parsing.Parser`)."""
    parser = Parser(prog="prtbench", description=DESCRIPTION)
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name, (_, text) in COMMANDS.items():
        p = sub.add_parser(name, help=text, description=text)
        if command is None or name == command:
            command_module(name).add_arguments(p)
    return parser


def _command_of(argv: Sequence[str]) -> str | None:
    """The subcommand named in ``argv`` (the first word that is one), else None."""
    for word in argv:
        if word in COMMANDS:
            return word
        if not word.startswith("-"):
            return None
    return None


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    command = _command_of(argv)
    parser = build_parser(command) if command is not None else build_parser("")
    args = parser.parse_args(argv)
    try:
        return command_module(args.command).run(args)
    except PrtbenchError as exc:
        print(f"prtbench: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print("prtbench: interrupted (caches and results hold only completed work)",
              file=sys.stderr)
        return 130
    except BrokenPipeError:  # `prtbench list methods | head`: the reader left, nothing is wrong
        sys.stderr.close()
        return 0
