"""A small results store for the site tests: a smoke sweep (three configurations of two
methods on plants) and the smoke tessellation table, measured in the test session's cache."""

from __future__ import annotations

from pathlib import Path

from prtbench.reproduction import Cell, TABLES, run_table
from prtbench.tradeoff.sweep import run_cells

CELLS = [Cell(method="vertex", scene="plants", light="sky", label={"sh_bands": b},
              overrides={"sh_bands": b}) for b in (2, 3)] + \
        [Cell(method="irradiance-volume", scene="plants", light="sky", label={})]


def make_store(folder: Path, *, table: bool = True) -> Path:
    """The store at ``folder/store.sqlite`` (sweep cells, then the tessellation table)."""
    path = folder / "store.sqlite"
    outcome = run_cells(CELLS, profile="smoke", results_path=path, workers=0, progress=False)
    assert [c.status for c in outcome.cells] == ["done"] * len(CELLS), outcome
    if table:
        run_table(TABLES.get("tessellation"), profile="smoke", results_path=path,
                  reports_dir=folder / "reports", progress=False)
    return path
