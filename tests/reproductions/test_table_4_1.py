"""Thesis table 4.1 reproduction: its sweep, the transcribed paper numbers and the formatter."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from reproductions import table_4_1 as t41


def test_paper_numbers_are_the_thesis_table():
    assert len(t41.PAPER) == 16
    assert t41.PAPER[("diffuse", "teaset", 64)] == (0.00074, 49.227, 0.99708, 350.5)
    assert t41.PAPER[("glossy", "plants", 128)] == (0.00250, 36.614, 0.98661, 12.2)
    assert t41.PAPER[("glossy", "dining-table", 64)] == (0.00411, 32.638, 0.97393, 130.1)
    # The thesis's k = 128 beats k = 64 on PSNR everywhere.
    for (variant, scene, k), values in t41.PAPER.items():
        if k == 64:
            assert t41.PAPER[(variant, scene, 128)][1] > values[1]


def test_sweep_covers_scenes_widths_materials_and_both_references():
    cells = t41.TABLE.cells("quick")
    learnt = [c for c in cells if c.method == "learnt"]
    assert len(learnt) == 2 * 4 * 2 * 2 and len(cells) == len(learnt) + 2 * 4
    assert {c.scene for c in cells} == {"teaset", "plants", "bust", "dining-table"}
    assert {c.reference for c in learnt} == {"method:texture-tp", "path"}
    bands = t41.baseline_bands("quick")
    assert all(c.overrides["sh_bands"] == bands and c.overrides["layers"] == 4 for c in learnt)
    assert {c.overrides["hidden"] for c in learnt} == {64, 128}
    assert all(c.method == "texture-tp" and c.reference == "path"
               for c in cells if c.method != "learnt")


def _row(variant, scene, k, reference, view, **metrics):
    out = {"label_variant": variant, "label_scene": scene, "label_k": k,
           "label_reference": reference, "view": view, "frame_ms": 10.0 * (1 + view),
           "renderer": "test", "git_sha": "x"}
    out.update({f"metric_{name}": value for name, value in metrics.items()})
    return out


def test_format_averages_views_and_keeps_paper_columns_apart():
    rows = []
    for variant in t41.VARIANTS:
        for scene in t41.SCENES:
            for k in (64, 128):
                for view in range(2):
                    rows.append(_row(variant, scene, k, "method:texture-tp", view, mae=0.01 * view,
                                     psnr=30.0 + view + k / 64, ssim=0.9))
                    rows.append(_row(variant, scene, k, "path", view, psnr_masked=20.0 + view,
                                     ssim_masked=0.8))
            rows.append(_row(variant, scene, 0, "path", 0, psnr_masked=25.0, ssim_masked=0.85))
    header, table = t41.TABLE.format(pd.DataFrame(rows), profile="quick")
    assert header[3:6] == ["MAE", "PSNR (dB)", "SSIM"] and header[9].startswith("paper")
    first = table[0]  # diffuse teaset k = 64
    assert first[:3] == ["diffuse", "TEASET", "learnt k=64, l=4"]
    assert first[3] == pytest.approx(0.005) and first[4] == pytest.approx(31.5)
    assert first[6] == pytest.approx(1000 / 15.0)  # FPS from the median frame time
    assert first[7] == pytest.approx(20.5)
    assert tuple(first[9:13]) == t41.PAPER[("diffuse", "teaset", 64)]
    baseline = table[2]
    assert baseline[2] == "texture-tp (baseline)" and baseline[7] == pytest.approx(25.0)
    assert np.isnan(baseline[9])  # no paper numbers for our context rows
