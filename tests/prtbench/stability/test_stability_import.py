"""``prtbench stability --import-csv``: a written report's rows back into a results store."""

from __future__ import annotations

import csv
import io
from pathlib import Path

import pytest

from prtbench.api.errors import InvalidInputError
from prtbench.cli import main
from prtbench.stability.importing import FLAG_COLUMNS, TEXT_COLUMNS, import_csv
from prtbench.stability.matrix import TABLE, stored_rows
from prtbench.stability.report import CSV_COLUMNS, format_csv, format_markdown

COMMITTED = Path(__file__).resolve().parents[3] / "reports" / "table-stability.csv"


def _row(method, case, outcome, *, stamp, partial=False, **values):
    return {"method": method, "case": case, "group": "knob", "outcome": outcome,
            "reason": "r", "scene": "s", "variant": "diffuse", "profile": "smoke",
            "git_sha": "abc", "renderer": "llvmpipe", "device": "cpu", "timestamp": stamp,
            "run_id": "000123", "partial_run": partial, **values}


def _csv(tmp_path: Path, rows, name="table-stability.csv") -> Path:
    path = tmp_path / name
    path.write_text(format_csv(rows))
    return path


def _same(column: str, a: str, b: str) -> bool:
    """Text and flags exactly; numbers by value (pandas reads a column mixing 12 and 12.5 back
    as floats, so 12 may be written as 12.0: the same number)."""
    if a == b:
        return True
    if column in TEXT_COLUMNS or column in FLAG_COLUMNS or "" in (a, b):
        return False
    return float(a) == float(b)


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
    assert type(back[0]["overflow"]) is int and back[0]["overflow"] == 12  # ints stay ints
    assert type(back[0]["memory_bytes"]) is float and back[0]["memory_bytes"] == 4096.0
    assert back[0]["precompute_cached"] is True and back[1]["precompute_cached"] is False
    assert back[0]["run_id"] == "000123"  # a digits-only id stays text
    assert all(r["imported_from"].startswith("table-stability.csv sha256:") for r in back)
    complete = stored_rows(profile="smoke", results_path=store)
    assert [r["case"] for r in complete] == ["moderate", "sh_bands=1"]  # partial only on ask
    md = format_markdown(back)
    assert "Imported: 3 of 3 rows" in md and "| light=black † ‡ |" in md


def test_a_later_measurement_of_a_case_wins_whatever_the_import_order(tmp_path):
    from prtbench.store import measurements

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


def test_a_measured_row_wins_a_tie_with_an_imported_one(tmp_path, monkeypatch):
    from prtbench.store import measurements

    store = tmp_path / "r.sqlite"
    monkeypatch.setattr(measurements, "_utc_now", lambda: "2026-01-01T00:00:00+00:00")
    fresh = measurements.new_run_id()
    measurements.record(TABLE, [{"method": "m", "case": "moderate", "outcome": "ok"}],
                        results_path=store, run_id=fresh, profile="smoke", git_sha="new")
    measurements.complete_report("table", TABLE, profile="smoke", run_id=fresh, members={},
                                 results_path=store, git_sha="new")
    import_csv(_csv(tmp_path, [_row("m", "moderate", "failed",
                                    stamp="2026-01-01T00:00:00+00:00")]), results_path=store)
    (row,) = stored_rows(profile="smoke", results_path=store)
    assert row["outcome"] == "ok" and not row.get("imported_from")


def test_an_import_never_doubles_rows(tmp_path):
    """A report rewritten from an import, or imported into the store it was written from,
    holds only rows the store has: refused, nothing stored."""
    store = tmp_path / "r.sqlite"
    rows = [_row("m", "moderate", "ok", stamp="2026-01-01T00:00:00+00:00", psnr_masked=31.25),
            _row("m", "light=black", "ok", stamp="2026-01-01T00:00:09+00:00", partial=True)]
    import_csv(_csv(tmp_path, rows), results_path=store)
    rewritten = tmp_path / "rewritten.csv"  # what --from-store --partial writes next
    rewritten.write_text(format_csv(stored_rows(profile="smoke", results_path=store,
                                                partial=True)))
    assert "imported_from" in rewritten.read_text().splitlines()[0]
    before = store.read_bytes()
    with pytest.raises(InvalidInputError, match="all 2 rows of rewritten.csv sha256:[0-9a-f]{12} "
                                                "are already in the store"):
        import_csv(rewritten, results_path=store)
    assert store.read_bytes() == before
    # One new row among known ones: only it is stored, the others are counted as skipped.
    more = rows + [_row("m", "sh_bands=1", "degraded", stamp="2026-01-02T00:00:00+00:00")]
    summary = import_csv(_csv(tmp_path, more, name="more.csv"), results_path=store)
    assert (summary.complete_rows, summary.partial_rows, summary.skipped_rows) == (1, 0, 2)
    back = stored_rows(profile="smoke", results_path=store, partial=True)
    assert sorted(r["case"] for r in back) == ["light=black", "moderate", "sh_bands=1"]
    assert {r["imported_from"].split()[0] for r in back} == {"table-stability.csv", "more.csv"}


