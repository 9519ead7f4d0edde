"""`prtbench verdict`: the best of each family within equal budgets, PRT against the engine
baselines, with paired intervals; measuring what the store lacks."""

from __future__ import annotations

import csv
import math
import re
from types import SimpleNamespace

import pytest

from prtbench.bench.intervals import t95
from prtbench.cli import main
from prtbench.store.results import ResultsStore
from prtbench.tradeoff.dominance import better_beyond, paired_difference
from prtbench.tradeoff.verdict import (
    auto_texture_resolutions,
    family_of,
    verdict,
    verdict_spec,
)
from tests.prtbench.tradeoff.test_budget import MiB, _noisy


def _point(values, half):
    per_view = {v: (x, x - half, x + half) for v, x in enumerate(values)}
    mean = sum(values) / len(values)
    return SimpleNamespace(per_view=per_view, error=mean, error_lo=mean - half,
                           error_hi=mean + half)


def test_paired_difference_is_the_mean_gain_with_t_spread_and_noise():
    # a gains exactly 1 dB on each of four views: no spread, the half-width is the noise of
    # both (0.2 + 0.3 dB). With the gain alternating 0 / 2 dB the spread adds t(3)·sd/√4.
    a, b = _point([21, 22, 23, 24], 0.2), _point([20, 21, 22, 23], 0.3)
    mean, half = paired_difference(a, b, higher_is_better=True)
    assert mean == pytest.approx(1.0) and half == pytest.approx(0.5)
    assert better_beyond(a, b, higher_is_better=True)
    assert paired_difference(b, a, higher_is_better=True)[0] == pytest.approx(-1.0)
    c = _point([20, 23, 22, 25], 0.2)
    mean, half = paired_difference(c, b, higher_is_better=True)
    sd = math.sqrt(4 / 3)  # gains 0, 2, 0, 2
    assert mean == pytest.approx(1.0) and half == pytest.approx(t95(3) * sd / 2 + 0.5)
    assert not better_beyond(c, b, higher_is_better=True)
    # Lower is better (FLIP): a lower a is a positive gain.
    f, g = _point([0.1, 0.1], 0.01), _point([0.2, 0.2], 0.01)
    assert paired_difference(f, g, higher_is_better=False)[0] == pytest.approx(0.1)


def test_auto_texture_resolutions_follow_the_triangle_count():
    assert auto_texture_resolutions(16890) == [256]          # plants packs at 256² (quick)
    assert auto_texture_resolutions(20070, count=2) == [512, 1024]
    assert auto_texture_resolutions(168728) == [1024]        # four-animals
    assert auto_texture_resolutions(10) == [256]


def test_every_family_of_the_grid_and_the_engine_baselines():
    spec = verdict_spec(scene="plants", light="sky", triangles=16890, profile="quick")
    names = [t["name"] for t in spec["method"]]
    assert {family_of(n)[0] for n in names} >= {"SH PRT", "wavelet PRT", "probe volume",
                                                "AO + bent normal", "lightmap"}
    assert {n for n in names if family_of(n)[1]} == {"irradiance-volume", "probe-volume",
                                                     "ao-bent-normal", "ao-bent-normal-texture",
                                                     "lightmap"}
    tpfl = next(t for t in spec["method"] if t["name"] == "texture-tpfl")
    assert tpfl["grid"]["texture_resolution"] == [256, 512]
    lightmap = next(t for t in spec["method"] if t["name"] == "lightmap")
    assert lightmap["grid"]["bake_light"] == ["sky"]  # baked, as engines ship it
    assert spec["reference_bounces"] == 1  # one reference: one panel


def _store(tmp_path):
    store = ResultsStore(tmp_path / "store.sqlite")
    rows = (_noisy("vertex", {"sh_bands": 3}, 24.0, memory=int(0.5 * MiB))
            + _noisy("texture-tpfl", {"texture_resolution": 256}, 30.0, memory=6 * MiB)
            + _noisy("probe-volume", {"light_mode": "relight"}, 26.0, memory=int(0.3 * MiB))
            + _noisy("lightmap", {"texture_resolution": 256}, 33.0, memory=4 * MiB)
            + _noisy("wavelet-vertex", {"light_terms": 64}, 31.0, memory=40 * MiB))
    for r in rows:
        r.light_class = {"lightmap": "fixed"}.get(r.method, "relight")
        r.split = "held-out"
    store.append(rows)
    return store


