"""The timed steps of ``prtbench advise``: what each does, how long it took.

On a user's own scene the advisor can take minutes; the steps (scene, analysis, pruning,
screening, search, verification) say where, on stderr as they happen (``[advise]`` lines, as
the search's per-cell lines) and in the ``--json`` answer.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any


@dataclass
class Step:
    """One step of the advisor and its wall time.

    Attributes
    ----------
    name : str
        ``scene``, ``analysis``, ``pruning``, ``screening``, ``search`` or ``verification``.
    seconds : float
        Wall time.
    cells : int
        Configurations measured in the step (0 for analysis and pruning).
    profile : str
        The profile its cells ran at ('' when it ran none).
    detail : str
        What it found, one line.
    """

    name: str
    seconds: float
    cells: int = 0
    profile: str = ""
    detail: str = ""

    def to_json(self) -> dict[str, Any]:
        return {"step": self.name, "seconds": round(self.seconds, 3), "cells": self.cells,
                "profile": self.profile, "detail": self.detail}

    def describe(self) -> str:
        """``screening 41.2 s (12 cells at smoke)``."""
        cells = f" ({_cells(self.cells)} at {self.profile})" if self.cells else ""
        return f"{self.name} {self.seconds:.1f} s{cells}"


def _cells(n: int) -> str:
    return f"{n} cell" + ("" if n == 1 else "s")


class StepClock:
    """Times the advisor's steps; with ``echo`` says on stderr what each does and how long it
    took (a user's scene can take minutes: they should see where)."""

    def __init__(self, *, echo: bool):
        self.echo, self.steps = echo, []
        self.started = time.perf_counter()

    def say(self, text: str) -> None:
        if self.echo:
            print(f"[advise] {text}", file=sys.stderr, flush=True)

    @contextmanager
    def step(self, name: str, doing: str, *, profile: str = "",
             announce: bool = True) -> Iterator[Step]:
        """Time the body as step ``name``; the body fills in the yielded step's ``cells`` and
        ``detail``.

        ``announce=False`` says nothing until the body has succeeded (for a step whose errors
        are the user's input: those stay the one ``prtbench: error:`` line).
        """
        if announce:
            self.say(f"{name}: {doing} ...")
        step = Step(name, 0.0, profile=profile)
        start = time.perf_counter()
        try:
            yield step
        except BaseException as exc:  # say where it stopped; the error itself is the caller's
            if announce:
                self.say(f"{name}: stopped after {time.perf_counter() - start:.1f} s "
                         f"({type(exc).__name__})")
            raise
        step.seconds = time.perf_counter() - start
        self.steps.append(step)
        self.say(f"{name}: {step.seconds:.1f} s" + (f", {_cells(step.cells)}" if step.cells else "")
                 + (f"; {step.detail}" if step.detail else ""))

    @property
    def total(self) -> float:
        return time.perf_counter() - self.started
