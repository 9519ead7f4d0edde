"""prtbench.tradeoff.budget and `prtbench pareto --at`: parsing budgets, each method's best
configuration within one, the best/tied marks beyond the intervals, the reports."""

from __future__ import annotations

import csv
import json
import re

import pytest

from prtbench.api import config as config_mod
from prtbench.api.errors import InvalidInputError, UnknownNameError
from prtbench.api.method import METHODS
from prtbench.cli import main
from prtbench.store.results import ResultRow, ResultsStore
from prtbench.tradeoff.budget import BEST, TIED, best_within, parse_budget
from prtbench.tradeoff.front import collect_points

MiB = 1 << 20


def _config(method: str, **knobs) -> dict:
    return config_mod.to_dict(METHODS.get(method).make_config(knobs, profile="quick"))


def _row(method="vertex", knobs=None, *, view=0, psnr=25.0, flip=0.2, frame_ms=2.0,
         memory=10 * MiB, **fields) -> ResultRow:
    values = dict(method=method, scene="plants", config=_config(method, **(knobs or {})),
                  scene_variant="diffuse", light="sky", view=view, width=64, height=48,
                  metrics={"psnr_masked": psnr, "flip_masked": flip}, frame_ms=frame_ms,
                  memory_bytes=memory, precompute_s=1.5, renderer="llvmpipe", device="cpu",
                  git_sha="abc", profile="quick", run_id=f"run-{method}-{view}",
                  reference_spp=256, reference_noise=0.01, scene_triangles=2000,
                  covered_pixels=1500, scene_vertices=1200, workers=1)
    values.update(fields)
    return ResultRow(**values)


def _noisy(method, knobs, psnr, *, memory, half=0.3):
    """Four views, each with the reference-noise interval psnr ± ``half`` dB."""
    return [_row(method, knobs, view=v, psnr=psnr + 0.01 * v, memory=memory,
                 psnr_masked_lo=psnr + 0.01 * v - half, psnr_masked_hi=psnr + 0.01 * v + half)
            for v in range(4)]


def _rows_at(rows, *, at, error="psnr_masked"):
    budget = parse_budget(at)
    points, _ = collect_points(rows, error=error, cost=budget.kind)
    return {r.method: r for r in best_within(points, budget=budget, error=error)}, budget


# -- parsing -----------------------------------------------------------------------------------

@pytest.mark.parametrize("text, kind, value", [
    ("memory=64MiB", "memory", 64 * MiB),
    ("memory=64 mib", "memory", 64 * MiB),
    ("memory=1.5KiB", "memory", 1536.0),
    ("memory=2GiB", "memory", 2 * 1024 * MiB),
    ("memory=512B", "memory", 512.0),
    ("memory=4096", "memory", 4096.0),
    ("ops=2e9", "ops", 2e9),
    ("ops=2G", "ops", 2e9),
    ("ops=3M", "ops", 3e6),
    ("ops=500k", "ops", 5e5),
    ("frame_ms=16.7", "frame_ms", 16.7),
    ("frame_ms=0.5s", "frame_ms", 500.0),
    ("precompute=600", "precompute", 600.0),
])
def test_parse_budget_units(text, kind, value):
    budget = parse_budget(text)
    assert budget.kind == kind and budget.value == pytest.approx(value, rel=1e-12)
    assert budget.text == text.split("=", 1)[1]  # as written: the report's file name


@pytest.mark.parametrize("text, message", [
    ("memory=lots", r"'lots' is not a memory budget; accepted: .*B, KiB, MiB, GiB"),
    ("speed=3", r"unknown budget kind 'speed'; accepted: .*frame_ms, memory, ops, precompute"),
    ("memry=3", r"unknown budget kind 'memry'; did you mean 'memory'\?"),
    ("memory=-1", r"memory budget must be finite and above 0, not '-1'"),
    ("memory=0", r"memory budget must be finite and above 0, not '0'"),
    ("memory=1e999", r"must be finite and above 0"),
    ("memory=", r"no memory value after '='; accepted: .*MiB"),
    ("memory", r"expected KIND=VALUE"),
    ("memory=64MB", r"unit 'MB' is not one memory takes; accepted: .*KiB, MiB, GiB"),
    ("ops=2m", r"unit 'm' is not one ops takes; accepted: .*k, M, G"),
    ("frame_ms=inf", r"'inf' is not a frame_ms budget"),
])
def test_parse_budget_refuses_bad_values(text, message):
    with pytest.raises(InvalidInputError) as caught:
        parse_budget(text)
    text_of = str(caught.value)
    assert "\n" not in text_of and text_of.startswith(f"--at '{text}'")
    assert re.search(message, text_of), text_of


