"""The CLI of issue #12: bad output locations, read-only queries, unknown profiles, view counts
and degenerate measurements — each a one-line error (exit 2) or a flagged result (exit 1),
with nothing written."""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path

import numpy as np
import pytest

from prtbench.cli import main
from prtbench.store.results import ResultsStore
from tests.prtbench.bench.test_runner_validation import patch_render

RUN = ["run", "--method", "vertex", "--scene", "sphere-over-plane", "--profile", "smoke",
       "--light", "sky", "--quiet"]


@pytest.fixture
def place(tmp_path, monkeypatch):
    """A folder with a plain file, a foreign SQLite file and a junk file; its own cache."""
    (tmp_path / "file").write_text("x")
    conn = sqlite3.connect(tmp_path / "foreign.sqlite")
    conn.execute("CREATE TABLE notes (x)")
    conn.commit()
    conn.close()
    (tmp_path / "junk.sqlite").write_bytes(b"not sqlite at all " * 20)
    monkeypatch.setenv("PRTBENCH_CACHE", str(tmp_path / "cache"))
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _snapshot(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): (p.read_bytes() if p.is_file() else b"<dir>")
            for p in sorted(root.rglob("*"))}


def _one_line_error(capsys, *fragments: str) -> str:
    err = capsys.readouterr().err.strip()
    assert err.startswith("prtbench: error: ") and "\n" not in err, err
    for fragment in fragments:
        assert fragment in err, err
    return err


@pytest.mark.parametrize("extra, fragments", [
    (["--json", "."], ["--json '.' is a folder"]),
    (["--out", "file"], ["--out 'file' is a file"]),
    (["--out", "file/sub"], ["--out 'file/sub' is under the file", "file'"]),
    (["--json", "file/s.json"], ["--json 'file/s.json' is under the file"]),
    (["--results", "foreign.sqlite"], ["--results", "foreign.sqlite' is an SQLite file but not a prtbench"]),
    (["--results", "junk.sqlite"], ["--results", "junk.sqlite' is not a usable SQLite file"]),
    (["--results", "file"], ["--results", "'file' is not a usable SQLite file"]),  # never overwritten
    (["--results", "."], ["--results '.' is a folder"]),
    (["--results", "file/r.sqlite"], ["--results 'file/r.sqlite' is under the file"]),
])
def test_run_output_locations_checked_before_work(place, capsys, extra, fragments):
    before = _snapshot(place)
    argv = [*RUN, "--out", "out", "--results", "r.sqlite"]
    status = main([*argv, *extra])
    assert status == 2
    _one_line_error(capsys, *fragments)
    assert _snapshot(place) == before  # no cache entry, no row, no image, no probe left


def test_cache_on_a_file_is_an_error(place, capsys, monkeypatch):
    monkeypatch.setenv("PRTBENCH_CACHE", str(place / "file" / "cache"))
    before = _snapshot(place)
    assert main([*RUN, "--out", "out", "--results", "r.sqlite"]) == 2
    _one_line_error(capsys, "$PRTBENCH_CACHE", "file/cache' is under the file")
    assert _snapshot(place) == before


def test_read_only_file_system(place, capsys):
    import subprocess

    ro = place / "ro"
    ro.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "ro,size=1m", "tmpfs", str(ro)],
                      capture_output=True).returncode != 0:
        pytest.skip("cannot mount a read-only tmpfs here (needs root)")
    try:
        before = _snapshot(place)
        for extra, option in ((["--out", "ro/out"], "--out 'ro/out'"),
                              (["--results", "ro/r.sqlite"], "--results 'ro/r.sqlite'")):
            argv = [*RUN, "--out", "out", "--results", "r.sqlite", *extra]
            assert main(argv) == 2
            _one_line_error(capsys, option, "Read-only file system")
        assert _snapshot(place) == before
    finally:
        subprocess.run(["umount", str(ro)], check=True)


