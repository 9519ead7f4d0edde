"""Reports come from the results store only: measurement tables, report runs, ``--from-store``."""

from __future__ import annotations

import json
import sqlite3

import pytest

from prtbench.api.errors import InvalidInputError, PrtbenchError
from prtbench.store import measurements


def _no_bare_constants(text: str):
    def refuse(token):
        raise AssertionError(f"non-strict JSON token {token} in {text!r}")

    return json.loads(text, parse_constant=refuse)


def _counts(store):
    conn = sqlite3.connect(store)
    try:
        return tuple(conn.execute(f"SELECT COUNT(*) FROM {t}").fetchone()[0]
                     for t in ("renders", "measurements", "measurement_images", "report_runs"))
    finally:
        conn.close()


def _files(folder):
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def test_measurement_rows_are_strict_json_with_provenance(tmp_path):
    store = tmp_path / "results.sqlite"
    measurements.record("demo", [{"a": float("nan"), "b": float("inf"), "c": 1.5, "n": 3,
                                  "v": [0.25, float("-inf")]}],
                        results_path=store, run_id="r1", profile="smoke", renderer="gl",
                        device="cpu", git_sha="abc", images={"p": [[0.0, 1.0]]})
    raw = sqlite3.connect(store).execute("SELECT data, git_sha, profile, run_id, renderer, device, "
                                         "timestamp FROM measurements").fetchall()
    assert len(raw) == 1
    data = _no_bare_constants(raw[0][0])
    assert data == {"a": None, "b": None, "c": 1.5, "n": 3, "v": [0.25, None]}
    assert raw[0][1:6] == ("abc", "smoke", "r1", "gl", "cpu") and raw[0][6].startswith("20")
    frame = measurements.load("demo", run_ids=["r1"], results_path=store)
    assert list(frame["c"]) == [1.5] and frame["a"].isna().all()
    assert measurements.load("demo", run_ids=["other"], results_path=store).empty
    assert measurements.load_images("r1", results_path=store)["p"].tolist() == [[0.0, 1.0]]


def test_a_bad_row_stores_nothing_and_reads_create_nothing(tmp_path):
    store = tmp_path / "results.sqlite"
    with pytest.raises(InvalidInputError, match="measurement value"):
        measurements.record("demo", [{"ok": 1}, {"bad": object()}], results_path=store,
                            run_id="r1", profile="smoke")
    assert measurements.load("demo", results_path=store).empty
    with pytest.raises(PrtbenchError, match="profile"):
        measurements.record("demo", [{"ok": 1}], results_path=store, run_id="r1", profile="fast")
    missing = tmp_path / "nothing" / "results.sqlite"
    assert measurements.load("demo", results_path=missing).empty
    assert measurements.latest_report("figure", "x", profile="smoke", results_path=missing) is None
    assert not missing.parent.exists()


def test_only_complete_report_runs_are_rebuilt(tmp_path):
    store = tmp_path / "results.sqlite"
    # Rows of a run that never completed (killed before its report run was written).
    measurements.record("demo", [{"x": 1}], results_path=store, run_id="half", profile="smoke")
    with pytest.raises(PrtbenchError, match="prtbench figure demo --profile smoke --results"):
        measurements.require_report("figure", "demo", profile="smoke", results_path=store)
    for run_id in ("old", "new"):
        measurements.record("demo", [{"x": run_id}], results_path=store, run_id=run_id,
                            profile="smoke")
        measurements.complete_report("figure", "demo", profile="smoke", run_id=run_id,
                                     members={"cell1": {"k": 1}}, results_path=store)
    report = measurements.require_report("figure", "demo", profile="smoke", results_path=store)
    assert report.run_id == "new" and report.members == {"cell1": {"k": 1}}
    assert measurements.latest_report("figure", "demo", profile="quick", results_path=store) is None
    assert measurements.latest_report("table", "demo", profile="smoke", results_path=store) is None


@pytest.mark.parametrize("kind,name", [("figure", "ddprt-14"), ("table", "volume")])
def test_from_store_with_an_empty_store_is_one_line_and_writes_nothing(tmp_path, capsys, kind,
                                                                       name):
    from prtbench.cli import main

    results, reports = tmp_path / "store" / "results.sqlite", tmp_path / "reports"
    code = main([kind, name, "--profile", "smoke", "--from-store", "--results", str(results),
                 "--reports", str(reports)])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("prtbench: error: no complete run of")
    assert f"prtbench {kind} {name} --profile smoke --results {results}" in err
    assert not results.parent.exists() and not reports.exists()
    # A store with other rows but no run of this report: the same error, the store unchanged.
    measurements.record("other", [{"x": 1}], results_path=results, run_id="r", profile="smoke")
    before = results.read_bytes()
    assert main([kind, name, "--profile", "smoke", "--from-store", "--results", str(results),
                 "--reports", str(reports)]) == 2
    assert "no complete run" in capsys.readouterr().err
    assert results.read_bytes() == before and not reports.exists()