def test_a_failure_part_way_stores_nothing(tmp_path, monkeypatch):
    from prtbench.store import measurements

    store = tmp_path / "r.sqlite"
    rows = [_row("m", "moderate", "ok", stamp="2026-01-01T00:00:00+00:00"),
            _row("m", "sh_bands=1", "ok", stamp="2026-01-01T00:00:05+00:00")]  # two batches
    real, calls = measurements._insert_rows, []

    def second_fails(*args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            raise OSError("disk full")
        return real(*args, **kwargs)

    monkeypatch.setattr(measurements, "_insert_rows", second_fails)
    with pytest.raises(OSError, match="disk full"):
        import_csv(_csv(tmp_path, rows), results_path=store)
    monkeypatch.setattr(measurements, "_insert_rows", real)
    assert measurements.load(TABLE, results_path=store).empty
    summary = import_csv(_csv(tmp_path, rows), results_path=store)  # a retry is not refused
    assert summary.complete_rows == 2


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
               if not _same(c, o[c], by_case[(o["method"], o["case"])][c])]
    assert changed == []
    # As many rows of interrupted runs as the report has (none since every case ran to its end;
    # partial rows' own round trip is the synthetic one of
    # test_rows_round_trip_with_their_own_revision_time_and_kinds).
    partial = sum(o["partial_run"] == "True" for o in original)
    assert sum(r["partial_run"] == "True" for r in back) == summary.partial_rows == partial


@pytest.mark.parametrize("edit, fragment", [
    (lambda text: text.replace("outcome,", "result,", 1), "no column outcome"),
    (lambda text: text.replace(",ok,", ",fine,", 1), "outcome='fine'; accepted: ok"),
    (lambda text: text.replace(",smoke,", ",fast,", 1), "profile='fast'; accepted"),
    (lambda text: text.replace("31.25", "31,25", 1), "more values than columns"),
    (lambda text: text.replace("31.25", "high", 1), "psnr_masked='high'; accepted: a number"),
    (lambda text: text.replace("2026-01-01T00:00:00+00:00", "yesterday", 1),
     "timestamp='yesterday'"),
    (lambda text: text.splitlines()[0] + "\n", "no rows"),
    (lambda text: text.replace("partial_run", "partial_run,extra", 1).replace(
        "\n", ",1\n").replace("extra,1", "extra", 1), "unknown column extra"),
    (lambda text: text.replace("2026-01-01T00:00:00+00:00", "2026-01-01T01:00:00+01:00", 1),
     "accepted: UTC as the store writes it"),
    (lambda text: text.replace("2026-01-01T00:00:00+00:00", "2026-01-01", 1),
     "timestamp='2026-01-01'"),
    (lambda text: text.replace("2026-01-01T00:00:00+00:00", "2999-01-01T00:00:00+00:00", 1),
     "is in the future"),
    (lambda text: text + text.splitlines()[1].replace(",smoke,", ",quick,") + "\n",
     "rows of profiles quick, smoke; accepted: one profile per file"),
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
    before = store.read_bytes()
    for extra, fragment in [
            ([], "all 1 rows of table-stability.csv sha256:"),  # the same file again
            (["--method", "vertex"], "--import-csv with --method; accepted"),
            (["--json", str(tmp_path / "x.json")], "--import-csv with --json; accepted"),
            (["--partial"], "--import-csv with --partial; accepted")]:
        assert main([*args, *extra]) == 2, extra
        err = capsys.readouterr().err.strip()
        assert err.startswith("prtbench: error: ") and fragment in err and "\n" not in err, err
        assert store.read_bytes() == before  # nothing written
    assert not (tmp_path / "x.json").exists()


@pytest.mark.parametrize("rows, extra, fragment", [
    ([_row("vertex", "moderate", "ok", stamp="2026-01-01T00:00:00+00:00")], ["--profile", "quick"],
     "rows of profile 'smoke' with --profile 'quick'; accepted: --profile smoke"),
    ([_row("vertex", "moderate", "ok", stamp="2026-01-01T00:00:00+00:00", partial=True)],
     ["--profile", "smoke"], "only rows of interrupted runs and no complete smoke run"),
])
def test_an_import_the_report_could_not_use_is_refused_before_writing(tmp_path, capsys, rows,
                                                                       extra, fragment):
    path = _csv(tmp_path, rows)
    store, reports = tmp_path / "r.sqlite", tmp_path / "reports"
    status = main(["stability", "--import-csv", str(path), "--from-store", "--results", str(store),
                   "--reports", str(reports), *extra])
    err = capsys.readouterr().err.strip()
    assert status == 2 and fragment in err and "\n" not in err, err
    assert not store.exists() and not reports.exists()


def test_a_missing_file_is_one_line_and_creates_no_store(tmp_path, capsys):
    missing, store = tmp_path / "nope.csv", tmp_path / "x.sqlite"
    assert main(["stability", "--import-csv", str(missing), "--results", str(store),
                 "--reports", str(tmp_path / "reports")]) == 2
    err = capsys.readouterr().err.strip()
    assert f"--import-csv {missing}: FileNotFoundError" in err and "\n" not in err
    assert not store.exists()
