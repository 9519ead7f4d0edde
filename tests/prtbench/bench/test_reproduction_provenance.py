"""The provenance every table and figure prints: the machine's load while measuring."""

from __future__ import annotations

import pandas as pd

from prtbench.bench.reproduction import BUSY_LOAD_PER_CORE, load_note, provenance_line


def _rows(loads, device="AMD EPYC, 2 cores"):
    return pd.DataFrame({"git_sha": ["abc"] * len(loads), "renderer": ["llvmpipe"] * len(loads),
                         "device": [device] * len(loads), "load_average": loads})


def test_a_quiet_machine_gets_its_load_range_and_no_warning():
    note = load_note([_rows([0.9, 1.7])])
    assert note == " Load while measuring: 1-min load average 0.9 to 1.7."


def test_a_busy_machine_is_said_to_be_busy_above_the_stated_load_per_core():
    busy = 2 * BUSY_LOAD_PER_CORE + 0.1  # just above the limit on 2 cores
    note = load_note([_rows([1.0, busy])])
    assert "on 2 cores: the machine was busy, so frame times and FPS here are not " \
        "representative" in note
    assert "busy" not in load_note([_rows([2 * BUSY_LOAD_PER_CORE])])  # at the limit: quiet
    assert "busy" in load_note([_rows([4.0], device="x, 2 cores"), _rows([4.0], "y, 16 cores")])


def test_rows_without_a_stored_load_say_nothing_about_it():
    assert load_note([_rows([None, float("nan")])]) == ""
    assert load_note([pd.DataFrame({"git_sha": ["abc"]})]) == ""
    line = provenance_line([_rows([11.6])], profile="quick")
    assert line.startswith("Measured with profile `quick` at git abc. GL renderer: llvmpipe. "
                           "Machine: AMD EPYC, 2 cores. Load while measuring: 1-min load "
                           "average 11.6 to 11.6 on 2 cores: the machine was busy")
