"""Thesis tables 4.2 and 4.3 (learnt transfer on SDFs): sweeps, formatting, paper columns."""

from __future__ import annotations

import csv
import math

import numpy as np
import pandas as pd
import pytest

from prtbench.bench.job import Job
from prtbench.bench.reproduction import run_table
from reproductions import table_4_2, table_4_3


@pytest.fixture(scope="module", autouse=True)
def _one_torch_thread():
    # The 2 cores are shared: one torch thread trains the smoke network ~4x faster than two.
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


def _frame(rows):
    """A results frame as run_table hands it to ``format`` (label_* columns added)."""
    return pd.DataFrame.from_records(rows)


def test_sweeps_cover_the_thesis_grids():
    cells = table_4_2.TABLE.cells("quick")
    assert len(cells) == 4 * 2 * 2
    assert {(c.scene, c.overrides["hidden"], c.variant) for c in cells} == set(table_4_2.PAPER_FPS)
    assert all(c.method == "learnt-sdf" and c.overrides["layers"] == 4
               and c.overrides["renderer"] == "glsl" and c.reference == "path" for c in cells)
    cells = table_4_3.TABLE.cells("paper")
    assert {(c.scene_params["size"], c.overrides["hidden"], c.variant) for c in cells} == \
        set(table_4_3.PAPER_FPS)
    assert all(c.scene == "sdf-bunny-neural" and c.views is None for c in cells)
    # Spot checks of the numbers copied from the thesis text.
    assert table_4_2.PAPER_FPS[("sdf-car", 64, "diffuse")] == 254.96
    assert table_4_2.PAPER_FPS[("sdf-monster", 128, "glossy")] == 24.2
    assert table_4_3.PAPER_FPS[("large", 128, "glossy")] == 15.2


def test_table_4_2_format_puts_ours_and_the_paper_in_separate_columns():
    frame = _frame([
        {"label_scene": "sdf-fish", "label_variant": "glossy", "label_k": 64, "frame_ms": ms,
         "metric_psnr_masked": psnr} for ms, psnr in ((20.0, 30.0), (30.0, 32.0), (25.0, 31.0))
    ] + [{"label_scene": "sdf-fish", "label_variant": "glossy", "label_k": 128, "frame_ms": 100.0,
          "metric_psnr_masked": 33.0}])
    header, rows = table_4_2.TABLE.format(frame, profile="quick")
    assert len(rows) == 8
    row = dict(zip(header, next(r for r in rows if r[1] == "sdf-fish" and r[2] == "glossy")))
    assert row["scene (thesis)"] == "FISH"
    assert row["FPS k=64"] == pytest.approx(1000 / 25.0)  # median frame time
    assert row["FPS k=128"] == pytest.approx(10.0)
    assert row["FPS ratio k=128/k=64"] == pytest.approx(0.25)
    assert row["PSNR masked k=64 (dB)"] == pytest.approx(31.0)
    assert row["paper FPS k=64"] == 231.6 and row["paper FPS k=128"] == 50.1
    assert row["paper FPS ratio k=128/k=64"] == pytest.approx(50.1 / 231.6)
    assert row["views"] == 3
    # Paper numbers appear only in columns headed "paper"; unmeasured cells are NaN, not paper.
    paper_values = set(table_4_2.PAPER_FPS.values())
    for r in rows:
        for name, value in zip(header, r):
            if isinstance(value, float) and value in paper_values:
                assert name.startswith("paper"), (name, value)
    car = dict(zip(header, rows[0]))
    assert math.isnan(car["FPS k=64"]) and math.isnan(car["PSNR masked k=128 (dB)"])


def test_table_4_3_format_grid_and_size_ratio():
    frame = _frame([
        {"label_size": size, "label_variant": "diffuse", "label_k": k, "frame_ms": ms,
         "metric_psnr_masked": 30.0}
        for size, k, ms in (("small", 64, 10.0), ("small", 128, 40.0), ("large", 64, 50.0),
                            ("large", 128, 80.0))])
    header, rows = table_4_3.TABLE.format(frame, profile="quick")
    assert len(rows) == 4
    by = {(r[0], r[1]): dict(zip(header, r)) for r in rows}
    small = by[("neural SDF k=32, l=2", "diffuse")]
    large = by[("neural SDF k=64, l=2", "diffuse")]
    assert small["FPS k=64"] == pytest.approx(100.0) and small["FPS k=128"] == pytest.approx(25.0)
    assert large["neural SDF ratio large/small k=64"] == pytest.approx(0.2)
    assert math.isnan(small["neural SDF ratio large/small k=64"])
    assert large["paper FPS k=64"] == 50.0 and small["paper FPS k=128"] == 77.0
    assert large["paper neural SDF ratio large/small k=64"] == pytest.approx(50.0 / 320.0)
    assert math.isnan(by[("neural SDF k=32, l=2", "glossy")]["FPS k=64"])


def test_table_4_2_end_to_end_on_a_tiny_sweep(monkeypatch, tmp_path):
    # One smoke-sized cell through the real runner and results store; the rest stay empty.
    import methods.learnt.sdf  # noqa: F401 - registers "learnt-sdf"

    cell = Job(method="learnt-sdf", scene="sdf-rabbit", variant="glossy", views=1,
                scene_params={"mc_resolution": 96},
                label={"scene": "sdf-rabbit", "variant": "glossy", "k": 64})
    monkeypatch.setattr(table_4_2.TABLE, "cells", lambda profile: [cell])
    paths = run_table(table_4_2.TABLE, profile="smoke", results_path=tmp_path / "results.sqlite",
                      reports_dir=tmp_path, progress=False)
    md, csv_path = paths
    assert md.name == "table-4.2.md" and csv_path.name == "table-4.2.csv"
    text = md.read_text()
    assert "paper FPS k=64" in text and "Scene substitutions" in text and "llvmpipe" in text
    with open(csv_path) as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 8
    rabbit = next(r for r in rows if r["ours"] == "sdf-rabbit" and r["material"] == "glossy")
    assert np.isfinite(float(rabbit["FPS k=64"])) and float(rabbit["FPS k=64"]) > 0
    assert float(rabbit["PSNR masked k=64 (dB)"]) > 10
    assert rabbit["FPS k=128"] == "nan" and float(rabbit["paper FPS k=128"]) == 37.9
    assert rabbit["views"] == "1"
