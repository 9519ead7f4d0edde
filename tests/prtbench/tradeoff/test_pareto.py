"""prtbench.tradeoff.pareto and .cost: fronts, the noise ceiling, cost kinds, the ops model,
the reports and the `prtbench pareto` command."""

from __future__ import annotations

import csv
import json
import math
import re

import pytest

from prtbench.api import config as config_mod
from prtbench.api.errors import UnknownNameError
from prtbench.api.method import METHODS, Method
from prtbench.cli import main
from prtbench.store.results import ResultRow, ResultsStore
from prtbench.tradeoff import cost
from prtbench.tradeoff.front import collect_points, mark_fronts, noise_ceiling_db, non_dominated
from prtbench.tradeoff.pareto import pareto


def _config(method: str, **knobs) -> dict:
    return config_mod.to_dict(METHODS.get(method).make_config(knobs, profile="quick"))


def _row(method="vertex", knobs=None, *, view=0, psnr=25.0, flip=0.2, frame_ms=2.0,
         workers=1, noise=0.01, **fields) -> ResultRow:
    values = dict(method=method, scene="plants", config=_config(method, **(knobs or {})),
                  scene_variant="diffuse", light="sky", view=view, width=64, height=48,
                  metrics={"psnr_masked": psnr, "flip_masked": flip}, frame_ms=frame_ms,
                  memory_bytes=1000, precompute_s=1.5, renderer="llvmpipe", device="cpu",
                  git_sha="abc", profile="quick", run_id=f"run-{method}-{view}",
                  reference_spp=256, reference_noise=noise, scene_triangles=2000,
                  covered_pixels=1500, scene_vertices=1200, workers=workers)
    values.update(fields)
    return ResultRow(**values)


# -- the front ---------------------------------------------------------------------------------

def test_front_on_hand_made_points():
    # (psnr, cost): c dominates d (better and cheaper); e equals b (tie: both stay); f has a
    # NaN cost and g a NaN error: neither is placed nor dominates anything.
    errors = [20.0, 25.0, 30.0, 24.0, 25.0, 40.0, math.nan]
    costs = [1.0, 2.0, 3.0, 3.5, 2.0, math.nan, 0.1]
    assert non_dominated(errors, costs, higher_is_better=True) == [
        True, True, True, False, True, False, False]


def test_front_equal_cost_keeps_only_the_better_error():
    assert non_dominated([20.0, 22.0], [1.0, 1.0], higher_is_better=True) == [False, True]
    assert non_dominated([20.0, 22.0], [1.0, 1.0], higher_is_better=False) == [True, False]


def test_flip_front_prefers_lower_error():
    # FLIP: lower is better, so the cheap high-FLIP point and the dear low-FLIP point are the
    # front, and the middle one (dearer and worse than the first) is dominated.
    errors, costs = [0.30, 0.35, 0.10], [1.0, 2.0, 5.0]
    assert non_dominated(errors, costs, higher_is_better=False) == [True, False, True]
    # Read as higher-is-better the same numbers give the opposite verdict on the last two.
    assert non_dominated(errors, costs, higher_is_better=True) == [True, True, False]


def test_one_method_only_and_views_averaged():
    rows = [_row(knobs={"sh_bands": n}, view=v, psnr=20.0 + n + v, frame_ms=float(n))
            for n in (2, 3, 4) for v in (0, 1)]
    rows.append(_row(knobs={"sh_bands": 5}, psnr=21.0, frame_ms=9.0))  # dearer and worse
    points = mark_fronts(collect_points(rows, error="psnr_masked", cost="frame_ms")[0],
                         error="psnr_masked")
    by_bands = {p.config["sh_bands"]: p for p in points}
    assert by_bands[3].error == pytest.approx(20.0 + 3 + 0.5) and by_bands[3].views == 2
    assert [by_bands[n].dominated for n in (2, 3, 4, 5)] == [False, False, False, True]


def _noisy(method, knobs, psnr, frame_ms, *, half=0.3):
    """Four views, each with the reference-noise interval psnr ± ``half`` dB."""
    return [_row(method, knobs, view=v, psnr=psnr + 0.01 * v, frame_ms=frame_ms,
                 psnr_masked_lo=psnr + 0.01 * v - half, psnr_masked_hi=psnr + 0.01 * v + half)
            for v in range(4)]