def test_verdict_reads_the_store_per_budget_and_concludes(tmp_path, capsys):
    store = _store(tmp_path)
    reports = tmp_path / "reports"
    result = verdict(scenes=["plants"], light="sky", results_path=store.path,
                     reports_dir=reports, measure=False)
    pv, = result.panels
    memory = {b.budget.text: {f.family: f for f in b.rows} for b in pv.blocks[:3]}
    # 1 MiB: SH PRT by vertex (0.5 MiB) and the probe volume fit; 26 dB beats 24 beyond ±0.3.
    one = memory["1 MiB"]
    assert one["SH PRT"].point.method == "vertex" and one["probe volume"].row.mark == "best"
    assert one["lightmap"].point is None and one["lightmap"].row.cheapest.cost == 4 * MiB
    # 8 MiB: texture-tpfl is SH PRT's best; the baked lightmap (fixed) leads overall.
    eight = memory["8 MiB"]
    assert eight["SH PRT"].point.method == "texture-tpfl"
    assert eight["lightmap"].row.mark == "best" and eight["wavelet PRT"].point is None
    assert memory["64 MiB"]["wavelet PRT"].point.error == pytest.approx(31.015)
    # The conclusion at 8 MiB: texture-tpfl is beaten by the lightmap by 3 dB; relightable
    # only, it beats the probe volume by 4 dB, each with its paired interval.
    assert re.search(r"at 8 MiB, texture-tpfl \(SH PRT, relight\) is beaten by the engine "
                     r"baseline lightmap \(lightmap, fixed\), by 3\.00 ± 0\.\d+ dB", pv.conclusion)
    assert re.search(r"texture-tpfl \(SH PRT, relight\) beats every relightable engine "
                     r"baseline; the closest, probe-volume \(probe volume, relight\), by "
                     r"4\.00 ± 0\.\d+ dB", pv.relight_conclusion)
    md = (reports / "verdict-plants-sky.md").read_text()
    assert "## Conclusions" in md and pv.conclusion in md
    with open(reports / "verdict-plants-sky.csv") as fh:
        table = list(csv.DictReader(fh))
    lightmap = next(r for r in table if r["budget_as_written"] == "8 MiB"
                    and r["family"] == "lightmap")
    assert float(lightmap["psnr_masked"]) == pytest.approx(33.015)  # the stored rows' mean
    assert lightmap["engine_baseline"] == "1" and lightmap["light_class"] == "fixed"


@pytest.mark.parametrize("args, message", [
    (["--scene", "nowhere"], r"unknown scene 'nowhere'"),
    (["--scene", "plants", "--name", "../up"], r"--name '\.\./up': accepted:"),
    (["--scene", "plants", "--profile", "huge"], r"unknown profile 'huge'"),
])
def test_verdict_bad_input_is_one_line_and_writes_nothing(tmp_path, capsys, args, message):
    missing = tmp_path / "none.sqlite"
    assert main(["verdict", *args, "--results", str(missing), "--reports",
                 str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and re.search(message, err), err
    assert not missing.exists() and not (tmp_path / "r").exists()


def ball_on_ground_glb(path):
    """A glTF file scene: a 320-triangle ball on a thin ground box (written by trimesh)."""
    import trimesh

    scene = trimesh.Scene()
    scene.add_geometry(trimesh.creation.icosphere(subdivisions=2, radius=0.5)
                       .apply_translation([0, 0.5, 0]), node_name="ball")
    scene.add_geometry(trimesh.creation.box(extents=[4, 0.02, 4])
                       .apply_translation([0, -0.01, 0]), node_name="ground")
    scene.export(str(path))
    return path


def test_verdict_on_a_file_scene_measures_what_the_store_lacks_then_only_reads(
        tmp_path, capsys, monkeypatch):
    # A glTF file at smoke, serially, two families: every cell measured once (a second verdict
    # stores nothing new and prints the same), each family with a row within 64 MiB.
    monkeypatch.setenv("PRTBENCH_CACHE", str(tmp_path / "cache"))
    glb = ball_on_ground_glb(tmp_path / "ball.glb")
    results, reports = tmp_path / "store.sqlite", tmp_path / "reports"
    args = ["verdict", "--scene", str(glb), "--profile", "smoke", "--workers", "0",
            "--method", "vertex", "--method", "ao-bent-normal", "--results", str(results),
            "--reports", str(reports), "--quiet"]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert re.search(r"^3 measured, 0 already stored, 0 failed$", out, re.M), out
    rows = len(ResultsStore(results, readonly=True).query())
    assert main(args) == 0
    again = capsys.readouterr().out
    assert re.search(r"^0 measured, 3 already stored, 0 failed$", again, re.M)
    assert again.splitlines()[1:] == out.splitlines()[1:]
    assert len(ResultsStore(results, readonly=True).query()) == rows
    md = (reports / "verdict-ball-default.md").read_text()
    assert "--scene ball.glb" in md and str(tmp_path) not in md  # no machine path
    with open(reports / "verdict-ball-default.csv") as fh:
        table = [r for r in csv.DictReader(fh) if r["budget_as_written"] == "64 MiB"]
    assert {r["family"] for r in table if r["psnr_masked"]} == {"SH PRT", "AO + bent normal"}
    assert re.search(r"at 8 MiB, vertex \(SH PRT, relight\) (beats every engine baseline; the "
                     r"closest,|ties with the engine baseline|is beaten by the engine baseline) "
                     r"ao-bent-normal", md)


def test_under_a_changing_sky_a_family_stands_by_its_relightable_configuration(tmp_path):
    # The probe volume's best at 8 MiB is baked (fixed, 28 dB); relit it reaches 25.5 dB, which
    # the changing-sky conclusion must weigh against texture-tpfl (24 dB), not drop the family.
    store = ResultsStore(tmp_path / "store.sqlite")
    rows = (_noisy("texture-tpfl", {"texture_resolution": 256}, 24.0, memory=6 * MiB)
            + _noisy("probe-volume", {"light_mode": "fixed"}, 28.0, memory=int(0.4 * MiB))
            + _noisy("probe-volume", {"light_mode": "relight"}, 25.5, memory=int(0.3 * MiB)))
    for r in rows:
        r.light_class = "fixed" if r.config.get("light_mode") == "fixed" else "relight"
        r.split = "held-out"
    store.append(rows)
    pv, = verdict(scenes=["plants"], light="sky", results_path=store.path,
                  reports_dir=tmp_path / "r", measure=False).panels
    assert "is beaten by the engine baseline probe-volume (probe volume, fixed), by 4.00" in (
        pv.conclusion)
    assert ("is beaten by the relightable engine baseline probe-volume (probe volume, relight), "
            "by 1.50") in pv.relight_conclusion
