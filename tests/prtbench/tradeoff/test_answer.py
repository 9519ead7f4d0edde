"""prtbench answer: the demo's plain-language last word, every number from files and rows."""

from __future__ import annotations

import json

import pytest

from prtbench.api.errors import PrtbenchError
from prtbench.cli import main
from prtbench.store.results import ResultsStore
from prtbench.tradeoff.answer import answer, requirements
from tests.prtbench.tradeoff.test_pareto import _row

ANALYSIS = {"scene": "plants", "variant": "diffuse", "light": "sky", "light_changes": "none",
            "target": 0.01, "required_bands": 9, "needs_glossy": False, "glossy_bands": 0,
            "needs_shadows": True, "needs_textures": True, "needs_bounces": False,
            "fixed_light_ok": True}


def _files(tmp_path):
    store = ResultsStore(tmp_path / "store.sqlite")
    rows = [_row(knobs={"sh_bands": n}, view=v, psnr=20.0 + n + 0.02 * v, frame_ms=1.0 + n,
                 profile="quick", psnr_masked_lo=19.7 + n, psnr_masked_hi=20.3 + n + 0.02 * v)
            for n in (2, 3, 4, 5) for v in (0, 1)]
    store.append(rows)
    (tmp_path / "analysis.json").write_text(json.dumps(ANALYSIS))
    advice = {"method": "vertex", "config": {"sh_bands": 4}, "cost_kind": "ops",
              "metrics": {"psnr_masked": 24.01}, "frame_ms": 5.0, "memory_bytes": 1000,
              "runner_up": {"method": "vertex", "config": {"sh_bands": 5},
                            "metrics": {"psnr_masked": 25.01}}}
    (tmp_path / "advice.json").write_text(json.dumps(advice))
    return store


def test_the_answer_names_the_need_the_choice_with_its_interval_and_the_front(tmp_path):
    store = _files(tmp_path)
    text = answer(analysis_path=tmp_path / "analysis.json", advice_path=tmp_path / "advice.json",
                  results_path=store.path, target="psnr_masked>=24",
                  site=tmp_path / "site" / "index.html")
    lines = text.splitlines()
    assert lines[0] == "Answer for plants (diffuse) under sky, quick profile:"
    assert "9 SH bands for a 1 % irradiance error" in lines[1]
    # The choice, with the interval of its stored views (mean of the views' noise intervals
    # widened by the spread over two views) and the target it meets.
    assert lines[2].startswith("  use vertex sh_bands=4: 24.0 dB masked PSNR [")
    assert "that meets psnr_masked>=24." in lines[2] and "5 ms a frame on llvmpipe" in lines[2]
    lo, hi = map(float, lines[2].split("PSNR [")[1].split("]")[0].split(", "))
    assert lo <= 24.0 <= hi  # the interval is the advised run's own, never another panel's
    assert lines[3] == "  runner-up: vertex sh_bands=5, 25.0 dB"
    assert "the front (4 of 4 configurations;" in lines[4]
    assert [line.split()[0] for line in lines[5:8]] == ["cheapest", "middle", "accurate"]
    assert lines[-1].endswith("site/index.html")


def test_requirements_read_like_the_analysis():
    assert requirements({**ANALYSIS, "required_bands": 17}).startswith("more than 16 SH bands")
    glossy = requirements({**ANALYSIS, "needs_glossy": True, "needs_bounces": True})
    assert "glossy transfer" in glossy and "interreflections" in glossy


def test_missing_files_are_one_line_errors(tmp_path, capsys):
    _files(tmp_path)
    with pytest.raises(PrtbenchError, match="analyze JSON 'nope.json' does not exist"):
        answer(analysis_path="nope.json", advice_path=tmp_path / "advice.json",
               results_path=tmp_path / "store.sqlite")
    status = main(["answer", "--analysis", str(tmp_path / "analysis.json"), "--advice",
                   str(tmp_path / "analysis.json" / "x"), "--results", str(tmp_path / "store.sqlite")])
    err = capsys.readouterr().err.strip()
    assert status == 2 and err.startswith("prtbench: error: advise JSON") and "\n" not in err
