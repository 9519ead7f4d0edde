"""``make paper-fps`` (scripts/paper_fps.py): frame time and resident memory only, stored as
the results store's measurement table ``paper-fps``, on a tiny size here (smoke knobs)."""

from __future__ import annotations

import csv
import importlib.util
from pathlib import Path

import pytest

from prtbench.store import measurements

ROOT = Path(__file__).resolve().parents[1]


def _script():
    spec = importlib.util.spec_from_file_location("paper_fps", ROOT / "scripts" / "paper_fps.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("probe_ms, expected", [(1.0, 30), (250.0, 20), (2000.0, 5),
                                                (float("nan"), 30), (0.0, 30)])
def test_a_slow_frame_gets_fewer_timed_frames_but_never_below_the_floor(probe_ms, expected):
    assert _script().timed_frames(probe_ms, frames=30, cell_seconds=5.0) == expected
    assert _script().timed_frames(2000.0, frames=3, cell_seconds=5.0) == 3  # never more


def test_the_papers_resolutions_are_named():
    script = _script()
    assert script.parse_resolution("1920x1080") == ("PRTT / thesis", 1920, 1080)
    assert script.parse_resolution("800x600") == ("Raghavan 2023", 800, 600)
    assert script.parse_resolution("64x48") == ("--res", 64, 48)


def test_frame_time_and_memory_of_each_method_are_stored_with_no_reference(tmp_path, capsys):
    results, table = tmp_path / "r.sqlite", tmp_path / "fps.csv"
    code = _script().main(["--method", "vertex", "--method", "wavelet-image", "--knobs", "smoke",
                           "--res", "64x48", "--res", "80x60", "--views", "1", "--frames", "2",
                           "--warmup", "1", "--results", str(results), "--csv", str(table)])
    assert code == 0
    report = measurements.latest_report("table", "paper-fps", profile="smoke",
                                        results_path=results)
    rows = measurements.load("paper-fps", run_ids=[report.run_id], results_path=results)
    ok = rows[rows["status"] == "ok"]
    assert sorted(zip(ok["method"], ok["width"])) == [("vertex", 64), ("vertex", 80),
                                                      ("wavelet-image", 64)]
    assert (ok["frame_ms"] > 0).all() and (ok["resident_bytes"] > 0).all()
    assert (ok["frames"] == 2).all() and set(ok["reference"]) == {"none"}
    assert "device" in rows and rows["device"].str.contains(" cores").all()
    assert ok["renderer"].str.len().gt(0).all() and ok["load_average"].notna().all()
    # wavelet-image precomputes for one image size: the other is refused, with the reason.
    refused = rows[rows["status"] == "refused"]
    assert list(zip(refused["method"], refused["width"])) == [("wavelet-image", 80)]
    assert "64x48" in refused["reason"].iloc[0]
    with table.open() as fh:
        assert len(list(csv.DictReader(fh))) == len(rows)
    assert "| vertex | 64x48 |" in capsys.readouterr().out


def test_no_method_starts_after_the_budget_and_the_run_says_so(tmp_path, capsys):
    results = tmp_path / "r.sqlite"
    code = _script().main(["--method", "vertex", "--method", "wavelet-image", "--knobs", "smoke",
                           "--res", "64x48", "--views", "1", "--frames", "2", "--warmup", "1",
                           "--budget-seconds", "0.001", "--results", str(results),
                           "--csv", str(tmp_path / "fps.csv")])
    rows = measurements.load("paper-fps", results_path=results)
    assert code == 1
    assert dict(zip(rows["method"], rows["status"])) == {"vertex": "ok",
                                                         "wavelet-image": "skipped"}
    assert "skipped (over budget): wavelet-image" in capsys.readouterr().err


def test_a_bad_option_is_one_line_and_exit_2(tmp_path, capsys):
    script = _script()
    assert script.main(["--method", "vertx", "--results", str(tmp_path / "r.sqlite")]) == 2
    assert script.main(["--frames", "0"]) == 2
    assert script.main(["--res", "20x", "--results", str(tmp_path / "r.sqlite")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 3 and all(line.startswith("prtbench: error: ") for line in err)
    assert "did you mean 'vertex'" in err[0]
