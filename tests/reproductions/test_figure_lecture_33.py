"""Lecture slides 32-33: the lighting-only error curve and the SH/wavelet panels (smoke)."""

from __future__ import annotations

import numpy as np
import pytest

from prtbench.io import imageio


def test_wavelets_approximate_a_sun_far_better_than_sh_at_equal_terms():
    """Slide 32's point, measured: for a small bright source, k wavelet terms leave much less
    lighting error than k SH terms, and both errors fall as terms are added."""
    from prtbench.transport.lights import get_light
    from reproductions.figure_lecture_33 import lighting_errors

    rows = lighting_errors(get_light("sun"), 16, max_bands=10, terms=(4, 25, 100, 400, 1536))
    by = {(r["basis"], r["terms"]): r["rel_l2"] for r in rows}
    sh = [by[("sh", b * b)] for b in range(1, 11)]
    area = [by[("wavelet-area", k)] for k in (4, 25, 100, 400, 1536)]
    assert all(a >= b - 1e-12 for a, b in zip(sh, sh[1:]))  # orthonormal truncation
    assert all(a > b for a, b in zip(area, area[1:]))
    assert area[-1] < 1e-6  # all 6·16² terms: the cubemap itself
    assert by[("wavelet-area", 100)] < 0.5 * by[("sh", 100)], by
    assert 0.0 < by[("sh", 1)] <= 1.0 + 1e-9  # the constant term alone is no worse than none


@pytest.mark.slow
@pytest.mark.assets  # the city and sunset HDRIs
def test_figure_writes_panels_curve_and_tables_from_the_store(tmp_path):
    from reproductions.figure_lecture_33 import FIGURE, SETTINGS

    results = tmp_path / "results.sqlite"
    paths = FIGURE.make(profile="smoke", reports_dir=tmp_path, results_path=results,
                        progress=False)
    names = {p.name for p in paths}
    assert {"figure-lecture-33.png", "figure-lecture-33-lighting.png", "figure-lecture-33.csv",
            "figure-lecture-33.md"} == names
    assert imageio.read_png(tmp_path / "figure-lecture-33.png").ndim == 3
    text = (tmp_path / "figure-lecture-33.md").read_text()
    assert "St Peter's Basilica" in text and "64 bands" in text and "Measured with profile" in text
    table = _stored_panels(results)
    wav = table[table["basis"] == "wavelet"].sort_values("terms")
    assert list(wav["terms"]) == list(SETTINGS["smoke"]["terms"])
    psnr = wav["psnr_masked_db"].to_numpy()
    assert np.all(np.isfinite(psnr)) and psnr[-1] > psnr[0] and psnr[-1] > 20.0
    # Re-plotting from the store measures nothing and writes the same numbers.
    before = (tmp_path / "figure-lecture-33.csv").read_text()
    FIGURE.make(profile="smoke", reports_dir=tmp_path, results_path=results, from_store=True)
    assert (tmp_path / "figure-lecture-33.csv").read_text() == before


def _stored_panels(results):
    from prtbench.store import measurements
    from reproductions.figure_lecture_33 import TABLE

    return measurements.load(TABLE, results_path=results)

