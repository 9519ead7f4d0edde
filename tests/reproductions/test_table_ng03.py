"""table-ng03 (issue #17): wavelet PRT beside SH PRT, smoke profile."""

from __future__ import annotations

import pytest


@pytest.mark.slow
def test_table_ng03_smoke_has_every_configuration_with_bytes(tmp_path):
    from prtbench.bench.reproduction import run_table
    from reproductions.table_ng03 import CONFIGS, TABLE

    md, csv_path = run_table(TABLE, profile="smoke", results_path=tmp_path / "r.sqlite",
                             reports_dir=tmp_path, progress=False)
    lines = csv_path.read_text().splitlines()
    assert len(lines) == 1 + len(CONFIGS)
    rows = {line.split(",")[2]: line.split(",") for line in lines[1:]}
    wavelet, sh = rows["wavelet-vertex k=100"], rows["vertex 8 bands"]
    assert int(wavelet[5]) < int(wavelet[4])  # kept < dense
    assert int(sh[5]) == int(sh[4])
    assert all(10.0 < float(r[8]) < 60.0 for r in rows.values())