def test_unknown_profile_is_refused_before_any_work(tmp_path, capsys):
    from prtbench.cli import main

    results = tmp_path / "results.sqlite"
    assert main(["figure", "ddprt-14", "--profile", "fast", "--results", str(results),
                 "--reports", str(tmp_path / "r")]) == 2
    assert "fast" in capsys.readouterr().err
    assert not results.exists() and not (tmp_path / "r").exists()


def test_figure_rebuilt_from_the_store_is_byte_identical(tmp_path, capsys):
    from prtbench.cli import main
    from prtbench.store.results import git_sha

    results = tmp_path / "results.sqlite"
    first, second = tmp_path / "measured", tmp_path / "rebuilt"
    assert main(["figure", "ddprt-14", "--profile", "smoke", "--results", str(results),
                 "--reports", str(first)]) == 0
    before = _counts(results)
    assert main(["figure", "ddprt-14", "--profile", "smoke", "--results", str(results),
                 "--reports", str(second), "--from-store"]) == 0
    assert _counts(results) == before  # nothing measured again
    written = _files(first)
    assert set(written) == {"figure-ddprt-14.png", "figure-ddprt-14-images.png",
                            "figure-ddprt-14.csv", "figure-ddprt-14.md"}
    assert _files(second) == written
    # Every number comes from stored rows that carry their provenance.
    report = measurements.require_report("figure", "ddprt-14", profile="smoke",
                                         results_path=results)
    rows = measurements.load("figure-ddprt-14", run_ids=[report.run_id], results_path=results)
    assert len(rows) > 0 and set(rows["git_sha"]) == {git_sha()} and set(rows["profile"]) == {"smoke"}
    assert rows["device"].str.len().min() > 0
    for (data,) in sqlite3.connect(results).execute("SELECT data FROM measurements"):
        _no_bare_constants(data)
    assert f"git {git_sha()}" in written["figure-ddprt-14.md"].decode()
    # One CSV line per stored row: nothing printed that the store does not hold.
    csv_lines = written["figure-ddprt-14.csv"].decode().splitlines()
    assert len(csv_lines) == 1 + len(rows)


def test_table_rebuilt_from_the_store_is_byte_identical_with_its_leak_column(tmp_path):
    import csv

    import methods.irradiance_volume.method  # noqa: F401 - registers the method
    from prtbench.bench.reproduction import run_table
    from reproductions import table_volume as tv

    class Tiny(tv.VolumeTable):
        def cells(self, profile):
            return [c for c in super().cells(profile)
                    if c.scene == "room" and c.method == "irradiance-volume" and c.label["N"] == 4]

    results = tmp_path / "results.sqlite"
    first, second = tmp_path / "measured", tmp_path / "rebuilt"
    run_table(Tiny(), profile="smoke", results_path=results, reports_dir=first, progress=False)
    before = _counts(results)
    assert before[0] > 0 and before[1] == 1 and before[3] == 1
    run_table(Tiny(), profile="smoke", results_path=results, reports_dir=second, progress=False,
              from_store=True)
    assert _counts(results) == before  # nothing measured again
    assert _files(second) == _files(first)
    rows = list(csv.DictReader(open(first / "table-volume.csv")))
    leak = measurements.load(tv.LEAK_TABLE, results_path=results)
    assert len(rows) == 1 and len(leak) == 1
    assert 0.0 < float(rows[0]["leak MAE (room)"]) < 1.0
    assert float(rows[0]["leak MAE (room)"]) == pytest.approx(float(leak["leak_mae"].iloc[0]),
                                                              rel=1e-3)


def test_integers_stored_in_some_rows_read_back_as_integers(tmp_path):
    """A count kept in one row of a table (a figure's facts row) is not read as 320.0."""
    store = tmp_path / "r.sqlite"
    measurements.record("mixed", [{"panel": "curve", "k": 8, "value": 0.5},
                                  {"panel": "facts", "k": 64, "value": None, "pixels": 320,
                                   "spp": 2.0}],
                        results_path=store, run_id="run-mixed", profile="smoke")
    frame = measurements.load("mixed", results_path=store)
    assert [type(v) for v in frame["pixels"]] == [float, int]  # NaN where absent, int where set
    assert frame["pixels"].iloc[1] == 320 and frame["pixels"].iloc[0] != frame["pixels"].iloc[0]
    assert frame["k"].dtype == "int64"  # every row has it: an integer column already
    assert frame["spp"].dtype == "float64"  # stored as a float: stays one
    assert frame["value"].iloc[1] != frame["value"].iloc[1]  # null float: NaN, as before
    assert f"{frame['pixels'].iloc[1]}" == "320"
