"""A small results store for the site tests: a smoke sweep (three configurations of two
methods on plants) and the smoke tessellation table, measured in the test session's cache."""

from __future__ import annotations

from pathlib import Path

from prtbench.bench.job import Job
from prtbench.bench.reproduction import TABLES, run_table
from prtbench.tradeoff.sweep import run_cells

CELLS = [Job(method="vertex", scene="plants", light="sky", label={"sh_bands": b},
              overrides={"sh_bands": b}) for b in (2, 3)] + \
        [Job(method="irradiance-volume", scene="plants", light="sky", label={})]


def make_store(folder: Path, *, table: bool = True) -> Path:
    """The store at ``folder/store.sqlite`` (sweep cells, then the tessellation table)."""
    path = folder / "store.sqlite"
    outcome = run_cells(CELLS, profile="smoke", results_path=path, workers=0, progress=False)
    assert [c.status for c in outcome.results] == ["done"] * len(CELLS), outcome
    if table:
        run_table(TABLES.get("tessellation"), profile="smoke", results_path=path,
                  reports_dir=folder / "reports", progress=False)
    return path


#: Stored stability rows for the site tests, one per outcome class (and an imported one).
STABILITY_ROWS = [
    {"method": "vertex", "case": "moderate", "group": "moderate", "outcome": "ok",
     "reason": "the moderate setting", "scene": "sphere-over-plane", "psnr_masked": 31.25,
     "flip_masked": 0.0625, "precompute_s": 1.5, "peak_rss_bytes": 3 * 2**20, "load_1m": 0.5},
    {"method": "vertex", "case": "sh_bands=1", "group": "knob", "outcome": "degraded",
     "reason": "masked PSNR 16 dB vs 31 moderate", "advice": "use 3-5 bands",
     "psnr_masked": 16.125, "psnr_vs_moderate": 17.5, "overflow": 0},
    {"method": "vertex", "case": "scale=1e-04", "group": "scene", "outcome": "refused",
     "reason": "scene diagonal 0.000585; accepted: 0.00894..1e+06"},
    {"method": "vertex", "case": "light=black", "group": "light", "outcome": "failed",
     "reason": "NaN in the image", "imported_from": "table-stability.csv sha256:0123456789ab"},
]


def add_stability(path: Path) -> None:
    """Store :data:`STABILITY_ROWS` as one complete smoke stability run in ``path``."""
    from prtbench.stability.matrix import TABLE
    from prtbench.store import measurements

    run_id = measurements.new_run_id()
    measurements.record(TABLE, STABILITY_ROWS, results_path=path, run_id=run_id, profile="smoke",
                        renderer="llvmpipe", device="test machine")
    measurements.complete_report("table", TABLE, profile="smoke", run_id=run_id, members={},
                                 results_path=path)
