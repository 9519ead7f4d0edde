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
"""

from __future__ import annotations

import pytest

from prtbench.api.method import METHODS
from prtbench.stability.matrix import CORE, load_rows, run_matrix
from prtbench.stability.report import write_reports

TRAINED = ("learnt", "learnt-sdf", "neural-wavelet")
SMOKE_CASES = ("sh_bands=1", "storage=float16", "precision=float16", "ridge=0", "light=black",
               "light=huge-constant", "scale=1e+04", "scale=1e-04", "shininess=1e+04",
               "light_terms=1", "compress=cpca clusters=signals", "compress=cpca pca_vectors=0",
               "geometry=solid-block")


def _same_picture(row) -> bool:
    """The case's image is the moderate one: a masked PSNR against it above 30 dB, or identical
    pixels (PSNR inf, which the store's strict JSON keeps as null, and FLIP 0)."""
    psnr = row["psnr_vs_moderate"]
    return psnr > 30.0 if psnr is not None else row["flip_vs_moderate"] == 0.0


@pytest.fixture(scope="module")
def smoke_rows(tmp_path_factory):
    folder = tmp_path_factory.mktemp("stability")
    methods = [m for m in METHODS.names() if m not in TRAINED] + [CORE]
    results = folder / "results.sqlite"
    run_id = run_matrix(methods, profile="smoke", results_path=results, cases=SMOKE_CASES,
                        echo=False)
    return load_rows(run_id, results_path=results), folder


def test_no_smoke_case_fails(smoke_rows):
    rows, _ = smoke_rows
    failed = [f"{r['method']} {r['case']}: {r['reason']}" for r in rows if r["outcome"] == "failed"]
    assert not failed, "\n".join(failed)


def test_every_method_was_measured_and_its_moderate_case_is_ok(smoke_rows):
    rows, _ = smoke_rows
    for method in (m for m in METHODS.names() if m not in TRAINED):
        mine = {r["case"]: r for r in rows if r["method"] == method}
        assert mine["moderate"]["outcome"] == "ok", mine["moderate"]["reason"]
        # Finite, measured and stored: a real PSNR, the artifact inspected.
        assert 10.0 < mine["moderate"]["psnr_masked"] < 60.0
        assert mine["moderate"]["artifact_values"] > 0 and mine["moderate"]["precompute_s"] >= 0
        assert {"light=black", "scale=1e+04", "scale=1e-04"} <= set(mine)
        assert mine["light=black"]["outcome"] == "ok"  # black in, black out
        # Scale invariance (the canonical frame): both scenes render the moderate picture.
        for scaled in ("scale=1e+04", "scale=1e-04"):
            assert mine[scaled]["outcome"] == "ok", (method, scaled, mine[scaled]["reason"])
            assert _same_picture(mine[scaled]), (method, scaled)
    core = [r for r in rows if r["method"] == CORE]
    assert any(r["outcome"] == "refused" for r in core)  # s = 1e5 past the lobe's range
    assert all(r["outcome"] != "failed" for r in core)


def test_report_is_written_from_the_stored_rows(smoke_rows):
    rows, folder = smoke_rows
    md, csv_path = write_reports(rows, folder / "reports")
    text = md.read_text()
    for method in (m for m in METHODS.names() if m not in TRAINED):
        assert f"\n- {method}: ok in " in text
    assert len(csv_path.read_text().splitlines()) == len(rows) + 1