@pytest.mark.parametrize("gap_db, dominated", [(0.05, False), (3.0, True)])
def test_dominance_only_beyond_the_intervals(gap_db, dominated):
    # The dearer irradiance volume is worse than vertex SH by gap_db on every view. Against
    # ±0.3 dB of reference noise a 0.05 dB gap is a tie (it stays, recording whom it ties
    # with); a 3 dB gap is dominance.
    rows = _noisy("vertex", {"sh_bands": 3}, 25.0, 2.0)
    rows += _noisy("irradiance-volume", {"resolution": 8}, 25.0 - gap_db, 4.0)
    points = mark_fronts(collect_points(rows, error="psnr_masked", cost="frame_ms")[0],
                         error="psnr_masked")
    volume = next(p for p in points if p.method == "irradiance-volume")
    assert volume.dominated is dominated
    assert bool(volume.tied_with) is (not dominated)
    assert volume.error_lo < volume.error < volume.error_hi
    assert volume.error - volume.error_lo >= 0.3 - 1e-9  # the reference noise is inside


def test_none_and_nan_errors_are_skipped_and_bad_rows_ignored():
    rows = [_row(view=0, psnr=None), _row(view=1, psnr=30.0),  # the None view does not count
            _row(knobs={"sh_bands": 3}, psnr=None), _row(knobs={"sh_bands": 3}, view=1, psnr=math.nan),
            _row(knobs={"sh_bands": 2}, psnr=99.0, status="degenerate"),
            _row(knobs={"sh_bands": 6}, psnr=99.0, reference_kind="method:texture-tp")]
    points, skipped = collect_points(rows, error="psnr_masked", cost="frame_ms")
    assert len(points) == 1 and points[0].error == pytest.approx(30.0)
    assert len(skipped) == 1 and '"sh_bands": 3' in skipped[0]


def test_noise_ceiling_clips_psnr_and_ties_go_to_the_cheaper():
    assert noise_ceiling_db(0.01) == pytest.approx(40.0)
    assert noise_ceiling_db(0.0) is None and noise_ceiling_db(None) is None
    # Both exceed the 40 dB ceiling: clipped to it, tied on error, so the dearer is dominated.
    rows = [_row(knobs={"sh_bands": 5}, psnr=45.0, frame_ms=1.0),
            _row(knobs={"sh_bands": 6}, psnr=48.0, frame_ms=3.0),
            _row(knobs={"sh_bands": 3}, psnr=35.0, frame_ms=0.5)]
    points = mark_fronts(collect_points(rows, error="psnr_masked", cost="frame_ms")[0],
                         error="psnr_masked")
    by_bands = {p.config["sh_bands"]: p for p in points}
    assert by_bands[6].error == pytest.approx(40.0) and by_bands[6].clipped
    assert by_bands[6].error_unclipped == pytest.approx(48.0)
    assert not by_bands[3].clipped and by_bands[3].error == pytest.approx(35.0)
    assert [by_bands[n].dominated for n in (3, 5, 6)] == [False, False, True]
    # FLIP has no stored ceiling: never clipped.
    flip = collect_points(rows, error="flip_masked", cost="frame_ms")[0]
    assert not any(p.clipped for p in flip) and all(p.ceiling_db is None for p in flip)


def test_frame_ms_prefers_rows_measured_alone():
    rows = [_row(view=0, frame_ms=2.0, workers=1), _row(view=1, frame_ms=9.0, workers=2)]
    point = collect_points(rows, error="psnr_masked", cost="frame_ms")[0][0]
    assert point.cost == pytest.approx(2.0) and point.timing_workers == [1]
    shared = collect_points([_row(frame_ms=9.0, workers=2)], error="psnr_masked", cost="frame_ms")
    assert shared[0][0].cost == pytest.approx(9.0) and "concurrent" in shared[0][0].note
    # Memory is averaged over every row.
    assert collect_points(rows, error="psnr_masked", cost="memory")[0][0].cost == 1000.0


def test_report_prints_the_load_its_frame_times_were_measured_under():
    from prtbench.tradeoff.pareto_report import _load_note

    quiet = [_row(view=0, load_average=1.2, device="AMD EPYC, 2 cores"),
             _row(view=1, load_average=2.4, device="AMD EPYC, 2 cores"),
             _row(view=2, load_average=9.0, device="AMD EPYC, 2 cores", workers=2)]
    points = collect_points(quiet, error="psnr_masked", cost="frame_ms")[0]
    # Only the rows the frame time comes from (measured alone) count.
    assert points[0].loads == [1.2, 2.4]
    note = _load_note(points, "frame_ms")
    assert "1.2 to 2.4" in note and "busy" not in note
    busy = collect_points([_row(load_average=3.5, device="AMD EPYC, 2 cores")],
                          error="psnr_masked", cost="frame_ms")[0]
    assert "busy" in _load_note(busy, "frame_ms")
    assert _load_note(busy, "memory") == ""  # a load says nothing about bytes
    assert _load_note(collect_points([_row()], error="psnr_masked", cost="frame_ms")[0],
                      "frame_ms") == ""  # no stored load: nothing claimed