def test_parse_budget_sets_the_cost_kind():
    assert parse_budget("memory=64MiB", cost="memory").kind == "memory"
    with pytest.raises(InvalidInputError, match="budgets memory but --cost is 'ops'; accepted: "
                                                "--cost memory, or no --cost"):
        parse_budget("memory=64MiB", cost="ops")
    with pytest.raises(UnknownNameError, match="unknown cost 'fps'"):
        parse_budget("memory=64MiB", cost="fps")


# -- the choice within the budget ---------------------------------------------------------------

def test_best_within_budget_per_method():
    rows = [_row(knobs={"sh_bands": n}, view=v, psnr=p + 0.01 * v, memory=m * MiB)
            for n, p, m in ((2, 20.0, 10), (3, 24.0, 40), (4, 28.0, 100)) for v in (0, 1)]
    # Equal error: the cheaper of the two is chosen.
    rows += [_row("vertex-tpfl", {"sh_bands": n}, view=v, psnr=22.0, memory=m * MiB)
             for n, m in ((3, 8), (4, 5)) for v in (0, 1)]
    rows += [_row("irradiance-volume", {"resolution": r}, view=v, psnr=30.0, memory=m * MiB)
             for r, m in ((4, 80), (8, 160)) for v in (0, 1)]
    by_method, budget = _rows_at(rows, at="memory=64MiB")
    # The 100 MiB configuration is better but over the budget.
    assert by_method["vertex"].point.config["sh_bands"] == 3
    assert by_method["vertex"].point.cost == pytest.approx(40 * MiB)
    assert by_method["vertex-tpfl"].point.config["sh_bands"] == 4
    # Every configuration over the budget: listed with its cheapest, never dropped.
    volume = by_method["irradiance-volume"]
    assert volume.point is None and volume.cheapest.config["resolution"] == 4
    assert volume.cheapest.cost == pytest.approx(80 * MiB)
    # Ordered by error, best first, then the methods with none within budget.
    ordered = best_within(collect_points(rows, error="psnr_masked", cost="memory")[0],
                          budget=budget, error="psnr_masked")
    assert [r.method for r in ordered] == ["vertex", "vertex-tpfl", "irradiance-volume"]
    # A budget at a configuration's cost takes it (within means <=).
    assert _rows_at(rows, at="memory=100MiB")[0]["vertex"].point.config["sh_bands"] == 4


def test_best_within_budget_for_flip_prefers_lower_and_reports_unknown_cost():
    rows = [_row(knobs={"sh_bands": n}, flip=f, frame_ms=ms)
            for n, f, ms in ((2, 0.30, 1.0), (3, 0.10, 2.0), (4, 0.05, 9.0))]
    rows += [_row("irradiance-volume", {"resolution": 4}, frame_ms=None)]
    by_method, _ = _rows_at(rows, at="frame_ms=5", error="flip_masked")
    assert by_method["vertex"].point.config["sh_bands"] == 3
    unknown = by_method["irradiance-volume"]
    assert unknown.point is None and unknown.cheapest is None and unknown.note


@pytest.mark.parametrize("gap_db, marks", [(0.05, (TIED, TIED)), (3.0, (BEST, ""))])
def test_best_only_beyond_the_intervals(gap_db, marks):
    # Against ±0.3 dB of reference noise on each of four views, a 0.05 dB lead is a tie;
    # a 3 dB lead is better beyond the intervals.
    rows = _noisy("vertex", {"sh_bands": 3}, 25.0, memory=20 * MiB)
    rows += _noisy("irradiance-volume", {"resolution": 8}, 25.0 - gap_db, memory=30 * MiB)
    by_method, _ = _rows_at(rows, at="memory=64MiB")
    assert (by_method["vertex"].mark, by_method["irradiance-volume"].mark) == marks
    # One method alone within the budget is the best there is.
    alone, _ = _rows_at(rows, at="memory=25MiB")
    assert alone["vertex"].mark == BEST and alone["irradiance-volume"].mark == ""


# -- the command -------------------------------------------------------------------------------

