"""Regression variants (``method:variant`` cases, e.g. ``sloan-matrix:cpca``): named, run with
their overrides, compared with their own baseline entry; an unknown variant is a one-line error."""

from __future__ import annotations

import json

import pytest

from prtbench.api.errors import UnknownNameError
from prtbench.bench import regress as regress_mod
from prtbench.bench.regress import TOLERANCES, Measurement, case_job, case_names, regress
from prtbench.cli import main

GOOD = {"psnr_masked": 22.0, "ssim_masked": 0.6, "flip_masked": 0.15, "mae": 0.04}
TRIVIAL = {"flat": {"psnr_masked": 17.0, "flip_masked": 0.40}}


def test_variant_cases_are_listed_and_carry_their_overrides():
    names = case_names()
    assert "sloan-matrix" in names and "sloan-matrix:cpca" in names
    assert names.index("sloan-matrix:cpca") == names.index("sloan-matrix") + 1
    plain, variant = case_job("sloan-matrix"), case_job("sloan-matrix:cpca")
    assert variant.method == "sloan-matrix" and "compress" not in plain.overrides
    assert variant.overrides["compress"] == "cpca" and variant.scene == plain.scene
    # --set overrides still come last.
    assert case_job("sloan-matrix:cpca", overrides={"clusters": 8}).overrides["clusters"] == 8


def test_unknown_variant_is_a_one_line_error(capsys):
    with pytest.raises(UnknownNameError, match="unknown regression case 'sloan-matrix:zip'"):
        case_job("sloan-matrix:zip")
    assert main(["regress", "--method", "sloan-matrix:zip"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("prtbench: error: unknown regression case") and "Traceback" not in err


def test_a_variant_is_compared_with_its_own_entry(monkeypatch, tmp_path, capsys):
    seen = []

    def measure(name):
        seen.append(name)
        return Measurement(regress_mod._case_of(name), dict(GOOD), dict(TRIVIAL))

    monkeypatch.setattr(regress_mod, "measure", measure)
    path = tmp_path / "metrics.json"
    entry = {"case": regress_mod._case_of("sloan-matrix:cpca"),
             "metrics": {m: {"value": GOOD[m], "tolerance": t} for m, t in TOLERANCES.items()}}
    path.write_text(json.dumps({"sloan-matrix": {**entry, "case": regress_mod._case_of(
        "sloan-matrix")}}))
    assert regress(methods=["sloan-matrix:cpca"], baseline_path=path) is False
    assert "sloan-matrix:cpca: FAIL no baseline" in capsys.readouterr().out
    path.write_text(json.dumps({"sloan-matrix:cpca": entry}))
    assert regress(methods=["sloan-matrix:cpca"], baseline_path=path) is True
    assert set(seen) == {"sloan-matrix:cpca"}
    # The plain method's case is not the variant's: its entry does not pass for it.
    path.write_text(json.dumps({"sloan-matrix:cpca": {**entry, "case": regress_mod._case_of(
        "sloan-matrix")}}))
    assert regress(methods=["sloan-matrix:cpca"], baseline_path=path) is False