# -- costs -------------------------------------------------------------------------------------

def test_cost_value_per_kind():
    row = _row(frame_ms=2.5, memory_bytes=4096, precompute_s=7.0)
    assert cost.cost_value(row, "frame_ms") == 2.5
    assert cost.cost_value(row, "memory") == 4096.0
    assert cost.cost_value(row, "precompute") == 7.0
    counts = cost.ops_counts(row)
    expected = counts["madds"] + 4.0 * counts["fetches"] + 0.5 * counts["bytes"]
    assert cost.cost_value(row, "ops") == pytest.approx(expected) and expected > 0
    # A dict from pandas / JSON works the same (config as JSON text).
    as_dict = {**vars(row), "config": '{"sh_bands": 4}'}
    assert cost.cost_value(as_dict, "ops") == pytest.approx(cost.cost_value(
        _row(knobs={"sh_bands": 4}), "ops"))
    assert math.isnan(cost.cost_value(_row(frame_ms=None), "frame_ms"))
    assert math.isnan(cost.cost_value(_row(covered_pixels=None), "ops"))
    assert "covered_pixels" in cost.cost_unavailable_reason(_row(covered_pixels=None), "ops")
    with pytest.raises(UnknownNameError, match="unknown cost 'fps'.*frame_ms, memory, ops, precompute"):
        cost.cost_value(row, "fps")


def test_a_method_without_a_model_is_reported_not_crashing(monkeypatch):
    class NoModel(Method):
        name = "no-model"
        Config = METHODS.get("vertex").Config

        @classmethod
        def precompute(cls, scene, config, *, progress=True):  # pragma: no cover
            raise NotImplementedError

        @classmethod
        def renderer(cls, scene, artifact, config, *, width, height):  # pragma: no cover
            raise NotImplementedError

    monkeypatch.setitem(METHODS._objects, "no-model", NoModel)
    row = _row(method="vertex", config=_config("vertex")).__dict__ | {"method": "no-model"}
    assert math.isnan(cost.cost_value(row, "ops"))
    assert "op_counts" in cost.cost_unavailable_reason(row, "ops")


def test_ops_rank_correlation():
    rows = [_row(knobs={"sh_bands": n}, frame_ms=float(n) ** 2) for n in (2, 3, 4, 5, 6)]
    rho, p, n = cost.ops_rank_correlation(rows)
    assert rho == pytest.approx(1.0) and n == 5
    reversed_rows = [_row(knobs={"sh_bands": n}, frame_ms=10.0 - n) for n in (2, 3, 4, 5, 6)]
    assert cost.ops_rank_correlation(reversed_rows)[0] == pytest.approx(-1.0)
    assert math.isnan(cost.ops_rank_correlation(rows[:2])[0])


#: The main knob of each method and increasing values of it.
MAIN_KNOBS = {
    "vertex": ("sh_bands", [2, 3, 4, 5, 6]),
    "vertex-tp": ("sh_bands", [2, 3, 4, 5, 6]),
    "vertex-tpfl": ("sh_bands", [2, 3, 4, 5, 6]),
    "sloan-matrix": ("sh_bands", [2, 3, 4, 5, 6]),
    "irradiance-volume": ("sh_bands", [2, 3, 4, 5]),
    "texture-tp": ("sh_bands", [2, 3, 4, 5, 6]),
    "texture-tpfl": ("sh_bands", [2, 3, 4, 5, 6]),
    "data-driven": ("basis", [4, 16, 64]),
    "learnt": ("hidden", [16, 32, 64, 128]),
    "learnt-sdf": ("hidden", [16, 32, 64, 128]),
    "wavelet-vertex": ("light_terms", [16, 64, 256, 1024]),
    "wavelet-texture": ("light_terms", [16, 64, 256, 1024]),
    "wavelet-tp": ("light_terms", [16, 64, 256, 1024]),
    "wavelet-image": ("light_terms", [16, 64, 256, 1024]),
}
#: Knobs that change what is resident but not the per-pixel work (ops must not shrink).
RESIDENT_KNOBS = {"irradiance-volume": ("resolution", [4, 8, 16]),
                  "texture-tpfl": ("texture_resolution", [128, 256, 512])}
