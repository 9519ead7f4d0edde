"""``prtbench stability --import-csv``: a written report's rows back into a results store."""

from __future__ import annotations

import csv
import io
from pathlib import Path

import pytest

from prtbench.cli import main
from prtbench.errors import InvalidInputError
from prtbench.stability.importing import import_csv
from prtbench.stability.matrix import TABLE, stored_rows
from prtbench.stability.report import CSV_COLUMNS, format_csv, format_markdown

COMMITTED = Path(__file__).resolve().parents[2] / "reports" / "table-stability.csv"


def _row(method, case, outcome, *, stamp, partial=False, **values):
    return {"method": method, "case": case, "group": "knob", "outcome": outcome,
            "reason": "r", "scene": "s", "variant": "diffuse", "profile": "smoke",
            "git_sha": "abc", "renderer": "llvmpipe", "device": "cpu", "timestamp": stamp,
            "run_id": "000123", "partial_run": partial, **values}


def _csv(tmp_path: Path, rows, name="table-stability.csv") -> Path:
    path = tmp_path / name
    path.write_text(format_csv(rows))
    return path


def _numbers_equal(a: str, b: str) -> bool:
    if a == b:
        return True
    try:  # pandas reads a column mixing 12 and 12.5 back as floats: the value is the same
        return float(a) == float(b)
    except ValueError:
        return False


def test_rows_round_trip_with_their_own_revision_time_and_kinds(tmp_path):
    store = tmp_path / "r.sqlite"
    rows = [_row("m", "moderate", "ok", stamp="2026-01-01T00:00:00+00:00", psnr_masked=31.25,
                 overflow=12, precompute_cached=True, memory_bytes=4096.0),
            _row("m", "sh_bands=1", "degraded", stamp="2026-01-01T00:00:05+00:00",
                 psnr_masked=0.1 + 0.2, precompute_cached=False, git_sha="def"),
            _row("m", "light=black", "ok", stamp="2026-01-02T00:00:00+00:00", partial=True)]
    summary = import_csv(_csv(tmp_path, rows), results_path=store)
    assert (summary.complete_rows, summary.partial_rows) == (2, 1)
    back = stored_rows(profile="smoke", results_path=store, partial=True)
    # An unregistered method's rows: moderate first, then by name.
    assert [(r["case"], r["partial_run"]) for r in back] == [
        ("moderate", False), ("light=black", True), ("sh_bands=1", False)]
    back = [back[0], back[2], back[1]]
    assert back[1]["psnr_masked"] == 0.1 + 0.2  # the repr float, bit for bit
    assert back[1]["git_sha"] == "def" and back[0]["git_sha"] == "abc"
    assert back[0]["timestamp"] == "2026-01-01T00:00:00+00:00"
    assert back[0]["overflow"] == 12 and back[0]["precompute_cached"] is True
    assert back[0]["run_id"] == "000123"  # a digits-only id stays text
    assert all(r["imported_from"].startswith("table-stability.csv sha256:") for r in back)
    complete = stored_rows(profile="smoke", results_path=store)
    assert [r["case"] for r in complete] == ["moderate", "sh_bands=1"]  # partial only on ask
    md = format_markdown(back)
    assert "Imported: 3 of 3 rows" in md and "| light=black † ‡ |" in md


def test_a_later_measurement_of_a_case_wins_whatever_the_import_order(tmp_path):
    from prtbench import measurements

    store = tmp_path / "r.sqlite"
    fresh = measurements.new_run_id()
    measurements.record(TABLE, [{"method": "m", "case": "moderate", "outcome": "ok"}],
                        results_path=store, run_id=fresh, profile="smoke", git_sha="new")
    measurements.complete_report("table", TABLE, profile="smoke", run_id=fresh, members={},
                                 results_path=store, git_sha="new")
    old = [_row("m", "moderate", "failed", stamp="2020-01-01T00:00:00+00:00"),
           _row("m", "sh_bands=1", "ok", stamp="2020-01-01T00:00:00+00:00")]
    import_csv(_csv(tmp_path, old), results_path=store)  # imported after, measured before
    rows = {r["case"]: r for r in stored_rows(profile="smoke", results_path=store)}
    assert rows["moderate"]["outcome"] == "ok" and rows["moderate"]["git_sha"] == "new"
    assert not rows["moderate"].get("imported_from")
    assert rows["sh_bands=1"]["imported_from"]  # the case only the import has


