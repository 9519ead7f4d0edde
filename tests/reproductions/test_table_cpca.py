"""``prtbench table cpca``: the grid, the form mapping, the findings, and a small end-to-end run."""

from __future__ import annotations

import csv
import math

import pytest

from reproductions import table_cpca as tc


def test_cells_are_the_issue_grid_plus_the_uncompressed_rows():
    cells = tc.TABLE.cells("quick")
    assert len(cells) == 2 * (1 + 4 * 6)
    glossy = [c for c in cells if c.method == "sloan-matrix"]
    assert {c.scene for c in glossy} == {"bust"} and all(c.overrides["sh_bands"] == 5
                                                         for c in glossy)
    assert {(c.label["K"], c.label["n"]) for c in glossy} == {(0, -1)} | {
        (k, n) for k in (1, 16, 64, 256) for n in (0, 1, 2, 4, 8, 16)}
    smoke = tc.TABLE.cells("smoke")
    assert len(smoke) == 2 * (1 + 3 * 3) and {c.scene for c in smoke} == {"plants"}


@pytest.mark.parametrize("k, n, want", [
    (1, 0, {"compress": "vq", "clusters": 1}), (1, 4, {"compress": "pca", "pca_vectors": 4}),
    (64, 0, {"compress": "vq", "clusters": 64}),
    (16, 2, {"compress": "cpca", "clusters": 16, "pca_vectors": 2})])
def test_grid_points_map_to_compress_knobs(k, n, want):
    assert tc.form_overrides(k, n) == want
    # Every mapping is a valid config of both methods.
    import methods.vertex.glossy  # noqa: F401
    from prtbench.api.method import METHODS

    for method in ("vertex", "sloan-matrix"):
        METHODS.get(method).make_config(want)


def _row(k, n, rmse, psnr, size, ms=1.0, form="cpca"):
    return {"case": "c", "K": k, "n": n, "rmse": rmse, "psnr": psnr, "form_bytes": size,
            "frame_ms": ms, "form": form}


def test_findings_compare_at_equal_cost_bytes_and_error():
    rows = [_row(0, -1, 0.0, 25.0, 1000, form="none"),
            _row(1, 1, 0.2, 20.0, 100, form="pca"), _row(16, 1, 0.1, 22.0, 300),
            _row(16, 0, 0.3, 19.0, 400, form="vq"),
            _row(1, 2, 0.15, 21.0, 150, form="pca"), _row(16, 2, 0.16, 20.5, 500)]
    text = tc.findings(rows)
    assert "lower transfer RMSE than global PCA at 1 of 2 n′ and the higher masked PSNR at 1 (0" \
        in text[0]
    assert "lower transfer RMSE than VQ in 1 of 1 comparisons" in text[1]
    assert "VQ K=16 400 B" in text[1] and "CPCA K=16 n′=1 300 B" in text[1]
    assert "matched by pca K=1 n′=1 (RMSE 0.2, 100 B" in text[2]
    # Near the uncompressed PSNR, a PSNR difference below the resolution is not a ranking.
    saturated = [_row(0, -1, 0.0, 19.3, 1000, form="none"), _row(1, 4, 0.06, 19.26, 100, form="pca"),
                 _row(16, 4, 0.02, 19.22, 300)]
    assert "higher masked PSNR at 0 (1 within 0.25 dB" in tc.findings(saturated)[0]


class _Small(tc.CpcaTable):
    """Diffuse plants only, K ∈ {1, 8} × n′ ∈ {0, 2}: the table's path, but small."""

    def cells(self, profile):
        return [c for c in super().cells(profile) if c.method == "vertex"
                and c.label["K"] in (0, 1, 16) and c.label["n"] in (-1, 0, 4)]


def test_small_table_from_the_results_store(tmp_path):
    from prtbench.bench.reproduction import run_table
    from prtbench.store.results import load

    results = tmp_path / "results.sqlite"
    md, csv_path = run_table(_Small(), profile="smoke", results_path=results,
                             reports_dir=tmp_path, progress=False)
    with open(csv_path) as fh:
        rows = list(csv.DictReader(fh))
    assert [(r["form"], r["K"], r["n′"]) for r in rows] == [
        ("none", "—", "—"), ("vq", "1", "0"), ("pca", "1", "4"), ("vq", "16", "0"),
        ("cpca", "16", "4")]
    by = {(r["K"], r["n′"]): r for r in rows}
    none = by[("—", "—")]
    assert float(none["transfer RMSE"]) == 0.0 and float(none["ratio"]) == 1.0
    # More clusters or vectors: lower transfer error; CPCA lowest, one mean highest.
    rmse = {key: float(r["transfer RMSE"]) for key, r in by.items()}
    assert rmse[("16", "4")] < rmse[("1", "4")] < rmse[("1", "0")]
    assert rmse[("16", "4")] < rmse[("16", "0")] < rmse[("1", "0")]
    # The one-mean VQ image is far worse than the uncompressed one; CPCA within 1 dB of it.
    psnr = {key: float(r["PSNR masked (dB)"]) for key, r in by.items()}
    assert psnr[("1", "0")] < psnr[("—", "—")] - 2.0
    assert psnr[("16", "4")] > psnr[("—", "—")] - 1.0
    stored = load(results)
    # Bytes: resident = the runner's memory_bytes row; ratio from the form's bytes.
    for r in rows:
        assert int(r["resident bytes"]) in set(stored["memory_bytes"].astype(int))
        assert math.isclose(float(r["ratio"]) * int(r["form bytes"]),
                            int(by[("—", "—")]["form bytes"]), rel_tol=1e-9)
    assert "Sloan 2003's finding" in md.read_text() and "than global PCA at" in md.read_text()


def test_the_optional_wavelet_case_is_added_only_when_asked_and_only_at_quick():
    from prtbench.api.errors import UnknownNameError

    assert not any(c.method == "wavelet-vertex" for c in tc.TABLE.cells("quick"))
    table = tc.CpcaTable(optional=("plants wavelet",))
    cells = table.cells("quick")
    assert cells[:len(tc.TABLE.cells("quick"))] == tc.TABLE.cells("quick")  # rows unchanged
    wavelet = [c for c in cells if c.method == "wavelet-vertex"]
    assert [(c.label["K"], c.label["n"]) for c in wavelet] == [(0, -1), *tc.OPTIONAL_FORMS]
    assert "compress" not in wavelet[0].overrides
    assert {c.overrides["compress"] for c in wavelet[1:]} == {"pca", "cpca", "vq"}
    import methods.wavelet.vertex  # noqa: F401
    from prtbench.api.method import METHODS

    for c in wavelet:  # every row is a valid config
        METHODS.get("wavelet-vertex").make_config(dict(c.overrides))
    assert table.cells("smoke") == tc.TABLE.cells("smoke")
    with pytest.raises(UnknownNameError, match="unknown optional table-cpca case 'bust wavelet'"):
        tc.CpcaTable(optional=("bust wavelet",))
