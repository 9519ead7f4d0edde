"""``prtbench advise``: expressions, analysis pruning, the adaptive search against exhaustive
search, unreachable targets, and one real, verified run (smoke profile)."""

from __future__ import annotations

import hashlib
import importlib.util
import json
import math
import re
from types import SimpleNamespace

import pytest

from prtbench.api.errors import InvalidInputError, PrtbenchError, UnknownNameError
from prtbench.bench.submit import JobResult
from prtbench.scene.registry import get_scene
from prtbench.tradeoff import advise as advise_mod
from prtbench.tradeoff.advice_text import format_advice
from prtbench.tradeoff.advise import CellResult, advise
from prtbench.tradeoff.expressions import parse_constraints
from prtbench.tradeoff.search_space import build_space

JSON_KEYS = {"method", "config", "metrics", "frame_ms", "memory_bytes", "precompute_s",
             "cost_kind", "evaluated", "grid_size", "runner_up", "pruned", "analysis", "steps",
             "total_s"}


def analysis(**changes):
    base = dict(required_bands=2, needs_glossy=False, glossy_bands=0, needs_shadows=True,
                needs_textures=False, needs_bounces=False, fixed_light_ok=True,
                measurements={"light_energy_bands": [0.9, 0.99]})
    return SimpleNamespace(**{**base, **changes})


# --- expressions ------------------------------------------------------------------------------

def test_expressions_parse_units_into_base_units():
    target = parse_constraints("psnr_masked>=28, flip_masked<0.1,ssim>=0.9,psnr>=30dB")
    assert [(c.name, c.op, c.value) for c in target] == [
        ("psnr_masked", ">=", 28.0), ("flip_masked", "<", 0.1), ("ssim", ">=", 0.9),
        ("psnr", ">=", 30.0)]
    budget = parse_constraints("frame_ms<=33,memory<=256MiB,precompute<2s,frame_ms<0.5s,"
                               "memory<=1.5GiB,precompute<=500ms,ops<=1e9", kinds=("cost",))
    assert [c.value for c in budget] == [33.0, 256 * 2 ** 20, 2.0, 500.0, 1.5 * 2 ** 30, 0.5, 1e9]
    assert all(c.kind == "cost" for c in budget)


def test_constraint_direction_follows_the_metric():
    psnr, flip_up, flip_down, frame = parse_constraints(
        "psnr_masked>=28,flip_masked>=0.1,flip_masked<=0.1,frame_ms<=3")
    assert psnr.grows_with_model is True and flip_down.grows_with_model is True
    assert flip_up.grows_with_model is False  # legal, evaluated as written
    assert frame.grows_with_model is False
    assert psnr.holds(28.0) and not psnr.holds(27.9) and not psnr.holds(float("nan"))
    assert psnr.shortfall(21.0) == pytest.approx(0.25) and psnr.shortfall(None) == math.inf


@pytest.mark.parametrize("text, kinds, fragment", [
    ("psnr_masked=>28", ("metric",), "fragment 'psnr_masked=>28' does not parse"),
    ("psnr_maskd>=28", ("metric",), "unknown name 'psnr_maskd'; did you mean 'psnr_masked'?"),
    ("psnr_masked>=", ("metric",), "does not parse"),
    ("psnr_masked>=28,", ("metric",), "fragment '' does not parse"),
    ("", ("metric",), "is empty"),
    ("frame_ms<=33", ("metric",), "cost not accepted in --target 'frame_ms'"),
    ("psnr>=20", ("cost",), "metric not accepted in --target 'psnr'"),
    ("memory<=256MB", ("cost",), "unit 'MB' for memory; accepted: B, KiB, MiB, GiB"),
    ("frame_ms<=3MiB", ("cost",), "unit 'MiB' for frame_ms; accepted: ms, s"),
    ("ssim>=0.9dB", ("metric",), "takes no unit 'dB'"),
    ("ops<=3k", ("cost",), "unit 'k' for ops"),
    ("memory<=-1", ("cost",), "negative memory"),
])
def test_expression_errors_name_the_fragment_and_what_is_accepted(text, kinds, fragment):
    with pytest.raises(InvalidInputError) as info:
        parse_constraints(text, kinds=kinds)
    message = str(info.value)
    assert fragment in message and "\n" not in message
    assert "operators >=, <=, >, <" in message or "unit" in message or "negative" in message


# --- pruning ----------------------------------------------------------------------------------

def _why(space, method):
    return next(p["why"] for p in space.pruned if p["method"] == method)