FACTS = dict(scene_vertices=10_000, scene_triangles=20_000, covered_pixels=40_000, width=320,
             height=240, memory_bytes=1 << 20)


def _ops(method: str, knobs: dict, **facts) -> float:
    cls = METHODS.get(method)
    counts = cls.op_counts(cls.make_config(knobs, profile="quick"), **{**FACTS, **facts})
    if counts is NotImplemented:
        return math.nan
    assert all(counts[k] >= 0 for k in ("madds", "fetches", "bytes"))
    return sum(cost.OPS_WEIGHTS[k] * counts[k] for k in cost.OPS_WEIGHTS)


@pytest.mark.parametrize("method", METHODS.names())
def test_ops_positive_and_increasing_with_main_knob_and_pixels(method):
    if math.isnan(_ops(method, {})):  # no model: reported unavailable (tested above)
        assert method not in MAIN_KNOBS, f"{method} lost its op_counts"
        return
    assert _ops(method, {}) > 0
    pixels = [_ops(method, {}, covered_pixels=c) for c in (1_000, 10_000, 40_000)]
    assert pixels[0] < pixels[1] < pixels[2]
    if method in MAIN_KNOBS:
        knob, values = MAIN_KNOBS[method]
        series = [_ops(method, {knob: v}) for v in values]
        assert all(a < b for a, b in zip(series, series[1:])), (knob, series)
    if method in RESIDENT_KNOBS:
        knob, values = RESIDENT_KNOBS[method]
        series = [_ops(method, {knob: v}) for v in values]
        assert all(a <= b for a, b in zip(series, series[1:])), (knob, series)


def test_triple_product_costs_more_than_fixed_light():
    for n in (3, 5):
        assert _ops("vertex-tp", {"sh_bands": n}) > _ops("vertex-tpfl", {"sh_bands": n})
        assert _ops("texture-tp", {"sh_bands": n}) > _ops("texture-tpfl", {"sh_bands": n})


# -- reports and the command --------------------------------------------------------------------

def _store(tmp_path):
    store = ResultsStore(tmp_path / "store.sqlite")
    # Views differ by 0.02 dB: the 95 % interval over two views (t = 12.7) is ±0.13 dB, well
    # inside the 1 dB steps between configurations, so dominance below is beyond the intervals.
    rows = [_row(knobs={"sh_bands": n}, view=v, psnr=18.0 + n + 0.02 * v, frame_ms=1.0 + n,
                 run_id=f"sweep-{n}") for n in (2, 3, 4, 5) for v in (0, 1)]
    rows += [_row("irradiance-volume", {"resolution": r}, view=v, psnr=19.0 + r / 4,
                  frame_ms=2.0 + r / 2, run_id="iv") for r in (4, 8) for v in (0, 1)]
    rows += [_row("vertex-tpfl", {"sh_bands": 4}, view=0, psnr=24.0, frame_ms=6.0,
                  scene_variant="glossy")]
    rows += [_row(light="studio", psnr=20.0)]
    store.append(rows)
    return store, rows


def test_reports_written_atomically_and_equal_to_the_store(tmp_path):
    store, rows = _store(tmp_path)
    reports = tmp_path / "reports"
    store_files = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    results = pareto(scene="plants", light="sky", cost="frame_ms", results_path=store.path,
                     reports_dir=reports)
    assert [r.light for r in results] == ["sky"]
    names = sorted(p.name for p in reports.iterdir())
    assert names == [f"pareto-plants-sky.{ext}" for ext in ("csv", "md", "png", "svg")]
    with open(reports / "pareto-plants-sky.csv") as fh:
        table = list(csv.DictReader(fh))
    assert len(table) == 4 + 2 + 1  # every configuration, dominated or not
    for line in table:
        mine = [r for r in rows if r.light == "sky" and r.method == line["method"]
                and r.scene_variant == line["variant"]
                and json.dumps(r.config, sort_keys=True) == line["config"]]
        assert float(line["error"]) == pytest.approx(
            sum(r.metrics["psnr_masked"] for r in mine) / len(mine), abs=1e-12)
        assert float(line["cost"]) == pytest.approx(sum(r.frame_ms for r in mine) / len(mine), abs=1e-12)
        assert int(line["views"]) == len(mine)
    front = {(l["method"], l["config"]) for l in table if l["on_front"] == "1"}
    # vertex costs 1+n ms at 20+n dB and irradiance-volume 4 / 6 ms at 20 / 21 dB: every vertex
    # configuration is on the front, both irradiance-volume ones are dominated.
    assert {m for m, _ in front} == {"vertex", "vertex-tpfl"} and len(front) == 5
    md = (reports / "pareto-plants-sky.md").read_text()
    # Five timed configurations per renderer: too few for a rank correlation, said so.
    assert "a rank correlation needs at least 8" in md and "Spearman" not in md
    assert "llvmpipe" in md and "profile" in md.lower()
    # One panel per reference and view set; rows from before the panel column get theirs
    # from scene, variant, light, resolution and reference.
    assert "## plants/diffuse sky 64x48 ref=path/256spp" in md
    assert "## plants/glossy sky 64x48 ref=path/256spp" in md
    assert (reports / "pareto-plants-sky.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # Same store, same files (deterministic plot metadata).
    before = {n: (reports / n).read_bytes() for n in names}
    pareto(scene="plants", light="sky", cost="frame_ms", results_path=store.path, reports_dir=reports)
    assert {n: (reports / n).read_bytes() for n in names} == before
    assert sorted(p.name for p in reports.iterdir()) == names  # no temporary files left
    # Read-only on the store: nothing created or changed beside it.
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()} == store_files