def test_results_is_read_only_and_checks_its_arguments(place, capsys, monkeypatch):
    monkeypatch.delenv("PRTBENCH_RESULTS", raising=False)  # the default: ./results/prtbench.sqlite
    before = _snapshot(place)
    assert main(["results", "--results", "."]) == 2
    _one_line_error(capsys, "results store '.' is a folder")
    assert main(["results", "--results", "missing/r.sqlite"]) == 2
    _one_line_error(capsys, "no results store at 'missing/r.sqlite'", "`prtbench run` fills it")
    assert main(["results"]) == 2
    _one_line_error(capsys, "no results store at", "results/prtbench.sqlite'")  # and no folder made
    assert main(["results", "--results", "foreign.sqlite"]) == 2
    _one_line_error(capsys, "foreign.sqlite' is an SQLite file but not a prtbench")
    assert main(["results", "--results", "file"]) == 2
    _one_line_error(capsys, "'file' is not a usable SQLite file")
    assert _snapshot(place) == before
    ResultsStore(place / "r.sqlite").append([])  # nothing: no file
    assert not (place / "r.sqlite").exists()


def test_results_rejects_an_unknown_profile(place, capsys):
    from prtbench.store.results import ResultRow

    ResultsStore(place / "r.sqlite").append([ResultRow(method="vertex", scene="plane", profile="smoke")])
    assert main(["results", "--results", "r.sqlite", "--profile", "fast"]) == 2
    _one_line_error(capsys, "unknown profile 'fast'")
    assert main(["results", "--results", "r.sqlite", "--profile", "smoke"]) == 0
    out = capsys.readouterr().out
    assert "plane" in out


@pytest.mark.parametrize("argv, fragments", [
    (["reference", "--scene", "sphere-over-plane", "--views", "0"], ["--views 0", "accepted: 1.."]),
    (["reference", "--scene", "sphere-over-plane", "--views", "999"], ["--views 999"]),
    (["figure", "4.11", "--profile", "fast"], ["unknown profile 'fast'"]),
    (["table", "4.1", "--profile", "fast"], ["unknown profile 'fast'"]),
    (["table", "4.1", "--profile", "smoke", "--reports", "file"], ["--reports 'file' is a file"]),
    (["table", "4.1", "--profile", "smoke", "--results", "junk.sqlite"], ["--results", "junk.sqlite"]),
    (["figure", "4.11", "--profile", "smoke", "--results", "."], ["--results '.' is a folder"]),
])
def test_reference_table_figure_checked_before_work(place, capsys, argv, fragments):
    before = _snapshot(place)
    assert main(argv) == 2
    _one_line_error(capsys, *fragments)
    assert _snapshot(place) == before  # no reports folder, no cache entry, no store


def test_reference_cache_checked_before_rendering(place, capsys, monkeypatch):
    monkeypatch.setenv("PRTBENCH_CACHE", str(place / "file"))
    before = _snapshot(place)
    assert main(["reference", "--scene", "sphere-over-plane", "--profile", "smoke"]) == 2
    _one_line_error(capsys, "$PRTBENCH_CACHE", "is a file")
    assert _snapshot(place) == before


def test_degenerate_run_is_stored_flagged_and_exits_1(place, capsys, monkeypatch):
    patch_render(monkeypatch, "vertex", lambda image: np.zeros_like(image))
    status = main([*RUN, "--out", "out", "--results", "r.sqlite", "--json", "s.json"])
    assert status == 1
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert err[-1].startswith("prtbench: degenerate result") and "method image is all black" in err[-1]
    assert "status=degenerate: view 0: method image is all black" in captured.out
    (row,) = ResultsStore(place / "r.sqlite").query()
    assert row.status == "degenerate" and "method image is all black" in row.status_reason
    data = json.loads((place / "s.json").read_text(), parse_constant=lambda name: 1 / 0)
    assert data["status"] == "degenerate"
    assert main(["results", "--results", "r.sqlite", "--profile", "smoke"]) == 0
