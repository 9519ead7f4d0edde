"""Stability matrix pieces (issue #15): the classifier, the artifact statistics, the case
catalogue generated from Config fields, the extreme lights, the case scenes, the timeout, the
report writer and the command's one-line errors. The smoke matrix itself is
``test_stability_smoke.py``."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from prtbench.api.config import knob
from prtbench.api.errors import InvalidInputError
from prtbench.stability import cases as cases_mod
from prtbench.stability.case import Case
from prtbench.stability.cases import knob_cases
from prtbench.stability.outcome import FLIP_MARGIN, PSNR_MARGIN_DB, classify
from prtbench.stability.run import artifact_stats

MODERATE = {"psnr_masked": 25.0, "flip_masked": 0.10}
GOOD = {"error_kind": "", "artifact_nonfinite": 0, "image_nonfinite": 0, "psnr_masked": 24.5,
        "flip_masked": 0.11, "reference_black": False, "image_black": False}


# --- the classifier ----------------------------------------------------------------------------

def test_a_finite_result_close_to_the_moderate_setting_is_ok():
    assert classify(GOOD, MODERATE)[0] == "ok"


@pytest.mark.parametrize("key", ["artifact_nonfinite", "image_nonfinite"])
def test_a_nan_anywhere_is_failed_whatever_the_metrics(key):
    outcome, reason = classify({**GOOD, key: 3}, MODERATE)
    assert outcome == "failed" and "3 non-finite values" in reason


def test_a_clear_one_line_error_is_refused_and_a_multi_line_one_is_failed():
    message = "config key 'samples' of LearntConfig got 1; accepted: [64, 67108864]"
    assert classify({"error_kind": "refused", "error": message}, MODERATE) == ("refused", message)
    assert classify({"error_kind": "refused", "error": "line one\nline two"}, MODERATE)[0] == "failed"
    assert classify({"error_kind": "refused", "error": ""}, MODERATE)[0] == "failed"


@pytest.mark.parametrize("kind", ["exception", "crash", "timeout"])
def test_exceptions_crashes_and_hangs_are_failed(kind):
    outcome, reason = classify({"error_kind": kind, "error": "boom"}, MODERATE)
    assert outcome == "failed" and reason.startswith(kind)


def test_worse_than_the_moderate_setting_by_more_than_the_margin_is_degraded():
    just_inside = {**GOOD, "psnr_masked": MODERATE["psnr_masked"] - PSNR_MARGIN_DB + 0.01}
    past = {**GOOD, "psnr_masked": MODERATE["psnr_masked"] - PSNR_MARGIN_DB - 0.01}
    assert classify(just_inside, MODERATE)[0] == "ok"
    outcome, reason = classify(past, MODERATE)
    assert outcome == "degraded" and "masked PSNR" in reason
    flip = {**GOOD, "flip_masked": MODERATE["flip_masked"] + FLIP_MARGIN + 0.01}
    assert classify(flip, MODERATE)[0] == "degraded"
    # Better than the moderate setting is never degraded (an infinite PSNR: identical images).
    assert classify({**GOOD, "psnr_masked": math.inf, "flip_masked": 0.0}, MODERATE)[0] == "ok"


def test_black_light_cases_and_unmeasured_metrics():
    black = {**GOOD, "reference_black": True, "image_black": True, "psnr_masked": None}
    assert classify(black, MODERATE)[0] == "ok"
    assert classify({**black, "image_black": False}, MODERATE)[0] == "degraded"
    # Without a moderate measurement nothing is called degraded, and the reason says so.
    outcome, reason = classify({**GOOD, "psnr_masked": 5.0}, {})
    assert outcome == "ok" and "no measurement to compare" in reason
    # Finite images whose masked metrics are NaN measured nothing: a bug of the case.
    assert classify({**GOOD, "psnr_masked": None}, MODERATE)[0] == "failed"


# --- artifact statistics -----------------------------------------------------------------------

def test_artifact_stats_count_half_float_overflow_underflow_and_nan():
    arrays = {"transfer": np.array([7.0e4, -1.0e-6, 1.0, 0.0, np.nan], dtype=np.float32),
              "ids": np.arange(4, dtype=np.int32)}  # not a float array: skipped
    stats = artifact_stats(arrays, np.dtype(np.float16))
    assert stats["artifact_nonfinite"] == 1
    assert stats["overflow"] == 1 and stats["underflow"] == 1  # 0.0 is not an underflow
    assert stats["artifact_peak"] == pytest.approx(7.0e4)
    assert stats["storage_max"] == 65504.0 and stats["artifact_values"] == 5
    assert artifact_stats(arrays, np.dtype(np.float32))["overflow"] == 0


# --- the catalogue -----------------------------------------------------------------------------

@dataclass
class _FakeConfig:
    sh_bands: int = knob(3, "bands", low=1, high=6)
    ridge: float = knob(0.1, "ridge", low=0.0, high=1e6)
    storage: str = knob("float32", "storage", choices=("float32", "float16"))
    width: int = knob(8, "a knob without a rule", low=1, high=64)


class _FakeMethod:
    Config = _FakeConfig

    @classmethod
    def make_config(cls, overrides=None, *, profile="quick"):
        return _FakeConfig(**(overrides or {}))


def test_cases_come_from_the_config_fields_and_their_declared_bounds():
    names = [c.name for c in knob_cases(_FakeMethod, profile="quick")]
    assert names == ["sh_bands=1", "sh_bands=2", "sh_bands=6", "ridge=0", "ridge=1e+06",
                     "storage=float16", "storage=float16 light=huge-constant"]
    by_name = {c.name: c for c in knob_cases(_FakeMethod, profile="quick")}
    assert by_name["ridge=1e+06"].overrides == {"ridge": 1e6}
    assert all(c.advice for c in by_name.values())
    # Half-float storage is also measured under the 10⁶ light (its own picture: no image
    # comparison with the moderate render).
    combo = by_name["storage=float16 light=huge-constant"]
    assert combo.light == "huge-constant" and not combo.compare_image
    assert by_name["storage=float16"].compare_image and by_name["ridge=0"].compare_image
    # The moderate value itself is not a case; smoke keeps the ends only.
    moderate_3 = [c.name for c in knob_cases(_FakeMethod, profile="smoke")]
    assert moderate_3 == ["sh_bands=1", "sh_bands=6", "ridge=0", "ridge=1e+06", "storage=float16",
                          "storage=float16 light=huge-constant"]


def test_a_knob_that_needs_another_knob_gets_it_in_its_cases():
    # wavelet-image reads sh_bands only with lighting='sh': its band cases must set it, or
    # they would render the moderate (wavelet-lit) picture again and be called ok.
    from prtbench.api.method import METHODS

    image = {c.name: c for c in knob_cases(METHODS.get("wavelet-image"), profile="quick")}
    bands = [c for c in image.values() if "sh_bands" in c.overrides]
    assert [c.name for c in bands] == ["lighting=sh sh_bands=1", "lighting=sh sh_bands=2",
                                       "lighting=sh sh_bands=64"]
    assert all(c.overrides["lighting"] == "sh" and "lighting=sh" in c.note for c in bands)
    vertex = {c.name: c for c in knob_cases(METHODS.get("vertex"), profile="quick")}
    assert vertex["sh_bands=1"].overrides == {"sh_bands": 1}


def test_every_registered_method_gets_the_shared_cases():
    from prtbench.api.method import METHODS

    for name in ("vertex", "texture-tpfl"):
        cases = cases_mod.method_cases(METHODS.get(name), profile="quick")
        names = [c.name for c in cases]
        assert names[0] == "moderate" and len(set(names)) == len(names)
        for shared in ("light=black", "light=sun-0.1deg", "scale=1e-04", "translate=1e+05",
                       "geometry=grazing"):
            assert shared in names
    glossy = [c.name for c in cases_mod.method_cases(METHODS.get("texture-tpfl"), profile="quick")]
    diffuse = [c.name for c in cases_mod.method_cases(METHODS.get("vertex"), profile="quick")]
    assert "shininess=1e+05" in glossy and not any(n.startswith("shininess") for n in diffuse)
    assert "storage=float16" in glossy and "storage=float16" not in diffuse


def test_every_case_of_every_method_says_what_to_do_instead():
    # The report prints a case's advice for each degraded row: a case without one would leave
    # the user with "None".
    from prtbench.api.method import METHODS

    for name in METHODS.names():
        cases = cases_mod.method_cases(METHODS.get(name), profile="quick")
        assert len({c.name for c in cases}) == len(cases), name
        assert [c.name for c in cases if c.name != "moderate" and not c.advice.strip()] == [], name


def test_shininess_advice_names_the_methods_own_basis():
    # An SH method's lobe is cut by its bands; a wavelet method's by its cubemap and the terms it
    # keeps: advising "<= 8 SH bands" to a method without SH bands would name the wrong cause.
    from prtbench.api.method import METHODS

    def advice(name):
        return {c.advice for c in cases_mod.method_cases(METHODS.get(name), profile="quick")
                if c.name.startswith("shininess=")}

    assert advice("sloan-matrix") == {cases_mod.material_advice(METHODS.get("sloan-matrix"))}
    assert "SH bands" in advice("sloan-matrix").pop()
    (text,) = advice("wavelet-tp")
    assert text.startswith("use exponents <= 1e3, or raise cubemap: "), text
    (text,) = advice("neural-wavelet")
    assert "SH bands" not in text and "raise cubemap and reflect_degree" in text, text


def test_light_advice_names_the_methods_own_basis():
    # A 0.1-degree sun rings in SH bands; a wavelet method spreads it over one cubemap texel, or
    # over the triangles between its vertices; a learnt one is only fitted under its training
    # lights.
    from prtbench.api.method import METHODS

    def advice(name):
        return {c.name: c.advice for c in cases_mod.method_cases(METHODS.get(name),
                                                                  profile="quick")
                if c.name.startswith("light=")}

    vertex, wavelet_tp = advice("vertex"), advice("wavelet-tp")
    assert vertex["light=sun-0.1deg"].startswith("subdivide the receiving surfaces, then raise "
                                                 "sh_bands"), vertex
    assert vertex["light=below-horizon"].startswith("more SH bands"), vertex
    assert advice("texture-tp")["light=sun-0.1deg"].startswith("more SH bands")  # per texel
    # Per-vertex wavelet transport: the sun's shadow is cut by the mesh, not by the cubemap.
    for name in ("light=sun-0.1deg", "light=single-texel"):
        assert wavelet_tp[name].startswith("subdivide the receiving surfaces"), wavelet_tp
    assert wavelet_tp["light=below-horizon"].startswith("raise light_terms and keep:")
    assert not any("SH bands" in a or "train_lights" in a for a in wavelet_tp.values())
    # wavelet-image has sh_bands too, but only for lighting='sh'; it lights with wavelets, per
    # pixel: its small sources are cut by the cubemap's texels.
    assert "one cubemap texel" in advice("wavelet-image")["light=sun-0.1deg"]
    neural = advice("neural-wavelet")
    assert all("train_lights" in a and "light_tilt" not in a for a in neural.values()), neural
    assert neural["light=below-horizon"].startswith("train under lights like this one")
    assert neural["light=sun-0.1deg"].startswith("raise cubemap")


# --- lights ------------------------------------------------------------------------------------

def test_extreme_lights_deliver_what_they_claim():
    from prtbench.stability import lights

    assert not lights.black().image.any()
    assert lights.huge_constant().image.min() == lights.HUGE_RADIANCE
    for light in (lights.single_texel(), lights.near_delta_sun()):
        # Irradiance at normal incidence towards the sun is π (exact quadrature of the map).
        dirs, omega = light.texel_directions(), light.texel_solid_angles()
        lum = light.image[..., 0].astype(np.float64)
        e = np.sum(lum * omega * np.clip(dirs @ lights._sun_direction(), 0.0, None))
        assert e == pytest.approx(math.pi, rel=0.02)
    assert np.count_nonzero(lights.single_texel().image[..., 0]) == 1
    sun = lights.near_delta_sun().image[..., 0]
    assert sun.max() / sun.min() == pytest.approx(lights.SUN_DYNAMIC_RANGE, rel=1e-5)
    below = lights.below_horizon()
    up = below.texel_directions()[..., 1]
    assert below.image[up > 0.01].max() == 0.0 and below.image[up < -0.01].min() == 1.0
    assert lights.hdri_2048().image.shape == (1024, 2048, 3)


# --- case scenes -------------------------------------------------------------------------------

def _base():
    from prtbench.scene.registry import get_scene

    return get_scene("sphere-over-plane", variant="glossy", sphere_segments=16).with_views(1)


def test_scaled_scene_scales_the_world_and_keeps_the_canonical_picture():
    # The canonical frame (DESIGN.md §22): the world is scaled (world_from_canonical, recorded
    # in params), the canonical geometry and views the base's own.
    from prtbench.stability.scenes import case_scene

    base = _base()
    big = case_scene(base, Case("scale=1e+04", "scene", scale=1e4))
    lo, hi = big.world_bounds()
    assert np.linalg.norm(hi - lo) == pytest.approx(1e4 * base.diagonal(), rel=1e-6)
    assert big.world_from_canonical.scale == pytest.approx(1e4)
    world_eye = big.world_from_canonical.view(big.trajectory.views[0]).eye
    assert np.allclose(world_eye, 1e4 * np.asarray(base.trajectory.views[0].eye))
    assert np.allclose(big.trajectory.views[0].eye, base.trajectory.views[0].eye)
    assert big.diagonal() == pytest.approx(base.diagonal(), rel=1e-6)
    assert big.params["stability_case"] == "scale=1e+04"
    assert big.params["world_from_canonical"]["scale"] == pytest.approx(1e4)


def test_case_scenes_refuse_only_undefined_extents_or_materials_out_of_range():
    from prtbench.stability.scenes import case_scene

    # Once refused by the float32 extent check, now rendered in the canonical frame.
    case_scene(_base(), Case("scale=1e-04", "scene", scale=1e-4))
    case_scene(_base(), Case("translate=1e+05", "scene", translate=1e5))
    with pytest.raises(InvalidInputError, match=r"has zero extent .* accepted: a bounds diagonal"):
        case_scene(_base(), Case("scale=1e-320", "scene", scale=1e-320))
    with pytest.raises(InvalidInputError, match=r"shininess=100000.0; accepted: \[0, 10000\]"):
        case_scene(_base(), Case("shininess=1e+05", "material", shininess=1e5))
    glossy = case_scene(_base(), Case("shininess=1e+04", "material", shininess=1e4))
    assert {o.material.shininess for o in glossy.objects} == {1e4}


def test_geometry_cases_change_only_what_they_say():
    from prtbench.stability.scenes import case_scene

    base = _base()
    degenerate = case_scene(base, Case("geometry=degenerate", "scene", geometry="degenerate"))
    ground = degenerate.objects[0].mesh
    assert ground.n_triangles == 3 * base.objects[0].mesh.n_triangles
    n, areas = base.objects[0].mesh.n_triangles, ground.triangle_areas()
    assert np.all(areas[n:2 * n] == 0.0)  # zero-area copies
    assert np.all((areas[2 * n:] > 0) & (areas[2 * n:] < 1e-5 * areas[:n].max()))  # slivers
    flipped = case_scene(base, Case("geometry=flipped-normals", "scene", geometry="flipped-normals"))
    assert np.allclose(flipped.objects[1].mesh.normals, -base.objects[1].mesh.normals)
    assert np.allclose(flipped.objects[0].mesh.normals, base.objects[0].mesh.normals)
    grazing = case_scene(base, Case("geometry=grazing", "scene", geometry="grazing"))
    eye = grazing.trajectory.views[0].eye
    assert 0.0 < eye[1] <= 2e-3 * base.diagonal()
    edge = case_scene(base, Case("geometry=edge-on", "scene", geometry="edge-on"))
    one = edge.objects[0].mesh
    assert one.n_triangles == 1 and edge.trajectory.views[0].eye[1] == 0.0  # in its plane
    lo, hi = base.objects[0].mesh.positions.min(0), base.objects[0].mesh.positions.max(0)
    assert np.all(one.positions.min(0)[[0, 2]] < lo[[0, 2]])  # still covers the old ground
    assert np.all(one.positions.max(0)[[0, 2]] > hi[[0, 2]])
    assert np.cross(*(one.positions[1:] - one.positions[0]))[1] > 0  # faces +Y
    t = case_scene(base, Case("geometry=t-junction", "scene", geometry="t-junction"))
    tj = t.objects[0].mesh
    assert tj.n_triangles == base.objects[0].mesh.n_triangles + 1
    assert tj.triangle_areas().sum() == pytest.approx(base.objects[0].mesh.triangle_areas().sum())
    # The new vertex lies on an edge of a triangle that does not use it: a T-junction.
    m = tj.n_vertices - 1
    assert sum(m in face for face in tj.faces) == 2


# --- the process runner ------------------------------------------------------------------------

def test_a_case_past_its_timeout_is_killed_and_reported(tmp_path):
    from prtbench.stability.run import run_case

    out = run_case("vertex", Case("moderate", "moderate"), profile="smoke",
                   base=cases_mod.BASE_SCENE, results_path=tmp_path / "r.sqlite",
                   out_dir=tmp_path / "out", timeout_s=0.05)
    assert out["error_kind"] == "timeout" and classify(out, MODERATE)[0] == "failed"


# --- report and command ------------------------------------------------------------------------

def test_report_summarises_each_method_and_says_what_to_do_instead(tmp_path):
    from prtbench.stability.report import format_csv, method_summary, write_reports

    rows = [{"method": "m", "case": "moderate", "outcome": "ok", "reason": "", "psnr_masked": 25.0},
            {"method": "m", "case": "sh_bands=1", "outcome": "degraded", "reason": "-9 dB",
             "advice": "use 3-5 bands", "note": "bands", "overflow": 0.0},
            {"method": "m", "case": "samples=1", "outcome": "refused", "reason": "accepted: ..."}]
    line = method_summary("m", rows)
    assert line == "m: ok in 1 cases, degraded at sh_bands=1 (-9 dB), refused 1 (samples=1)"
    md, csv_path = write_reports(rows, tmp_path)
    text = md.read_text()
    assert "use 3-5 bands" in text and "| sh_bands=1 | **degraded** |" in text
    assert format_csv(rows).splitlines()[2].startswith("m,sh_bands=1,,degraded,-9 dB")
    assert csv_path.read_text() == format_csv(rows)


@pytest.mark.parametrize("argv, fragment", [
    (["--profile", "paper"], "unknown stability profile 'paper'"),
    (["--method", "vertx"], "unknown method 'vertx'"),
    (["--method", "vertex", "--case", "light=blak"], "unknown stability case 'light=blak'"),
    (["--method", "vertex", "--timeout", "0"], "--timeout 0.0; accepted"),
])
def test_command_errors_are_one_line_exit_2_before_any_work(tmp_path, capsys, argv, fragment):
    from prtbench.cli import main

    results, reports = tmp_path / "r.sqlite", tmp_path / "reports"
    status = main(["stability", *argv, "--results", str(results), "--reports", str(reports)])
    err = capsys.readouterr().err.strip()
    assert status == 2 and err.startswith("prtbench: error: ") and "\n" not in err
    assert fragment in err
    assert not results.exists() and not reports.exists()


def test_from_store_merges_the_newest_row_of_each_case_and_marks_partial_runs(tmp_path):
    from prtbench.api.errors import PrtbenchError
    from prtbench.stability.matrix import TABLE, stored_rows
    from prtbench.store import measurements

    store = tmp_path / "r.sqlite"

    def run(rows, *, complete):
        run_id = measurements.new_run_id()
        measurements.record(TABLE, rows, results_path=store, run_id=run_id, profile="smoke",
                            git_sha="abc")
        if complete:
            measurements.complete_report("table", TABLE, profile="smoke", run_id=run_id,
                                         members={}, results_path=store, git_sha="abc")

    with pytest.raises(PrtbenchError, match="no complete stability run for profile 'smoke'"):
        stored_rows(profile="smoke", results_path=store)
    run([{"method": "a", "case": "moderate", "outcome": "ok"},
         {"method": "b", "case": "moderate", "outcome": "failed"}], complete=True)
    run([{"method": "b", "case": "moderate", "outcome": "ok"}], complete=True)   # newer b
    run([{"method": "a", "case": "moderate", "outcome": "degraded"},
         {"method": "a", "case": "light=black", "outcome": "ok"}], complete=False)
    rows = stored_rows(profile="smoke", results_path=store)
    assert [(r["method"], r["case"], r["outcome"], r["partial_run"]) for r in rows] == [
        ("a", "moderate", "ok", False), ("b", "moderate", "ok", False)]
    rows = stored_rows(profile="smoke", results_path=store, partial=True)
    assert [(r["method"], r["case"], r["outcome"], r["partial_run"]) for r in rows] == [
        ("a", "moderate", "degraded", True), ("a", "light=black", "ok", True),
        ("b", "moderate", "ok", False)]


def test_report_lists_what_the_catalogue_has_and_the_store_does_not():
    from prtbench.stability.report import coverage_lines, format_markdown

    rows = [{"method": "m", "case": "moderate", "outcome": "ok", "reason": "", "wall_s": 10.0,
             "git_sha": "old", "timestamp": "2026-12-02T02:00:00+00:00", "load_1m": 1.25},
            {"method": "m", "case": "light=black", "outcome": "ok", "reason": "", "wall_s": 300.0,
             "git_sha": "new", "timestamp": "2026-12-02T10:00:00+00:00", "load_1m": 2.5,
             "partial_run": True},
            {"method": "m", "case": "gone", "outcome": "ok", "reason": "", "git_sha": "old",
             "timestamp": "2026-12-02T01:00:00+00:00"}]
    expected = {"m": ["moderate", "light=black", "scale=1e-04", "sh_bands=1"],
                "absent": ["moderate", "keep=1"]}
    lines = coverage_lines(rows, expected, ["trained cases take 10 min each"])
    text = "\n".join(lines)
    # 2 of the 6 catalogue cases have rows; the stale 'gone' row does not count as coverage.
    assert "2 of the 6 catalogue cases of 2 methods have a stored row; 4 have none" in text
    assert ("- m: 2 of 4 cases not measured; its measured cases took 2.6 min median, 5.0 min "
            "at most: `scale=1e-04`, `sh_bands=1`") in text
    assert "- absent: **not measured** (no stored row; 2 cases in its catalogue)" in text
    assert "m `gone`" in text and "\nWhy:\n\n- trained cases take 10 min each" in text
    assert coverage_lines(rows, None) == []
    md = format_markdown(rows, expected=expected)
    # A registered method without rows is in the summary too, not silently absent.
    assert "- absent: **not measured** (no stored row)" in md
    assert "| light=black † | **ok** |" in md and "m (1 of 3 rows)" in md
    assert "newest row `new`" in md and "Load (1-min average" in md and "1.25-2.50" in md
    full = coverage_lines(rows[:2], {"m": ["moderate", "light=black"]})
    assert full[-1].endswith("cases of 1 method have a stored row; 0 have none.")
    noted = coverage_lines(rows[:2], {"m": ["moderate", "light=black"]}, ["measured at a0"])
    assert noted[-3:] == ["Notes:", "", "- measured at a0"]
    one = coverage_lines(rows[:2], {"m": ["moderate", "light=black", "sh_bands=1"]})
    assert "2 of the 3 catalogue cases of 1 method have a stored row; 1 has none:" in one


def test_core_case_names_are_the_rows_core_rows_measures():
    from prtbench.stability.core import core_case_names, core_rows

    assert core_case_names(profile="smoke") == [r["case"] for r in core_rows(profile="smoke")]
    assert len(core_case_names(profile="quick")) == 2 * 16 * 3 + 5


def test_from_store_report_names_every_registered_method_without_rows(tmp_path, capsys):
    from prtbench.api.method import METHODS
    from prtbench.cli import main
    from prtbench.stability.matrix import TABLE
    from prtbench.store import measurements

    store, reports = tmp_path / "r.sqlite", tmp_path / "reports"
    run_id = measurements.new_run_id()
    measurements.record(TABLE, [{"method": "vertex", "case": "moderate", "outcome": "ok",
                                 "reason": "the moderate setting", "wall_s": 12.0}],
                        results_path=store, run_id=run_id, profile="smoke", git_sha="abc")
    measurements.complete_report("table", TABLE, profile="smoke", run_id=run_id, members={},
                                 results_path=store, git_sha="abc")
    status = main(["stability", "--from-store", "--profile", "smoke", "--results", str(store),
                   "--reports", str(reports), "--note", "not run: out of time"])
    assert status == 0, capsys.readouterr().err
    md = (reports / "table-stability.md").read_text()
    others = [m for m in METHODS.names() if m != "vertex"]
    assert all(f"- {m}: **not measured** (no stored row)" in md for m in [*others, "sh-core"])
    assert "- vertex: ok in 1 cases" in md and "- not run: out of time" in md
    assert "- vertex: " in md.split("## Not measured")[1]  # its other cases are listed
