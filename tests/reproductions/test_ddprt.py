"""The data-driven PRT reproductions (Belcour et al. 2022 Table 1, Figs. 8, 12, 14) in smoke size."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

import methods.data_driven  # noqa: F401 - registers the method


def _csv(path):
    with open(path) as fh:
        return list(csv.DictReader(fh))


def test_figure_14_reports_prediction_and_projection(tmp_path):
    from reproductions.figure_ddprt_14 import FIGURE, SETTINGS

    paths = FIGURE.make(profile="smoke", reports_dir=tmp_path, progress=False)
    assert {p.name for p in paths} == {"figure-ddprt-14.png", "figure-ddprt-14-images.png",
                                       "figure-ddprt-14.csv", "figure-ddprt-14.md"}
    rows = _csv(tmp_path / "figure-ddprt-14.csv")
    lightmap = [r for r in rows if r["space"] == "lightmap"]
    assert len(lightmap) == 2 * 2 * len(SETTINGS["smoke"]["counts"])
    for r in rows:
        ours, proj = float(r["ours_rmse"]), float(r["projection_rmse"])
        assert np.isfinite(ours) and np.isfinite(proj) and proj > 0
    # The projection is the best any coefficients can do in lightmap space, and it can only
    # improve as elements are added (nested bases).
    for family in ("env-rotations", "spot"):
        part = [r for r in lightmap if r["family"] == family and r["ridge"] == "0.01"]
        proj = [float(r["projection_rmse"]) for r in part]
        assert all(b <= a * (1 + 1e-9) for a, b in zip(proj, proj[1:]))
        assert all(float(r["ours_rmse"]) >= float(r["projection_rmse"]) * (1 - 1e-9) for r in part)
    text = (tmp_path / "figure-ddprt-14.md").read_text()
    assert "within 1.5× of the projection" in text and "Reference kind: `path`" in text


def test_figure_8_in_and_out_of_distribution(tmp_path):
    from reproductions.figure_ddprt_8 import FIGURE

    FIGURE.make(profile="smoke", reports_dir=tmp_path, progress=False)
    rows = _csv(tmp_path / "figure-ddprt-8.csv")
    assert [r["case"].split(":")[0] for r in rows] == ["in distribution", "out of distribution"]
    for r in rows:
        assert np.isfinite(float(r["indirect_rmse"])) and float(r["indirect_rmse"]) > 0
    assert (tmp_path / "figure-ddprt-8.png").stat().st_size > 1000


@pytest.mark.assets
def test_figure_12_vertex_prt_leaks_behind_the_lion(tmp_path):
    from reproductions.figure_ddprt_12 import FIGURE

    FIGURE.make(profile="smoke", reports_dir=tmp_path, progress=False)
    rows = {r["image"]: r for r in _csv(tmp_path / "figure-ddprt-12.csv")}
    ours = float(rows["data-driven"]["unlit_vs_reference"])
    vertex = float(next(v for k, v in rows.items() if k.startswith("vertex"))["unlit_vs_reference"])
    # SH band-limiting spreads the sun into the unlit side; shadow maps do not.
    assert vertex > 1.5 and ours < 1.3 and ours < vertex


def test_table_1_from_the_results_store(tmp_path, monkeypatch):
    import reproductions.table_ddprt_1 as table
    from prtbench.bench.reproduction import run_table
    from prtbench.store.results import load

    monkeypatch.setattr(table, "SCENES", table.SCENES[:1])  # cornell only: seconds, not minutes
    reproduction = table.DdprtTable1()
    store = tmp_path / "results.sqlite"
    md, csv_path = run_table(reproduction, profile="smoke", results_path=store,
                             reports_dir=tmp_path, progress=False)
    # The table's own timing rows go to the store it was given (and only there).
    frame = load(store, run_id=reproduction._run_id)
    assert len(frame) == len(table.BASIS_COUNTS)
    for name in ("ms_no_gi", "ms_shading", "ms_gbuffer", "ms_transfer", "ms_frame", "bake_s"):
        assert (frame[f"metric_{name}"] > 0).all(), name
    storage = sorted(frame["metric_bytes_basis"])
    # 4, 16, 64 elements = 1, 4, 16 RGBA32F layers of the lightmap.
    assert storage[1] == 4 * storage[0] and storage[2] == 16 * storage[0]
    rows = list(csv.reader(open(csv_path)))
    no_gi = next(r for r in rows if r[0] == "No GI shader")
    assert float(no_gi[2]) == 1.0 and no_gi[3] == "221"
    assert "wall+finish" in md.read_text() or "timer-query" in md.read_text()
    configs = [json.loads(c)["light_family"] for c in frame["config"]]
    assert set(configs) == {"spot"}


@pytest.mark.slow
@pytest.mark.assets
def test_table_1_smoke_all_scenes(tmp_path):
    import reproductions.table_ddprt_1 as table
    from prtbench.bench.reproduction import run_table

    md, _ = run_table(table.DdprtTable1(), profile="smoke", reports_dir=tmp_path, progress=False)
    text = md.read_text()
    assert "dragon-lo" in text and "room" in text and "asset missing" not in text