def _store(tmp_path):
    store = ResultsStore(tmp_path / "store.sqlite")
    rows = [_row(knobs={"sh_bands": n}, view=v, psnr=18.0 + n + 0.02 * v, memory=m * MiB,
                 run_id=f"sweep-{n}") for n, m in ((2, 8), (3, 32), (4, 96)) for v in (0, 1)]
    rows += [_row("irradiance-volume", {"resolution": r}, view=v, psnr=30.0, memory=m * MiB)
             for r, m in ((4, 80), (8, 160)) for v in (0, 1)]
    rows += [_row("vertex-tpfl", {"sh_bands": 4}, view=v, psnr=26.0 + 0.02 * v, memory=48 * MiB)
             for v in (0, 1)]
    rows += [_row(light="studio", psnr=20.0)]
    store.append(rows)
    return store, rows


def test_cli_writes_the_budget_table(tmp_path, capsys):
    store, rows = _store(tmp_path)
    reports = tmp_path / "reports"
    assert main(["pareto", "--scene", "plants", "--light", "sky", "--at", "memory=64MiB",
                 "--cost", "memory", "--results", str(store.path), "--reports", str(reports)]) == 0
    out = capsys.readouterr().out
    assert "irradiance-volume" in out and "none within budget (cheapest: 80 MiB)" in out
    stem = "budget-plants-sky-memory-64MiB"
    assert sorted(p.name for p in reports.iterdir()) == [f"{stem}.csv", f"{stem}.md"]
    with open(reports / f"{stem}.csv") as fh:
        table = list(csv.DictReader(fh))
    assert [line["method"] for line in table] == ["vertex-tpfl", "vertex", "irradiance-volume"]
    for line in table[:2]:  # every number is a mean of the stored rows it names
        mine = [r for r in rows if r.light == "sky" and r.method == line["method"]
                and json.dumps(r.config, sort_keys=True) == line["config"]]
        assert float(line["error"]) == pytest.approx(
            sum(r.metrics["psnr_masked"] for r in mine) / len(mine), abs=1e-12)
        assert float(line["cost"]) == sum(r.memory_bytes for r in mine) / len(mine)
        assert int(line["views"]) == len(mine) and line["within_budget"] == "1"
    assert json.loads(table[1]["config"])["sh_bands"] == 3  # 96 MiB is over the budget
    # 26 vs 21 dB with intervals of about ±0.13 dB: the leader is best beyond them.
    assert [line["mark"] for line in table] == [BEST, "", ""]
    assert table[2]["within_budget"] == "0" and float(table[2]["cheapest_cost"]) == 80 * MiB
    assert float(table[0]["budget"]) == 64 * MiB and table[0]["budget_as_written"] == "64MiB"
    md = (reports / f"{stem}.md").read_text()
    assert "| best | vertex-tpfl |" in md and "none within budget (cheapest: 80 MiB)" in md
    assert "--at memory=64MiB" in md and "2 of 3 methods" in md


def test_cli_budget_every_light_and_ops(tmp_path, capsys):
    store, _ = _store(tmp_path)
    assert main(["pareto", "--scene", "plants", "--at", "ops=2e9", "--results", str(store.path),
                 "--reports", str(tmp_path / "r")]) == 0
    out = capsys.readouterr().out
    assert "budget plants/sky" in out and "budget plants/studio" in out
    assert sorted(p.name for p in (tmp_path / "r").iterdir()) == [
        f"budget-plants-{light}-ops-2e9.{ext}" for light in ("sky", "studio")
        for ext in ("csv", "md")]


@pytest.mark.parametrize("args, message", [
    (["--at", "memory=lots"], r"--at 'memory=lots': 'lots' is not a memory budget; accepted:"),
    (["--at", "speed=3"], r"--at 'speed=3': unknown budget kind 'speed'; accepted:"),
    (["--at", "memory=-1"], r"--at 'memory=-1': a memory budget must be finite and above 0"),
    (["--at", "memory="], r"--at 'memory=': no memory value after '='; accepted:"),
    (["--at", "memory=64MiB", "--cost", "frame_ms"], r"budgets memory but --cost is 'frame_ms'"),
])
def test_cli_budget_bad_input(tmp_path, capsys, args, message):
    # The store does not exist: the budget is checked before anything is read or written.
    missing = tmp_path / "none.sqlite"
    assert main(["pareto", "--scene", "plants", "--results", str(missing), "--reports",
                 str(tmp_path / "r"), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("prtbench: error: ")
    assert re.search(message, err), err
    assert not (tmp_path / "r").exists() and not missing.exists()