def test_a_diffuse_scene_prunes_glossy_only_and_misfit_methods():
    space = build_space(get_scene("plants"), analysis(required_bands=3), profile="quick")
    kept = {m.method: m for m in space.methods}
    for name in ("vertex-tp", "vertex-tpfl", "sloan-matrix"):
        assert "does not need (needs_glossy false)" in _why(space, name)
    assert "needs an SDF scene" in _why(space, "learnt-sdf")  # the method's own validation
    assert "always models interreflection" in _why(space, "data-driven")
    assert {"vertex", "irradiance-volume", "texture-tp", "texture-tpfl"} <= set(kept)
    # Every band from the knob's low up to required + margin; the search starts at required.
    assert kept["vertex"].ladders["sh_bands"] == [1, 2, 3, 4, 5]
    assert kept["vertex"].start.overrides == {"sh_bands": 3, "bounces": 0}
    assert kept["vertex"].fixed == {"bounces": 0}
    # Vertices resolve the shadows: no texture resolution above the profile's (quick: 256).
    assert kept["texture-tp"].ladders["texture_resolution"] == [128, 256]
    assert kept["irradiance-volume"].ladders["resolution"] == [4, 8, 16]  # ×2 around 8
    assert kept["irradiance-volume"].start.overrides == {"resolution": 8, "sh_bands": 3}
    # 55 (bands 1-5: vertex 5, irradiance-volume 15, texture-tp and texture-tpfl 10 each,
    # learnt 15 with hidden 32/64/128), + 9 for wavelet-vertex (generic ladders: light_terms 50/100/200 × cubemap 16/32/64)
    # + 6 for wavelet-texture (light_terms × the analysed texture_resolution, as texture-tp)
    # + 8 for the engine baselines (ao-bent-normal 1, ao-bent-normal-texture and lightmap 2
    # each, probe-volume's resolution 10/19/38).
    assert kept["wavelet-vertex"].ladders == {"light_terms": [50, 100, 200], "cubemap": [16, 32, 64]}
    assert kept["wavelet-texture"].ladders == {"light_terms": [50, 100, 200],
                                               "texture_resolution": [128, 256]}
    assert space.size == sum(len(m.candidates) for m in space.methods) == 78
    # Every registered method is either searched or pruned with its reason.
    from prtbench.api.method import METHODS

    assert sorted([*kept, *(p["method"] for p in space.pruned)]) == METHODS.names()


def test_a_glossy_scene_keeps_glossy_methods_with_the_lobe_bands():
    space = build_space(get_scene("plants", variant="glossy"),
                        analysis(needs_glossy=True, glossy_bands=5, needs_textures=True),
                        profile="quick")
    kept = {m.method: m for m in space.methods}
    assert "diffuse" in _why(space, "vertex") and "diffuse" in _why(space, "irradiance-volume")
    assert kept["vertex-tp"].ladders["sh_bands"] == [1, 2, 3, 4, 5, 6, 7]
    assert kept["vertex-tp"].start.overrides["sh_bands"] == 5  # the lobe's bands
    assert kept["texture-tpfl"].ladders["texture_resolution"] == [128, 256, 512]


def test_changing_lights_and_bounces_prune_what_cannot_follow(monkeypatch):
    from prtbench.api.method import METHODS

    monkeypatch.setattr(METHODS.get("texture-tp"), "light_dependence", "bounce textures",
                        raising=False)
    space = build_space(get_scene("plants"), analysis(fixed_light_ok=False, needs_bounces=True),
                        profile="smoke", methods=["vertex", "irradiance-volume", "texture-tp",
                                                  "data-driven"])
    assert "depends on the light (bounce textures)" in _why(space, "texture-tp")
    # The methods' own declarations (light_dependence): probes light once, data-driven bakes
    # a light family.
    assert "depends on the light (fixed-light)" in _why(space, "irradiance-volume")
    assert "depends on the light (family)" in _why(space, "data-driven")
    kept = {m.method: m for m in space.methods}
    # Interreflection matters, so the search starts at one bounce; none stays a candidate
    # (the 5 % threshold is not the user's target).
    assert kept["vertex"].ladders["bounces"] == [0, 1, 2]
    assert kept["vertex"].start.overrides["bounces"] == 1
    # A method that follows any light but has no bounces knob cannot model interreflection.
    monkeypatch.setattr(METHODS.get("irradiance-volume"), "light_dependence", "none")
    space = build_space(get_scene("plants"), analysis(fixed_light_ok=False, needs_bounces=True),
                        profile="smoke", methods=["vertex", "irradiance-volume"])
    assert "no bounces knob" in _why(space, "irradiance-volume")


def test_bands_beyond_a_methods_range_are_recorded_as_a_shortfall():
    space = build_space(get_scene("sphere-over-plane"), analysis(required_bands=11),
                        profile="smoke", methods=["vertex"])
    vertex = space.methods[0]
    assert vertex.ladders["sh_bands"] == list(range(1, 9)) and len(vertex.candidates) == 8
    assert vertex.start.overrides["sh_bands"] == 8  # the search starts at the top
    assert "asks for 11 bands; vertex stops at 8" in vertex.shortfalls["sh_bands"]


