"""`prtbench regress`: drift, malformed baselines, the fresh cache, and the trivial-image gate.

Most cases replace :func:`prtbench.bench.regress.measure` by a fixed measurement (no rendering); the
mutation tests run the real ``vertex`` regression case with its renderer patched to return a
flat or a half-bright image, which the gate must reject.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from prtbench.api.errors import InvalidInputError
from prtbench.api.method import METHODS
from prtbench.bench import regress as regress_mod
from prtbench.bench.regress import TOLERANCES, Measurement, regress
from prtbench.bench.trivial import FLIP_MARGIN, PSNR_MARGIN_DB
from prtbench.cli import main

CASE = regress_mod.regression_case(METHODS.get("vertex"))
GOOD = {"psnr_masked": 22.0, "ssim_masked": 0.6, "flip_masked": 0.15, "mae": 0.04}
TRIVIAL = {"flat": {"psnr_masked": 17.0, "flip_masked": 0.40},
           "half": {"psnr_masked": 16.0, "flip_masked": 0.48}}


def _entry(metrics=GOOD, case=CASE):
    return {"case": case, "metrics": {m: {"value": metrics[m], "tolerance": TOLERANCES[m]}
                                      for m in TOLERANCES}}


@pytest.fixture
def fake(monkeypatch):
    """Replace measure() by a fixed Measurement; returns the dict of what it will report."""
    state = {"metrics": dict(GOOD), "trivial": {k: dict(v) for k, v in TRIVIAL.items()},
             "caches": []}

    def measure(name):
        state["caches"].append(os.environ.get("PRTBENCH_CACHE"))
        return Measurement(dict(CASE), dict(state["metrics"]),
                           {k: dict(v) for k, v in state["trivial"].items()})

    monkeypatch.setattr(regress_mod, "measure", measure)
    return state


def _write(tmp_path: Path, data) -> Path:
    path = tmp_path / "metrics.json"
    path.write_text(data if isinstance(data, str) else json.dumps(data))
    return path


def test_within_tolerance_passes_and_drift_beyond_it_fails(fake, tmp_path, capsys):
    path = _write(tmp_path, {"vertex": _entry()})
    fake["metrics"]["psnr_masked"] = GOOD["psnr_masked"] + 0.9 * TOLERANCES["psnr_masked"]
    assert regress(methods=["vertex"], baseline_path=path) is True
    fake["metrics"]["psnr_masked"] = GOOD["psnr_masked"] - 1.1 * TOLERANCES["psnr_masked"]
    assert regress(methods=["vertex"], baseline_path=path) is False
    assert "psnr_masked = 20.9000 (baseline 22.0000 ± 1.0) FAIL" in capsys.readouterr().out


def test_nan_metric_fails(fake, tmp_path):
    path = _write(tmp_path, {"vertex": _entry()})
    fake["metrics"]["mae"] = float("nan")
    assert regress(methods=["vertex"], baseline_path=path) is False


@pytest.mark.parametrize("text", ['{"vertex": {"case": ', "[1, 2]", '"metrics"', "null", "",
                                  "\xff\xfe"])
def test_unreadable_baseline_files_are_one_line_errors(fake, tmp_path, capsys, text):
    path = tmp_path / "metrics.json"
    path.write_bytes(text.encode("latin-1"))
    with pytest.raises(InvalidInputError, match="baseline file"):
        regress(methods=["vertex"], baseline_path=path)
    assert main(["regress", "--method", "vertex", "--baselines", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("prtbench: error: baseline file") and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1
    assert fake["caches"] == []  # refused before any work


def test_missing_baseline_file_is_an_error(fake, tmp_path):
    with pytest.raises(InvalidInputError, match="does not exist"):
        regress(methods=["vertex"], baseline_path=tmp_path / "absent.json")


_BAD_ENTRIES = {
    "no-metrics": {"case": CASE},
    "empty-metrics": {"case": CASE, "metrics": {}},
    "null-entry": None,
    "null-metrics": {"case": CASE, "metrics": None},
    "null-spec": {"case": CASE, "metrics": {"psnr_masked": None}},
    "null-value": {"case": CASE, "metrics": {"psnr_masked": {"value": None, "tolerance": 1.0}}},
    "text-value": {"case": CASE, "metrics": {"psnr_masked": {"value": "22", "tolerance": 1.0}}},
    "text-tolerance": {"case": CASE, "metrics": {"psnr_masked": {"value": 22.0,
                                                                 "tolerance": "wide"}}},
    "negative-tolerance": {"case": CASE, "metrics": {"psnr_masked": {"value": 22.0,
                                                                     "tolerance": -1}}},
    "bool-value": {"case": CASE, "metrics": {"psnr_masked": {"value": True, "tolerance": 1.0}}},
    "unknown-metric": {"case": CASE, "metrics": {"psnr_bogus": {"value": 22.0, "tolerance": 1.0}}},
    "entry-is-a-list": [1, 2],
    "other-case": _entry(case={**CASE, "scene": "cornell"}),
    "no-case": {"metrics": _entry()["metrics"]},
}


@pytest.mark.parametrize("kind", sorted(_BAD_ENTRIES))
def test_malformed_entries_fail_with_a_line_never_pass(fake, tmp_path, capsys, kind):
    path = _write(tmp_path, {"vertex": _BAD_ENTRIES[kind]})
    assert regress(methods=["vertex"], baseline_path=path) is False
    out = capsys.readouterr().out
    assert "vertex: FAIL" in out and "Traceback" not in out
    assert out.index("vertex: FAIL") < out.index("vertex: trivial")  # reported before the work
    assert main(["regress", "--method", "vertex", "--baselines", str(path)]) == 1


def test_missing_entry_fails(fake, tmp_path, capsys):
    path = _write(tmp_path, {"other-method": _entry()})
    assert regress(methods=["vertex"], baseline_path=path) is False
    assert "vertex: FAIL no baseline" in capsys.readouterr().out


def test_a_method_not_beating_a_trivial_image_fails_even_on_its_baseline(fake, tmp_path, capsys):
    weak = {**GOOD, "psnr_masked": TRIVIAL["flat"]["psnr_masked"] + 0.5 * PSNR_MARGIN_DB}
    path = _write(tmp_path, {"vertex": _entry(weak)})
    fake["metrics"] = dict(weak)
    assert regress(methods=["vertex"], baseline_path=path) is False
    out = capsys.readouterr().out
    assert "vertex: FAIL does not beat the flat image" in out
    assert "vertex: trivial flat: psnr_masked=17.0000, flip_masked=0.4000" in out
    # FLIP alone also fails the gate.
    fake["metrics"] = {**GOOD, "flip_masked": TRIVIAL["half"]["flip_masked"] - 0.5 * FLIP_MARGIN}
    path = _write(tmp_path, {"vertex": _entry(fake["metrics"])})
    assert regress(methods=["vertex"], baseline_path=path) is False
    assert "does not beat the half image" in capsys.readouterr().out


def test_update_writes_only_when_the_gate_passes(fake, tmp_path, capsys):
    path = _write(tmp_path, {"vertex": _entry()})
    before = path.read_text()
    fake["metrics"] = {**GOOD, "psnr_masked": 16.5}  # below the flat image
    assert regress(update=True, methods=["vertex"], baseline_path=path) is False
    assert path.read_text() == before
    captured = capsys.readouterr()
    assert "refused to update the baselines: vertex" in captured.err
    fake["metrics"] = {**GOOD, "psnr_masked": 23.0}
    assert regress(update=True, methods=["vertex"], baseline_path=path) is True
    assert json.loads(path.read_text())["vertex"]["metrics"]["psnr_masked"]["value"] == 23.0


def test_update_creates_a_missing_file(fake, tmp_path):
    path = tmp_path / "new" / "metrics.json"
    assert regress(update=True, methods=["vertex"], baseline_path=path) is True
    assert json.loads(path.read_text())["vertex"]["case"] == CASE


def test_a_fresh_temporary_cache_is_used_by_default_and_removed(fake, tmp_path, monkeypatch):
    user = tmp_path / "user-cache"
    monkeypatch.setenv("PRTBENCH_CACHE", str(user))
    path = _write(tmp_path, {"vertex": _entry()})
    assert regress(methods=["vertex"], baseline_path=path)
    seen = Path(fake["caches"][-1])
    assert seen != user and seen.name.startswith("prtbench-regress-") and not seen.exists()
    assert os.environ["PRTBENCH_CACHE"] == str(user)  # restored
    assert main(["regress", "--method", "vertex", "--baselines", str(path),
                 "--cache", str(tmp_path / "mine")]) == 0
    assert fake["caches"][-1] == str(tmp_path / "mine")
    monkeypatch.delenv("PRTBENCH_CACHE")
    monkeypatch.delenv("PRTBENCH_ASSETS", raising=False)
    assert regress(methods=["vertex"], baseline_path=path)
    assert "PRTBENCH_CACHE" not in os.environ and "PRTBENCH_ASSETS" not in os.environ


def test_fetched_assets_stay_visible_in_the_fresh_cache(tmp_path, monkeypatch):
    from prtbench.io.assets import assets_root

    monkeypatch.setenv("PRTBENCH_CACHE", str(tmp_path / "user"))
    monkeypatch.delenv("PRTBENCH_ASSETS", raising=False)
    seen = []
    monkeypatch.setattr(regress_mod, "measure", lambda name: seen.append(assets_root()) or
                        Measurement(dict(CASE), dict(GOOD), {k: dict(v) for k, v in TRIVIAL.items()}))
    assert regress(methods=["vertex"], baseline_path=_write(tmp_path, {"vertex": _entry()}))
    assert seen == [tmp_path / "user" / "assets"]


# --- the real vertex case: mutations must fail, the unpatched method passes -----------------------

def _patch_render(monkeypatch, transform):
    """Make VertexRenderer.render return ``transform(true image, geometry mask)``."""
    from methods.vertex.diffuse import VertexRenderer
    from prtbench.transport.raytrace import geometry_mask

    original = VertexRenderer.render

    def render(self, view, light):
        image = original(self, view, light)
        mask = geometry_mask(self.scene, view, image.shape[1], image.shape[0])
        return transform(image, mask).astype(np.float32)

    monkeypatch.setattr(VertexRenderer, "render", render)


def _flat(image, mask):
    out = np.zeros_like(image)
    out[mask] = image[mask].mean(axis=0)  # the mean colour of the true render, on the geometry
    return out


def test_the_real_vertex_case_passes_and_leaves_the_session_cache_alone(capsys, monkeypatch,
                                                                       tmp_path):
    from prtbench.api.cache import cache_root

    # A cache of this test's own: the run's shared cache changes under other xdist workers.
    monkeypatch.setenv("PRTBENCH_CACHE", str(tmp_path / "session-cache"))
    before = set(cache_root().rglob("*")) if cache_root().exists() else set()
    assert regress(methods=["vertex"]) is True, capsys.readouterr().out
    out = capsys.readouterr().out
    assert "vertex: gate ok" in out and "trivial unshadowed" in out
    after = set(cache_root().rglob("*")) if cache_root().exists() else set()
    assert after == before  # everything went to the temporary cache


@pytest.mark.parametrize("mutation", ["flat", "half"])
def test_a_renderer_returning_a_trivial_image_fails_regress(monkeypatch, capsys, mutation):
    transform = _flat if mutation == "flat" else (lambda image, mask: 0.5 * image)
    _patch_render(monkeypatch, transform)
    assert regress(methods=["vertex"]) is False
    assert f"vertex: FAIL does not beat the {mutation} image" in capsys.readouterr().out


def test_a_known_metric_the_run_does_not_produce_fails(fake, tmp_path, capsys):
    path = _write(tmp_path, {"vertex": {"case": CASE, "metrics": {
        "flip_hdr": {"value": 0.1, "tolerance": 0.1}}}})  # needs HDR images: never in regress
    assert regress(methods=["vertex"], baseline_path=path) is False
    assert "vertex: FAIL baseline metric 'flip_hdr' is not produced" in capsys.readouterr().out


def test_a_cache_that_is_a_file_is_refused(fake, tmp_path):
    path = _write(tmp_path, {"vertex": _entry()})
    (tmp_path / "file").write_text("x")
    with pytest.raises(InvalidInputError, match="is a file"):
        regress(methods=["vertex"], baseline_path=path, cache=tmp_path / "file")
    assert fake["caches"] == []


def test_case_job_applies_the_case_scene_params_and_overrides():
    from prtbench.bench.regress import case_job

    vertex = case_job("vertex")
    assert vertex.profile == "smoke" and vertex.scene_params == CASE["scene_params"]
    learnt = case_job("learnt", overrides={"visibility": False})
    assert learnt.overrides == {"samples": 32_768, "epochs": 40, "visibility": False}
