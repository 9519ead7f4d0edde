"""The stability smoke subset (issue #15): runs in ``make test`` and fails on any ``failed``.

Every registered method except the two that train a network (``learnt``, ``learnt-sdf``: a
minute of training per case here; they run in ``make table-stability``) is measured in the
smoke profile on the cheap extremes its knobs have (SH bands at 1, half-float storage, a ridge
of 0), an all-black and a 10⁶ constant light, the scene scaled by 10⁴ and by 10⁻⁴ (both rendered in
the canonical frame: the moderate picture) and a Phong exponent of 10⁴, the method edges that are cheap here (one
wavelet lighting term, CPCA with one cluster per vertex and with no PCA vectors, probes inside
a solid block), plus the SH core's rows. Every case must be
``ok``, ``degraded`` or ``refused``; the moderate cases ``ok``; and the report must be written
from the stored rows.

``make test`` runs the cases every method must survive whatever its knobs (black and 10⁶
lights, the scene at 10⁻⁴) on both cores, one method per test; the scene at 10⁴ and the knob
and method edges (``SMOKE_EDGE_CASES``, about five minutes more here) run in ``make test-slow``.
"""

from __future__ import annotations

import pytest

from prtbench.api.method import METHODS
from prtbench.stability.matrix import CORE, load_rows, run_matrix
from prtbench.stability.report import write_reports

TRAINED = ("learnt", "learnt-sdf", "neural-wavelet")
#: What every method must survive whatever its knobs: in ``make test``. (A scaled scene is a
#: new precompute and reference, the dearest case here: the larger scale runs in test-slow.)
SMOKE_CORE_CASES = ("light=black", "light=huge-constant", "scale=1e-04")
#: The knob and method edges that are cheap at smoke: ``make test-slow``.
SMOKE_EDGE_CASES = ("scale=1e+04", "sh_bands=1", "storage=float16", "precision=float16", "ridge=0",
                    "shininess=1e+04", "light_terms=1", "compress=cpca clusters=signals",
                    "compress=cpca pca_vectors=0", "geometry=solid-block")
SMOKE_CASES = SMOKE_CORE_CASES + SMOKE_EDGE_CASES
MEASURED = [m for m in METHODS.names() if m not in TRAINED]


def _same_picture(row) -> bool:
    """The case's image is the moderate one: a masked PSNR against it above 30 dB, or identical
    pixels (PSNR inf, which the store's strict JSON keeps as null, and FLIP 0)."""
    psnr = row["psnr_vs_moderate"]
    return psnr > 30.0 if psnr is not None else row["flip_vs_moderate"] == 0.0


def _matrix(folder, methods, cases):
    results = folder / "results.sqlite"
    run_id = run_matrix(methods, profile="smoke", results_path=results, cases=cases, echo=False)
    return load_rows(run_id, results_path=results)


@pytest.mark.parametrize("method", MEASURED)
def test_no_core_case_fails_and_scaled_scenes_render_the_moderate_picture(method,
                                                                          tmp_path_factory):
    # One method per test, so pytest-xdist spreads the matrix over both cores.
    rows = _matrix(tmp_path_factory.mktemp("stability-" + method), [method], SMOKE_CORE_CASES)
    mine = {r["case"]: r for r in rows}
    failed = [f"{case}: {r['reason']}" for case, r in mine.items() if r["outcome"] == "failed"]
    assert not failed, "\n".join(failed)
    assert mine["moderate"]["outcome"] == "ok", mine["moderate"]["reason"]
    # Finite, measured and stored: a real PSNR, the artifact inspected.
    assert 10.0 < mine["moderate"]["psnr_masked"] < 60.0
    assert mine["moderate"]["artifact_values"] > 0 and mine["moderate"]["precompute_s"] >= 0
    assert mine["light=black"]["outcome"] == "ok"  # black in, black out
    # Scale invariance (the canonical frame): both scenes render the moderate picture.
    assert mine["scale=1e-04"]["outcome"] == "ok", mine["scale=1e-04"]["reason"]
    assert _same_picture(mine["scale=1e-04"])


@pytest.mark.slow
def test_no_smoke_edge_case_fails(tmp_path_factory):
    rows = _matrix(tmp_path_factory.mktemp("stability-edges"), MEASURED + [CORE], SMOKE_CASES)
    failed = [f"{r['method']} {r['case']}: {r['reason']}" for r in rows if r["outcome"] == "failed"]
    assert not failed, "\n".join(failed)
    for r in rows:  # both scales render the moderate picture (the canonical frame)
        if r["case"] in ("scale=1e+04", "scale=1e-04"):
            assert r["outcome"] == "ok" and _same_picture(r), (r["method"], r["case"], r["reason"])
    core = [r for r in rows if r["method"] == CORE]
    assert any(r["outcome"] == "refused" for r in core)  # s = 1e5 past the lobe's range
    assert all(r["outcome"] != "failed" for r in core)


def test_report_is_written_from_the_stored_rows(tmp_path):
    # One method and the SH core's rows are enough for the report's shape.
    rows = _matrix(tmp_path, ["vertex", CORE], SMOKE_CORE_CASES)
    assert all(r["outcome"] != "failed" for r in rows if r["method"] == CORE)
    md, csv_path = write_reports(rows, tmp_path / "reports")
    text = md.read_text()
    assert "\n- vertex: ok in " in text
    assert len(csv_path.read_text().splitlines()) == len(rows) + 1