# --- the search against exhaustive search (synthetic measurements) -----------------------------

METHODS3 = ["vertex", "irradiance-volume", "texture-tp"]


def _jitter(method, overrides, profile):
    # ±0.15 dB of deterministic "measurement noise": the search must not need exact monotony.
    digest = hashlib.sha256(repr((method, sorted(overrides.items()), profile)).encode()).digest()
    return (digest[0] / 255 - 0.5) * 0.3


def synthetic_row(method, overrides, profile):
    """A fixed table: accuracy and cost grow with each main knob, at different rates per method."""
    b = overrides["sh_bands"]
    if method == "vertex":
        psnr, ms, mem = 20 + 2.0 * b, 1 + 0.3 * b * b, 1000 * b * b
    elif method == "irradiance-volume":
        r = overrides["resolution"]
        psnr, ms, mem = 18 + 1.5 * b + 2 * math.log2(r), 0.5 + 0.1 * b * b + 0.01 * r, 12 * r ** 3 * b * b
    else:
        t = overrides["texture_resolution"]
        psnr, ms, mem = 21 + 2.2 * b + math.log2(t / 32), 2 + 0.4 * b * b + t / 64, 4 * t * t * b * b
    if profile == "smoke":  # the screening profile: lower and noisier, much cheaper
        psnr, ms = psnr - 1.0, ms / 5
    psnr += _jitter(method, overrides, profile)
    return {"metrics": {"psnr_masked": psnr, "flip_masked": 2.0 / psnr}, "frame_ms": ms,
            "memory_bytes": mem, "precompute_s": 0.1 * b, "status": "ok", "config": dict(overrides)}


class Recorder:
    def __init__(self, fail=()):
        self.calls, self.fail = [], set(fail)

    def __call__(self, cells, *, profile):
        out = []
        for c in cells:
            self.calls.append((profile, c.method, tuple(sorted(c.overrides.items()))))
            if (c.method, c.overrides.get("sh_bands")) in self.fail:
                out.append(CellResult([], "RuntimeError: synthetic failure"))
            else:
                out.append([synthetic_row(c.method, c.overrides, profile)])
        return out


COST_FIELD = {"frame_ms": "frame_ms", "memory": "memory_bytes", "precompute": "precompute_s"}


def exhaustive(space, profile, target, budget, cost):
    constraints = parse_constraints(target) + (parse_constraints(budget, kinds=("cost",))
                                               if budget else [])
    best = math.inf
    for m in space.methods:
        for c in m.candidates:
            row = synthetic_row(c.method, c.overrides, profile)
            values = {**row["metrics"], "frame_ms": row["frame_ms"],
                      "memory": row["memory_bytes"], "precompute": row["precompute_s"]}
            if all(k.holds(values[k.name]) for k in constraints):
                best = min(best, row[COST_FIELD[cost]])
    return best


#: (scene, light, analysed bands, grid size). The first is what the advisor was developed on;
#: the others are scenes and lights it never saw, with an analysis that asks for more bands
#: than the target needs (the held-out case of issue 53: the cheaper bands must still be
#: found) or fewer.
SCENES_LIGHTS = [
    ("sphere-over-plane", None, 2, 6 + 18 + 6 * 2),  # bands 1-6
    pytest.param("dining-table", "purple", 5, 8 + 24 + 8 * 2, id="held-out-dining-table-purple"),
    pytest.param("living-room", "sun", 3, 7 + 21 + 7 * 2, id="held-out-living-room-sun"),
]