def test_the_committed_report_survives_the_round_trip(tmp_path):
    store = tmp_path / "r.sqlite"
    summary = import_csv(COMMITTED, results_path=store)
    original = list(csv.DictReader(io.StringIO(COMMITTED.read_text())))
    back = list(csv.DictReader(io.StringIO(format_csv(
        stored_rows(profile="quick", results_path=store, partial=True)))))
    assert summary.complete_rows + summary.partial_rows == len(original) == len(back)
    assert {(r["method"], r["case"]) for r in back} == {(r["method"], r["case"]) for r in original}
    by_case = {(r["method"], r["case"]): r for r in back}
    columns = [c for c in CSV_COLUMNS if c != "imported_from"]
    changed = [(o["method"], o["case"], c) for o in original for c in columns
               if not _numbers_equal(o[c], by_case[(o["method"], o["case"])][c])]
    assert changed == []
    assert sum(r["partial_run"] == "True" for r in back) == summary.partial_rows > 0


@pytest.mark.parametrize("edit, fragment", [
    (lambda text: text.replace("outcome,", "result,", 1), "no column outcome"),
    (lambda text: text.replace(",ok,", ",fine,", 1), "outcome='fine'; accepted: ok"),
    (lambda text: text.replace(",smoke,", ",fast,", 1), "profile='fast'; accepted"),
    (lambda text: text.replace("31.25", "31,25", 1), "more values than columns"),
    (lambda text: text.replace("31.25", "high", 1), "psnr_masked='high'; accepted: a number"),
    (lambda text: text.replace("2026-01-01T00:00:00+00:00", "yesterday", 1),
     "timestamp='yesterday'"),
    (lambda text: text.splitlines()[0] + "\n", "no rows"),
])
def test_a_bad_csv_is_refused_before_anything_is_written(tmp_path, edit, fragment):
    good = _csv(tmp_path, [_row("m", "moderate", "ok", stamp="2026-01-01T00:00:00+00:00",
                                psnr_masked=31.25)], name="good.csv")
    bad = tmp_path / "bad.csv"
    bad.write_text(edit(good.read_text()))
    store = tmp_path / "r.sqlite"
    with pytest.raises(InvalidInputError, match="--import-csv") as info:
        import_csv(bad, results_path=store)
    assert fragment in str(info.value) and "\n" not in str(info.value)
    assert not store.exists()


def test_the_command_imports_once_and_rebuilds_the_report(tmp_path, capsys):
    path = _csv(tmp_path, [_row("vertex", "moderate", "ok", stamp="2026-01-01T00:00:00+00:00",
                                psnr_masked=31.25)])
    store, reports = tmp_path / "r.sqlite", tmp_path / "reports"
    args = ["stability", "--profile", "smoke", "--import-csv", str(path), "--results", str(store),
            "--reports", str(reports)]
    assert main([*args, "--from-store"]) == 0
    text = (reports / "table-stability.md").read_text()
    assert "Imported: 1 of 1 rows" in text and "| moderate ‡ | **ok** | 31.25 |" in text
    capsys.readouterr()
    before = store.stat().st_size, store.read_bytes()
    assert main(args) == 2  # the same file again: refused, the store unchanged
    err = capsys.readouterr().err.strip()
    assert "is already in the store" in err and "\n" not in err
    assert (store.stat().st_size, store.read_bytes()) == before
    assert main([*args, "--method", "vertex"]) == 2
    assert "--import-csv with --method/--case" in capsys.readouterr().err
    missing = tmp_path / "nope.csv"
    assert main(["stability", "--import-csv", str(missing), "--results", str(tmp_path / "x.sqlite"),
                 "--reports", str(reports)]) == 2
    err = capsys.readouterr().err.strip()
    assert f"--import-csv {missing}" in err and "\n" not in err
    assert not (tmp_path / "x.sqlite").exists()
