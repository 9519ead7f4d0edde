"""The advisor's step clock: what each step does and how long it took, on stderr and in JSON."""

from __future__ import annotations

import re
import time

import pytest

from prtbench.tradeoff.steps import Step, StepClock


def test_each_step_is_announced_timed_and_kept(capsys):
    clock = StepClock(echo=True)
    with clock.step("analysis", "what plants under sky requires") as step:
        time.sleep(0.05)
        step.detail = "required_bands 4"
    with clock.step("search", "2 methods at the quick profile", profile="quick") as step:
        step.cells = 7
    err = capsys.readouterr().err.splitlines()
    assert err[0] == "[advise] analysis: what plants under sky requires ..."
    assert re.fullmatch(r"\[advise\] analysis: 0\.\d s; required_bands 4", err[1])
    assert err[2] == "[advise] search: 2 methods at the quick profile ..."
    assert re.fullmatch(r"\[advise\] search: 0\.0 s, 7 cells", err[3])
    assert [s.name for s in clock.steps] == ["analysis", "search"]
    assert clock.steps[0].seconds >= 0.05 and clock.total >= sum(s.seconds for s in clock.steps)
    assert clock.steps[1].to_json() == {"step": "search", "seconds": pytest.approx(0, abs=0.01),
                                        "cells": 7, "profile": "quick", "detail": ""}
    assert clock.steps[1].describe() == "search 0.0 s (7 cells at quick)"
    assert Step("pruning", 1.26).describe() == "pruning 1.3 s"


def test_quiet_says_nothing_but_still_times(capsys):
    clock = StepClock(echo=False)
    with clock.step("scene", "loading it"):
        pass
    clock.say("total: 0.0 s")
    assert capsys.readouterr().err == ""
    assert [s.name for s in clock.steps] == ["scene"]


def test_a_failing_step_says_where_it_stopped_and_reraises(capsys):
    clock = StepClock(echo=True)
    with pytest.raises(RuntimeError, match="boom"), clock.step("search", "1 method at smoke"):
        raise RuntimeError("boom")
    err = capsys.readouterr().err.splitlines()
    assert re.fullmatch(r"\[advise\] search: stopped after 0\.0 s \(RuntimeError\)", err[-1])
    assert clock.steps == []  # an unfinished step has no time


def test_an_unannounced_step_is_silent_until_it_succeeds(capsys):
    # The scene step: a bad scene parameter stays the CLI's one error line.
    clock = StepClock(echo=True)
    with pytest.raises(ValueError), clock.step("scene", "loading it", announce=False):
        raise ValueError("radius=-1")
    assert capsys.readouterr().err == ""
    with clock.step("scene", "loading it", announce=False) as step:
        step.detail = "12 triangles"
    assert re.fullmatch(r"\[advise\] scene: 0\.0 s; 12 triangles\n", capsys.readouterr().err)