@pytest.mark.parametrize("scene, light, bands, size", SCENES_LIGHTS)
@pytest.mark.parametrize("profile", ["smoke", "quick"])
@pytest.mark.parametrize("cost", ["frame_ms", "memory"])
@pytest.mark.parametrize("target, budget", [
    ("psnr_masked>=26", ""), ("psnr_masked>=28", ""), ("psnr_masked>=30", ""),
    ("psnr_masked>=32", ""), ("psnr_masked>=34,flip_masked<=0.06", ""),
    ("psnr_masked>=28", "frame_ms<=4"), ("psnr_masked>=27", "memory<=40KiB"),
])
def test_the_advisor_matches_exhaustive_search_for_fewer_cells(profile, cost, target, budget,
                                                                scene, light, bands, size):
    a = analysis(required_bands=bands)
    space = build_space(get_scene(scene), a, profile=profile, methods=METHODS3, band_margin=4)
    assert space.size == size  # every band from 1: the analysis only says where to start
    evaluate, verify = Recorder(), Recorder()
    advice = advise(scene, light, target=target, budget=budget, cost=cost, profile=profile,
                    analysis=a, evaluate=evaluate, verify=verify, methods=METHODS3, band_margin=4)
    best = exhaustive(space, profile, target, budget, cost)
    assert math.isfinite(best)  # every case here is reachable
    assert advice.met
    chosen = synthetic_row(advice.choice.candidate.method, advice.choice.candidate.overrides, profile)
    assert all(c.holds(advice.choice.values[c.name]) for c in advice.constraints)
    assert chosen[COST_FIELD[cost]] <= 1.25 * best
    # Clearly fewer cells than the grid; one verification run. With screening, at most a third
    # of the grid is run at the requested profile, and the cheap smoke cells come on top.
    assert advice.evaluated == len(evaluate.calls)
    at_profile = sum(1 for p, _, _ in evaluate.calls if p == profile)
    assert at_profile <= (0.5 if profile == "smoke" else 0.35) * advice.grid_size
    assert advice.evaluated <= 0.8 * advice.grid_size
    assert len(verify.calls) == 1 and verify.calls[0][0] == profile
    assert verify.calls[0][1] == advice.choice.candidate.method
    if profile == "quick":  # successive halving: screened at smoke, fewer methods go on
        screened = {m for p, m, _ in evaluate.calls if p == "smoke"}
        final = {m for p, m, _ in evaluate.calls if p == "quick"}
        assert screened == set(METHODS3) and len(final) == 2
        assert any(p["why"].startswith("screened out at the smoke profile") for p in advice.pruned)
    doc = advice.to_json()
    assert set(doc) == JSON_KEYS and doc["grid_size"] == advice.grid_size
    runner_up = doc["runner_up"]
    assert runner_up is not None and (runner_up["method"], runner_up["config"]) != (
        doc["method"], doc["config"])


def test_a_cheap_near_miss_at_screening_is_not_dropped_for_a_dear_hit():
    # At smoke (1 dB below quick here) irradiance-volume resolution=4 sh_bands=6 misses
    # psnr_masked >= 30 by 0.03 dB, while texture-tp meets it at 38x the memory: ranking the
    # screened methods by shortfall kept texture-tp and dropped the cheapest answer.
    evaluate = Recorder()
    advice = advise("sphere-over-plane", target="psnr_masked>=30", cost="memory",
                    profile="quick", analysis=analysis(required_bands=2), evaluate=evaluate,
                    verify=Recorder(), methods=METHODS3, band_margin=4)
    assert (advice.choice.candidate.method, advice.choice.candidate.overrides) == (
        "irradiance-volume", {"resolution": 4, "sh_bands": 6})
    assert {m for p, m, _ in evaluate.calls if p == "quick"} == {"irradiance-volume", "vertex"}
    assert "texture-tp" in {p["method"] for p in advice.pruned}


def test_the_analysis_orders_the_search_but_never_ends_it():
    # The analysis asks for 6 bands; the target needs 3. The search starts at 6 and must come
    # down to 3 by measurement alone (issue 53: 5 bands picked where the default met it).
    evaluate = Recorder()
    advice = advise("sphere-over-plane", target="psnr_masked>=26", cost="memory",
                    profile="smoke", analysis=analysis(required_bands=6), evaluate=evaluate,
                    verify=Recorder(), methods=["vertex"])
    assert evaluate.calls[0] == ("smoke", "vertex", (("bounces", 0), ("sh_bands", 6)))
    assert advice.met and advice.choice.candidate.overrides["sh_bands"] == 4  # 20 + 2b - 1 >= 26
    # Every band left unmeasured is decided by a measurement: 1 and 2 by 3's clear miss,
    # 7 and 8 by 6 meeting the target (more memory for nothing).
    measured = [dict(k)["sh_bands"] for _, _, k in evaluate.calls]
    assert sorted(measured) == [3, 4, 5, 6]


def test_an_unreachable_target_reports_the_closest_and_what_is_needed():
    a = analysis(required_bands=10)
    verify = Recorder()
    advice = advise("sphere-over-plane", target="psnr_masked>=60", cost="frame_ms",
                    profile="smoke", analysis=a, evaluate=Recorder(), verify=verify,
                    methods=["vertex", "irradiance-volume"])
    assert not advice.met and len(verify.calls) == 1  # the closest is still really run
    assert advice.choice.candidate.overrides["sh_bands"] == 8
    assert "needs > 8 bands; use texture methods or wavelets" in advice.hint
    assert "wanted psnr_masked >= 60" in advice.hint
    assert "closest (target not reached)" in format_advice(advice)
    assert set(advice.to_json()) == JSON_KEYS


def test_a_budget_nothing_fits_says_the_target_is_reachable_but_too_expensive():
    advice = advise("sphere-over-plane", target="psnr_masked>=26", budget="frame_ms<=0.1",
                    profile="smoke", analysis=analysis(), evaluate=Recorder(), verify=Recorder(),
                    methods=["vertex", "irradiance-volume"], band_margin=4)
    assert not advice.met
    assert "but it breaks the budget (frame_ms" in advice.hint