def test_cli_pareto_every_light_and_ops(tmp_path, capsys):
    store, _ = _store(tmp_path)
    assert main(["pareto", "--scene", "plants", "--cost", "ops", "--results", str(store.path),
                 "--reports", str(tmp_path / "r")]) == 0
    out = capsys.readouterr().out
    assert "pareto plants/sky" in out and "pareto plants/studio" in out
    assert "rank correlation needs at least 8" in out
    assert (tmp_path / "r" / "pareto-plants-studio.csv").is_file()


@pytest.mark.parametrize("args, message", [
    (["--error", "psnr"], "unknown error metric 'psnr'.*flip_masked, psnr_masked"),
    (["--cost", "fps"], "unknown cost 'fps'.*frame_ms, memory, ops, precompute"),
    (["--profile", "fast"], "unknown profile 'fast'"),
    (["--light", "forest"], "no ok rows of scene 'plants' under light 'forest'.*stored lights: "
                            "sky, studio.*prtbench sweep"),
])
def test_cli_pareto_bad_input(tmp_path, capsys, args, message):
    store, _ = _store(tmp_path)
    assert main(["pareto", "--scene", "plants", "--results", str(store.path), "--reports",
                 str(tmp_path / "r"), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("prtbench: error: ")
    assert re.search(message, err), err
    assert not (tmp_path / "r").exists()


def test_cli_pareto_empty_selection_names_the_sweep(tmp_path, capsys):
    missing = tmp_path / "none.sqlite"
    assert main(["pareto", "--scene", "plants", "--results", str(missing), "--reports",
                 str(tmp_path / "r")]) == 2
    assert "prtbench sweep" in capsys.readouterr().err and not missing.exists()
    store, _ = _store(tmp_path)
    assert main(["pareto", "--scene", "room", "--results", str(store.path), "--reports",
                 str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert "no ok rows of scene 'room'" in err and "prtbench sweep" in err


def test_ops_correlation_never_mixes_renderers():
    from prtbench.tradeoff.front import ops_correlations

    rows = [_row(knobs={"sh_bands": n}, frame_ms=float(n), renderer="llvmpipe") for n in (2, 3, 4, 5)]
    rows += [_row(knobs={"sh_bands": n}, frame_ms=10.0 - n, renderer="gpu", device="H200")
             for n in (2, 3, 4, 5)]
    by_renderer = ops_correlations(rows)
    assert sorted(by_renderer) == ["gpu", "llvmpipe"]
    assert by_renderer["llvmpipe"]["rows"][0] == pytest.approx(1.0)
    assert by_renderer["gpu"]["configs"][0] == pytest.approx(-1.0)
    assert by_renderer["gpu"]["devices"] == ["H200"] and by_renderer["gpu"]["rows"][2] == 4


def test_csv_carries_the_ops_breakdown(tmp_path):
    store, rows = _store(tmp_path)
    pareto(scene="plants", light="sky", cost="memory", results_path=store.path,
           reports_dir=tmp_path / "r")
    with open(tmp_path / "r" / "pareto-plants-sky.csv") as fh:
        line = next(l for l in csv.DictReader(fh) if l["method"] == "vertex-tpfl")
    counts = cost.ops_counts(next(r for r in rows if r.method == "vertex-tpfl"))
    assert float(line["ops_madds"]) == pytest.approx(counts["madds"])
    assert float(line["ops_fetches"]) == pytest.approx(counts["fetches"])
    assert float(line["ops_bytes"]) == pytest.approx(counts["bytes"])
