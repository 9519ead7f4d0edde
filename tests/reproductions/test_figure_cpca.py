"""``prtbench figure cpca``: equal-memory forms, and a small end-to-end run from stored rows."""

from __future__ import annotations

import pytest

from prtbench.transport.compress import stored_bytes
from reproductions import figure_cpca as fc


@pytest.mark.parametrize("n_signals, dimension, k, n", [(15_000, 25, 16, 4), (19_000, 625, 16, 4),
                                                        (500, 9, 4, 2)])
def test_forms_store_at_most_the_budget_and_one_more_vector_or_cluster_exceeds_it(
        n_signals, dimension, k, n):
    forms = fc.equal_memory_forms(n_signals=n_signals, dimension=dimension, clusters=k,
                                  pca_vectors=n)

    def size(kk, nn):
        return stored_bytes(n_signals=n_signals, dimension=dimension, clusters=kk,
                            pca_vectors=nn)

    budget = size(k, n)
    assert forms["cpca"] == (k, n)
    (one, pca), (vq, zero) = forms["pca"], forms["vq"]
    assert one == 1 and zero == 0
    assert size(1, pca) <= budget < size(1, pca + 1)
    assert size(vq, 0) <= budget < size(vq + 1, 0)


def test_quick_cells_are_the_table_cases_at_equal_memory():
    import methods.vertex.glossy  # noqa: F401
    from prtbench.io.assets import AssetMissingError

    try:
        cells = fc.FIGURE.cells("quick")
    except AssetMissingError:
        pytest.skip("bust asset not fetched")
    assert [(c.method, c.label["form"]) for c in cells] == [
        (m, f) for m in ("vertex", "sloan-matrix") for f in ("none", "pca", "vq", "cpca")]
    assert {c.light for c in cells} == {"sun"} and all(c.overrides["sh_bands"] == 5 for c in cells)


@pytest.mark.slow  # ~11 s; test_table_cpca keeps the CPCA reproduction path in make test
def test_figure_writes_panels_and_caption_from_stored_rows(tmp_path, monkeypatch):
    from prtbench.io import imageio
    from prtbench.store.results import load

    monkeypatch.setattr(fc, "SMOKE_CASES", fc.SMOKE_CASES[:1])  # plants diffuse vertex only
    results = tmp_path / "results.sqlite"
    png, md = fc.FIGURE.make(profile="smoke", reports_dir=tmp_path, results_path=results,
                             progress=False)
    image = imageio.read_png(png)
    assert image.shape[0] > 2 * 48 and image.shape[1] > 5 * 64  # 2 rows × 5 columns of panels
    from prtbench.bench.reproduction import Stored
    from prtbench.store import measurements

    report = Stored(measurements.require_report("figure", fc.FIGURE.name, profile="smoke",
                                                results_path=results))
    assert len(load(results)) == 4  # one result row per cell (one view each)
    stored = report.frame()
    assert sorted(stored["label_form"]) == ["cpca", "none", "pca", "vq"]
    text = md.read_text()
    for _, row in stored.iterrows():  # caption numbers are the stored ones
        assert row["run_id"] in text and f"{row['metric_psnr_masked']:.4g}" in text
    assert "Measured with profile `smoke`" in text
    # Lossy forms differ from the uncompressed render: the error maps are not blank.
    panels = report.images()
    assert all(panels[f"plants diffuse/{f}/error"].max() > 0 for f in ("pca", "vq", "cpca"))