def test_failing_cells_do_not_abort_the_search():
    advice = advise("sphere-over-plane", target="psnr_masked>=28", profile="smoke",
                    analysis=analysis(), evaluate=Recorder(fail={("vertex", 4), ("vertex", 5)}),
                    verify=Recorder(), methods=["vertex", "irradiance-volume"], band_margin=4)
    assert advice.met
    failed = [e for e in advice.history if e.error]
    assert failed and all("synthetic failure" in e.error for e in failed)


def test_a_verification_that_misses_falls_back_to_the_runner_up():
    class Worse(Recorder):
        def __call__(self, cells, *, profile):
            rows = super().__call__(cells, profile=profile)
            if len(self.calls) == 1:  # the first pick measures worse when verified
                rows[0][0]["metrics"]["psnr_masked"] -= 10
            return rows

    verify = Worse()
    advice = advise("sphere-over-plane", target="psnr_masked>=28", profile="smoke",
                    analysis=analysis(), evaluate=Recorder(), verify=verify,
                    methods=["vertex", "irradiance-volume"], band_margin=4)
    assert len(verify.calls) == 2 and advice.met
    assert any("trying the runner-up" in n for n in advice.notes)


@pytest.mark.skipif(importlib.util.find_spec("prtbench.tradeoff.cost") is not None,
                    reason="the ops cost model is present")
def test_ops_without_the_cost_model_is_an_error_before_any_work():
    evaluate = Recorder()
    with pytest.raises(InvalidInputError, match="--cost ops needs the operation-count model"):
        advise("sphere-over-plane", target="psnr_masked>=28", cost="ops", profile="smoke",
               analysis=analysis(), evaluate=evaluate, verify=Recorder(), methods=["vertex"])
    assert evaluate.calls == []


@pytest.mark.parametrize("kwargs, error, fragment", [
    ({"cost": "watts"}, UnknownNameError, "unknown cost kind 'watts'"),
    ({"target": "psnr_masked>28dB!"}, InvalidInputError, "does not parse"),
    ({"budget": "psnr>=3"}, InvalidInputError, "metric not accepted in --budget"),
    ({"profile": "fast"}, UnknownNameError, "unknown profile 'fast'"),
    ({"methods": ["vertx"]}, UnknownNameError, "unknown method 'vertx'"),
    ({"variant": "shiny"}, PrtbenchError, "shiny"),
    ({"light": "skyy"}, UnknownNameError, "unknown light 'skyy'"),
])
def test_bad_input_is_rejected_before_any_work(kwargs, error, fragment):
    evaluate = Recorder()
    options = dict(target="psnr_masked>=28", profile="smoke", analysis=analysis(),
                   evaluate=evaluate, verify=Recorder())
    options.update(kwargs)
    light = options.pop("light", None)
    with pytest.raises(error, match=fragment):
        advise("sphere-over-plane", light, **options)
    assert evaluate.calls == []


# --- real runs: the verification path and the CLI ---------------------------------------------

def _strict(text):
    def refuse(token):
        raise ValueError(f"non-strict JSON token {token}")
    return json.loads(text, parse_constant=refuse)


def test_a_real_search_verifies_its_pick_and_stores_its_rows(tmp_path):
    from prtbench.api import strict_json
    from prtbench.store.results import load

    store = tmp_path / "results.sqlite"
    advice = advise("sphere-over-plane", target="psnr_masked>=24", cost="memory", profile="smoke",
                    analysis=analysis(required_bands=2), methods=["vertex", "irradiance-volume"],
                    results_path=store)
    assert advice.met and advice.grid_size == 4 + 12  # bands 1-4
    assert advice.evaluated < advice.grid_size
    doc = _strict(strict_json.dumps(advice.to_json()))
    assert set(doc) == JSON_KEYS and doc["cost_kind"] == "memory"
    assert doc["metrics"]["psnr_masked"] >= 24
    assert isinstance(doc["memory_bytes"], int) and doc["memory_bytes"] > 0
    # Only the verification run is stored: its rows are the answer's numbers.
    frame = load(store)
    assert len(frame) == 1 and set(frame["profile"]) == {"smoke"}
    assert frame["method"].iloc[0] == doc["method"]
    config = frame["config"].iloc[0]
    assert (json.loads(config) if isinstance(config, str) else config) == doc["config"]
    assert frame["metric_psnr_masked"].iloc[0] == pytest.approx(doc["metrics"]["psnr_masked"])
    assert frame["memory_bytes"].iloc[0] == doc["memory_bytes"]


def test_cli_unreachable_target_exits_1_with_the_closest_and_a_hint(tmp_path, monkeypatch, capsys):
    from prtbench.cli import main

    monkeypatch.setattr(advise_mod, "analyze_scene",
                        lambda scene, light, *, light_changes, progress: analysis(required_bands=3))
    out = tmp_path / "advice.json"
    code = main(["advise", "--scene", "sphere-over-plane", "--target", "psnr_masked>=60",
                 "--method", "vertex", "--band-margin", "1", "--profile", "smoke", "--cost",
                 "memory", "--json", str(out), "--results", str(tmp_path / "r.sqlite"), "--quiet"])
    captured = capsys.readouterr()
    assert code == 1
    assert "closest (target not reached)" in captured.out
    assert "prtbench: target not reached" in captured.err and "sh_bands" in captured.err
    assert "[advise]" not in captured.err  # --quiet: no progress
    doc = _strict(out.read_text())
    # Bands 1-4; the analysed 3 and the top 4 miss clearly, so 1 and 2 are implied; the
    # closest of the two measured is the answer.
    assert set(doc) == JSON_KEYS and doc["method"] == "vertex" and doc["config"]["sh_bands"] in (3, 4)
    assert doc["evaluated"] == 2 and doc["grid_size"] == 4
    # The step times are recorded even when quiet (smoke: no screening step).
    assert [s["step"] for s in doc["steps"]] == ["scene", "analysis", "pruning", "search",
                                                 "verification"]
    assert [s["cells"] for s in doc["steps"]] == [0, 0, 0, 2, 1]
    assert sum(s["seconds"] for s in doc["steps"]) <= doc["total_s"]


@pytest.mark.parametrize("extra, fragment", [
    (["--target", "psnr_masked>=2x"], "--target fragment 'psnr_masked>=2x'"),
    (["--target", "psnr_maskd>=28"], "did you mean 'psnr_masked'"),
    (["--target", "psnr_masked>=28", "--budget", "memory<=1TB"], "unit 'TB' for memory"),
    (["--target", "psnr_masked>=28", "--cost", "joules"], "unknown cost kind 'joules'"),
    (["--target", "psnr_masked>=28", "--method", "vertx"], "unknown method 'vertx'"),
    (["--target", "psnr_masked>=28", "--json", "."], "--json '.' is a folder"),
    (["--target", "psnr_masked>=28", "--scene-param", "radius=-1"],
     "scene 'sphere-over-plane' parameter radius='-1'; accepted: finite numbers in (0,"),
])
def test_cli_bad_input_exits_2_and_writes_nothing(tmp_path, monkeypatch, capsys, extra, fragment):
    from prtbench.cli import main

    calls = []
    monkeypatch.setattr(advise_mod, "analyze_scene",
                        lambda *a, **k: calls.append(1) or analysis())
    monkeypatch.chdir(tmp_path)
    code = main(["advise", "--scene", "sphere-over-plane", "--profile", "smoke",
                 "--results", str(tmp_path / "r.sqlite"), *extra])
    err = capsys.readouterr().err
    assert code == 2 and fragment in err and err.startswith("prtbench: error: ")
    assert err.count("\n") == 1 and calls == []
    assert list(tmp_path.iterdir()) == []


def test_cli_scene_params_reach_the_scene_and_every_cell(tmp_path, monkeypatch, capsys):
    from prtbench.cli import main

    scenes = []
    monkeypatch.setattr(advise_mod, "analyze_scene", lambda scene, light, *, light_changes,
                        progress: scenes.append(scene) or analysis(required_bands=2))
    cells = []

    def evaluate(batch, *, profile, **_):  # the verification run
        cells.extend(batch)
        return Recorder()(batch, profile=profile)

    class Pool:  # the search's candidates, as they are submitted
        def __init__(self, executor, **_):
            self.executor, self.queue = executor, []

        def submit(self, job, *, profile, token):
            cells.append(job)
            self.queue.append((token, Recorder()([job], profile=profile)[0]))

        def next_finished(self):
            token, rows = self.queue.pop(0)
            return token, JobResult(None, "", "done", rows=rows)

    monkeypatch.setattr(advise_mod, "evaluate_jobs", evaluate)
    monkeypatch.setattr(advise_mod, "JobPool", Pool)
    code = main(["advise", "--scene", "sphere-over-plane", "--scene-param", "radius=0.3",
                 "--target", "psnr_masked>=24", "--method", "vertex", "--profile", "smoke",
                 "--results", str(tmp_path / "r.sqlite"), "--quiet"])
    assert code == 0, capsys.readouterr().err
    (scene,) = scenes
    assert scene.params["radius"] == pytest.approx(0.3)
    assert scene.content_hash() != get_scene("sphere-over-plane").content_hash()
    # Screening and verification cells carry the parameter to their runs.
    assert len(cells) >= 2 and all(dict(c.scene_params) == {"radius": "0.3"} for c in cells)


def _fake_runs(monkeypatch, cells=None):
    """The CLI's runs replaced by the synthetic table: the verification (``evaluate_jobs``)
    and the search's pool (``JobPool``)."""
    cells = [] if cells is None else cells

    def evaluate(batch, *, profile, **_):
        cells.extend(batch)
        return Recorder()(batch, profile=profile)

    class Pool:
        def __init__(self, executor, **_):
            self.executor, self.queue = executor, []

        def submit(self, job, *, profile, token):
            cells.append(job)
            self.queue.append((token, Recorder()([job], profile=profile)[0]))

        def next_finished(self):
            token, rows = self.queue.pop(0)
            return token, JobResult(None, "", "done", rows=rows)

    monkeypatch.setattr(advise_mod, "evaluate_jobs", evaluate)
    monkeypatch.setattr(advise_mod, "JobPool", Pool)
    return cells


def test_cli_says_each_step_and_its_time_on_stderr(tmp_path, monkeypatch, capsys):
    from prtbench.cli import main

    monkeypatch.setattr(advise_mod, "analyze_scene", lambda scene, light, *, light_changes,
                        progress: analysis(required_bands=2))
    _fake_runs(monkeypatch)
    out = tmp_path / "advice.json"
    code = main(["advise", "--scene", "sphere-over-plane", "--light", "sun", "--target",
                 "psnr_masked>=28", "--method", "vertex", "--method", "irradiance-volume",
                 "--method", "texture-tp", "--profile", "quick", "--cost", "memory",
                 "--band-margin", "4", "--results", str(tmp_path / "r.sqlite"),
                 "--json", str(out)])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    lines = [line for line in captured.err.splitlines() if line.startswith("[advise] ")]
    assert lines == captured.err.splitlines()  # progress only, one prefix
    steps = ["scene", "analysis", "pruning", "screening", "search", "verification"]
    for name in steps:  # each step says how long it took
        assert any(re.match(rf"\[advise\] {name}: \d+\.\d s", line) for line in lines), name
    assert re.search(r"\[advise\] scene: \d+\.\d s; [\d,]+ triangles, light sun", captured.err)
    assert re.search(r"\[advise\] screening: \d+\.\d s, \d+ cells; kept ", captured.err)
    assert re.search(r"\[advise\] total: \d+\.\d s", lines[-1])
    assert "[advise]" not in captured.out
    assert re.search(r"^time: scene \d+\.\d s, analysis .*; total \d+\.\d s$", captured.out,
                     re.MULTILINE)
    doc = _strict(out.read_text())
    assert [s["step"] for s in doc["steps"]] == steps
    assert doc["steps"][3]["profile"] == "smoke" and doc["steps"][4]["profile"] == "quick"
    assert doc["steps"][3]["cells"] + doc["steps"][4]["cells"] == doc["evaluated"]


def test_generic_ladders_and_the_visibility_rule_come_from_the_config_fields():
    from dataclasses import dataclass

    from prtbench.api.config import knob
    from prtbench.api.method import Method
    from prtbench.tradeoff.search_space import method_space

    @dataclass(frozen=True)
    class ProbeConfig:
        sh_bands: int = knob(3, "bands", low=1, high=6)
        probes: int = knob(8, "probes per axis (wide range: x2 steps)", low=2, high=64)
        taps: int = knob(3, "narrow range: +-1 steps", low=1, high=4)
        mode: str = knob("a", "unordered choices", choices=("a", "b"))
        visibility: bool = knob(True, "shadowed transfer")

    class Probe(Method):
        name, Config = "probe", ProbeConfig
        main_knobs = ("probes", "taps", "mode")

        @classmethod
        def precompute(cls, scene, config, *, progress=True):
            raise NotImplementedError

        @classmethod
        def renderer(cls, scene, artifact, config, *, width, height):
            raise NotImplementedError

    scene = get_scene("sphere-over-plane")
    space = method_space(Probe, "probe", scene, analysis(required_bands=5, needs_shadows=False),
                         profile="smoke")
    assert space.ladders == {"probes": [4, 8, 16], "taps": [2, 3, 4], "mode": ["a", "b"],
                             "sh_bands": [1, 2, 3, 4, 5, 6]}
    assert space.fixed == {"visibility": False}  # needs_shadows false: unshadowed only
    assert len(space.candidates) == 3 * 3 * 2 * 6
    # The search starts at the profile's defaults and the analysed bands.
    assert space.start.overrides == {"probes": 8, "taps": 3, "mode": "a", "sh_bands": 5,
                                     "visibility": False}
    low = next(c for c in space.candidates if c.overrides["probes"] == 4
               and c.overrides["taps"] == 2 and c.overrides["sh_bands"] == 5)
    high = next(c for c in space.candidates if c.overrides["probes"] == 16
                and c.overrides["taps"] == 4 and c.overrides["sh_bands"] == 6
                and c.overrides["mode"] == low.overrides["mode"])
    other_mode = next(c for c in space.candidates if c.overrides["mode"] != low.overrides["mode"])
    assert low.below(high) and not high.below(low)
    assert not low.below(other_mode) and not other_mode.below(low)  # choices do not compare
    shadowed = method_space(Probe, "probe", scene, analysis(needs_shadows=True), profile="smoke")
    assert "visibility" not in shadowed.fixed and "visibility" not in shadowed.ladders


@pytest.mark.parametrize("lo, met", [(29.5, False), (30.2, True)])
def test_a_target_is_met_by_the_lower_end_of_the_interval(lo, met):
    # Two views at 30.4 dB mean: the target psnr_masked >= 30 is met only when the interval
    # (the reference's noise and the spread over views) keeps its lower end above 30.
    from prtbench.tradeoff.search import Judge

    judge = Judge(parse_constraints("psnr_masked>=30"), "frame_ms",
                  lambda row, kind: float(row[kind]))
    rows = [{"metrics": {"psnr_masked": 30.4 + d}, "psnr_masked_lo": lo + d,
             "psnr_masked_hi": 31.0 + d, "frame_ms": 2.0, "status": "ok"} for d in (0.0, 0.001)]
    evaluation = judge(None, "smoke", CellResult(rows))
    assert evaluation.values["psnr_masked"] == pytest.approx(30.4005)
    assert evaluation.feasible is met


# --- held-out scenes and lights, real measurements against exhaustive search -------------------

#: Scenes and lights the advisor was not developed on (its tests use sphere-over-plane, the
#: demo plants under sky). dining-table under purple is issue 53's held-out case: the analysis
#: asks for 5 bands where 2 meet the target for a sixth of the memory.
HELD_OUT = [("dining-table", "purple"), ("living-room", "sun")]


@pytest.mark.slow  # the whole grid is measured (2-3 minutes a scene on 2 cores)
@pytest.mark.parametrize("scene, light", HELD_OUT)
def test_held_out_scenes_land_within_1_25x_of_exhaustive_search(scene, light):
    from prtbench.bench.job import Job
    from prtbench.tradeoff.analyze import analyze_scene
    from prtbench.tradeoff.cost import cost_value
    from prtbench.tradeoff.search import Judge
    from prtbench.transport.lights import get_light

    methods = ["vertex", "irradiance-volume"]
    a = analyze_scene(get_scene(scene), get_light(light), fast=True)
    space = build_space(get_scene(scene), a, profile="smoke", methods=methods)
    candidates = [c for m in space.methods for c in m.candidates]
    jobs = [Job(method=c.method, scene=scene, light=light, overrides=c.overrides,
                reference_bounces=1) for c in candidates]
    table = {(c.method, tuple(sorted(c.overrides.items()))): r
             for c, r in zip(candidates, advise_mod.evaluate_jobs(jobs, profile="smoke"))}
    assert all(r.rows for r in table.values()), [r.error for r in table.values() if not r.rows]

    # A target the measured grid reaches: 1 dB below its best pessimistic end.
    best_lo = max(min(float(row["psnr_masked_lo"]) for row in r.rows) for r in table.values())
    target = f"psnr_masked>={math.floor((best_lo - 1.0) * 10) / 10}"
    judge = Judge(parse_constraints(target), "memory", cost_value)
    judged = [judge(c, "smoke", table[(c.method, tuple(sorted(c.overrides.items())))])
              for c in candidates]
    best = min(e.cost for e in judged if e.feasible)

    def replay(cells, *, profile):
        return [table[(c.method, tuple(sorted(c.overrides.items())))] for c in cells]

    advice = advise(scene, light, target=target, cost="memory", profile="smoke", analysis=a,
                    evaluate=replay, verify=replay, methods=methods)
    assert advice.met and advice.choice.cost <= 1.25 * best, (
        target, advice.choice.candidate, advice.choice.cost, best)
    assert advice.evaluated < len(candidates)


def test_advise_on_a_file_scene(tmp_path, capsys, monkeypatch):
    # `advise --scene file.glb` runs like on a built-in scene: the analysis, the screening and
    # the verified answer, all on the imported glTF (real runs at smoke, serially).
    from prtbench.cli import main
    from tests.prtbench.tradeoff.test_verdict import ball_on_ground_glb

    monkeypatch.setenv("PRTBENCH_CACHE", str(tmp_path / "cache"))
    glb = ball_on_ground_glb(tmp_path / "ball.glb")
    out = tmp_path / "advice.json"
    code = main(["advise", "--scene", str(glb), "--target", "psnr_masked>=10", "--method",
                 "vertex", "--band-margin", "0", "--profile", "smoke", "--workers", "0",
                 "--results", str(tmp_path / "r.sqlite"), "--json", str(out), "--quiet"])
    assert code == 0, capsys.readouterr().err
    doc = _strict(out.read_text())
    assert doc["method"] == "vertex" and doc["evaluated"] >= 1
    assert doc["metrics"]["psnr_masked"] >= 10.0  # met (exit status 0), verified by a run
