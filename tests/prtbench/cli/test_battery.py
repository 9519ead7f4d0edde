"""The bad-input battery's findings: each case is one line ``prtbench: error: …`` naming the
value (exit 2, nothing written to the cache, the store or the output folders), or a correct
result -- an interrupted sweep says one line, a damaged build record is never trusted."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import psutil
import pytest

from prtbench.cli import COMMANDS, main
from prtbench.store.results import ResultRow, ResultsStore

ROOT = Path(__file__).resolve().parents[3]
RUN = ["run", "--method", "vertex", "--scene", "sphere-over-plane", "--profile", "smoke",
       "--light", "sky", "--quiet", "--out", "out", "--results", "r.sqlite"]
INTERRUPTED = "prtbench: interrupted (caches and results hold only completed work)"


@pytest.fixture
def place(tmp_path, monkeypatch):
    """An empty folder as the working directory, with its own cache and results store."""
    monkeypatch.setenv("PRTBENCH_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("PRTBENCH_RESULTS", str(tmp_path / "default.sqlite"))
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _status(argv: list[str]) -> int:
    """``prtbench ARGV``'s exit status: argparse's errors leave by ``SystemExit`` as ``-m`` does."""
    try:
        return main(argv)
    except SystemExit as exc:
        return exc.code


def _snapshot(root: Path) -> dict[str, bytes]:
    return {str(p.relative_to(root)): (p.read_bytes() if p.is_file() else b"<dir>")
            for p in sorted(root.rglob("*"))}


def _refused(place: Path, capsys, argv: list[str], *fragments: str) -> str:
    """Run ``argv``: exit 2, one stderr line naming ``fragments``, nothing written."""
    before = _snapshot(place)
    assert _status(argv) == 2
    captured = capsys.readouterr()
    err = captured.err
    assert err.startswith("prtbench: error: ") and err.count("\n") == 1, err
    for fragment in fragments:
        assert fragment in err, err
    assert _snapshot(place) == before  # no cache entry, row, image or probe left
    return err


def test_json_on_the_out_folder_is_refused_before_any_work(place, capsys):
    # --out does not exist yet: alone, each passes its check; the run makes `out` a folder.
    _refused(place, capsys, [*RUN, "--json", "out"], "--json 'out' is the --out folder",
             "accepted: a file path")
    _refused(place, capsys, [*RUN[:-4], "--out", "out/images", "--results", "r.sqlite",
                             "--json", "out"], "--json 'out' is above the --out folder")
    _refused(place, capsys, [*RUN, "--json", str(place / "out")],
             f"--json '{place / 'out'}' is the --out folder 'out'")
    _refused(place, capsys, ["stability", "--method", "vertex", "--profile", "smoke", "--reports",
                             "rep", "--json", "rep", "--results", "r.sqlite"],
             "--json 'rep' is the --reports folder 'rep'")


@pytest.mark.parametrize("extra, fragments", [
    (["--light", ""], ["--light ''", "accepted: light name"]),
    (["--res", ""], ["--res ''", "accepted: WxH"]),
    (["--views", "abc"], ["--views 'abc'", "accepted: a whole number of views"]),
    (["--views", "1.5"], ["--views '1.5'", "accepted: a whole number"]),
    (["--views", ""], ["--views ''", "accepted: a whole number"]),
    (["--views", "1e3"], ["--views '1e3'", "accepted: a whole number"]),
    (["--views", "-1"], ["--views -1", "accepted: 1.."]),  # a number, out of range
    (["--res", "-64x48"], ["--res '-64x48'", "accepted: width and height in 8..8192"]),
    (["--res", "1_000x48"], ["--res '1_000x48'", "accepted: WxH"]),
    (["--scene-param", "radus=1"], ["has no parameter 'radus'; did you mean 'radius'?",
                                    "accepted: radius, height"]),
    (["--resutls", "x.sqlite"], ["run: unknown option '--resutls'; did you mean '--results'?"]),
    (["surplus"], ["run: unexpected argument 'surplus'"]),
])
def test_run_refuses_bad_values_in_one_line(place, capsys, extra, fragments):
    _refused(place, capsys, [*RUN, *extra], *fragments)


@pytest.mark.parametrize("argv, fragments", [
    (["reference", "--scene", "sphere-over-plane", "--spp", "nan"],
     ["--spp 'nan'", "accepted: a whole number of samples per pixel"]),
    (["reference", "--scene", "sphere-over-plane", "--light", ""], ["--light ''"]),
    (["list", "foo"], ["list: unknown kind 'foo'; accepted: methods, scenes"]),
    (["list", "method"], ["unknown kind 'method'; did you mean 'methods'?"]),
    (["run", "--scene", "plants"], ["run: missing --method", "prtbench run --help"]),
    ([], ["missing COMMAND; accepted: list, describe"]),
    (["rnu"], ["unknown command 'rnu'; did you mean 'run'?"]),
    (["run", "--method", "vertex", "--scene", "plants", "--views"],
     ["--views: expected one argument"]),
    (["scene", "info", "plants", "--scene-parm", "x=1"],
     ["scene info: unknown option '--scene-parm'; did you mean '--scene-param'?"]),
    (["sweep", "--scene", "plants", "--method", "vertex", "--grid", "sh_bands=3,,4"],
     ["--grid 'sh_bands=3,,4' has an empty value"]),
    (["sweep", "--scene", "plants", "--method", "vertex", "--grid", "sh_bands=3,4,"],
     ["--grid 'sh_bands=3,4,' has an empty value"]),
    (["sweep", "--scene", "plants,", "--method", "vertex"], ["--scene 'plants,' has an empty value"]),
    (["sweep", "--scene", "plants", "--method", "vertex", "--grid", "sh_bands=[3,4"],
     ["--grid 'sh_bands=[3,4' has unbalanced brackets"]),
    (["sweep", "--scene", "plants", "--method", "vertex", "--workers", "two"],
     ["--workers 'two'", "accepted: a whole number of workers"]),
])
def test_argument_mistakes_are_one_line(place, capsys, argv, fragments):
    _refused(place, capsys, argv, *fragments)


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_every_subcommand_answers_an_unknown_option_in_one_line(place, capsys, command):
    err = _refused(place, capsys, [command, "--no-such-option"])
    # A command with subcommands of its own first misses the subcommand.
    assert "'--no-such-option'" in err or "missing" in err, err


def test_python_dash_m_prints_one_line_too(place):
    done = subprocess.run([sys.executable, "-m", "prtbench", "run", "--method", "vertex",
                           "--scene", "plants", "--views", "1.5"], capture_output=True,
                          text=True, cwd=place)
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr == ("prtbench: error: --views '1.5'; accepted: a whole number of "
                           "views, 1 up to the scene's\n")


def test_results_names_unknown_filters_with_a_did_you_mean(place, capsys):
    ResultsStore(place / "r.sqlite").append([
        ResultRow(method="vertex", scene="plane", profile="smoke"),
        ResultRow(method="retired-method", scene="file-1234abcd", profile="smoke")])
    for flag, typo, fix in (("--method", "vertx", "vertex"), ("--scene", "plnts", "plants"),
                            ("--profile", "smok", "smoke")):
        kind = flag[2:]
        _refused(place, capsys, ["results", "--results", "r.sqlite", flag, typo],
                 f"unknown {kind} '{typo}'; did you mean '{fix}'?")
    # Names that are stored but no longer (or never) registered are rows, not mistakes.
    assert _status(["results", "--results", "r.sqlite", "--method", "retired-method"]) == 0
    assert "file-1234abcd" in capsys.readouterr().out
    assert _status(["results", "--results", "r.sqlite", "--scene", "plants"]) == 0
    assert capsys.readouterr().out.strip() == "no results"  # registered, nothing stored


def _summary(place: Path) -> dict:
    return json.loads((place / "out" / "vertex" / "sphere-over-plane-diffuse" / "sky"
                       / "summary.json").read_text())


def test_a_damaged_build_record_is_detected_and_rewritten(place, capsys):
    argv = [*RUN[:-2], "--no-store"]
    assert _status(argv) == 0
    folder = place / "cache" / "artifacts" / "vertex"
    (record,) = folder.glob("*.json")
    (artifact,) = folder.glob("*.npz")
    first = _summary(place)["precompute_s"]
    assert json.loads(record.read_text()) == {"precompute_s": first} and first > 0

    # A cache hit: the truncated record is rewritten from the artifact's own meta.
    record.write_text('{"precompute_s": 0')
    assert _status(argv) == 0
    assert _summary(place)["precompute_cached"] and _summary(place)["precompute_s"] == first
    assert json.loads(record.read_text()) == {"precompute_s": first}
    record.write_text('{"precompute_s": 0.5}')  # sound but not the artifact's: rewritten too
    assert _status(argv) == 0
    assert json.loads(record.read_text()) == {"precompute_s": first}

    # A rebuild (corrupt artifact) beside a damaged record: its 0 is not trusted; the first
    # build's time is unknown now, so no record claims one.
    record.write_text('{"precompute_s": 0')
    artifact.write_bytes(artifact.read_bytes()[:100])
    assert _status(argv) == 0
    rebuilt = _summary(place)
    assert rebuilt["precompute_rebuilt"] and rebuilt["precompute_s"] > 0
    assert not record.exists()

    # A build from scratch (artifact gone) beside a damaged record: recorded anew.
    artifact.unlink()
    record.write_text('{"precompute_s": -1}')
    assert _status(argv) == 0
    built = _summary(place)
    assert not built["precompute_rebuilt"] and not built["precompute_cached"]
    assert json.loads(record.read_text()) == {"precompute_s": built["precompute_s"]} != {
        "precompute_s": -1}
    capsys.readouterr()


def _sweep(cache: Path, results: Path) -> list[str]:
    return [sys.executable, "-m", "prtbench", "sweep", "--scene", "plants", "--method",
            "vertex", "--grid", "sh_bands=2,3,4,5", "--profile", "smoke", "--workers", "2",
            "--results", str(results), "--quiet"]


def _is_worker(process: psutil.Process) -> bool:
    """A spawned Dask worker (not multiprocessing's resource tracker), gone or not."""
    try:
        return any("spawn_main" in part for part in process.cmdline())
    except psutil.Error:
        return False


# ~30 s with its resume; make test keeps kill -9 mid-sweep and its resume (test_sweep.py)
@pytest.mark.slow
@pytest.mark.parametrize("target", ["group", "process"])
def test_sigint_to_a_running_sweep_is_one_line_and_resumes(tmp_path, target):
    """Ctrl-C signals the terminal's whole process group (the Dask workers too); ``kill -INT``
    only the client. Either way: exit 130, one line, and a rerun measures only the rest."""
    cache, results = tmp_path / "cache", tmp_path / "r.sqlite"
    env = {**os.environ, "PRTBENCH_CACHE": str(cache), "PRTBENCH_RESULTS": str(results)}
    sweep = subprocess.Popen(_sweep(cache, results), cwd=ROOT, env=env, stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        deadline = time.monotonic() + 240
        client = psutil.Process(sweep.pid)
        # The Dask workers are up (the client ignores SIGINT while it starts them, which under
        # load takes seconds, and may lock a cache entry of its own before that) ...
        while sum(_is_worker(c) for c in client.children(recursive=True)) < 2:
            assert sweep.poll() is None and time.monotonic() < deadline, sweep.communicate()
            time.sleep(0.02)
        # ... and a cell is running: a worker holds a cache entry's lock (transfer, artifact,
        # reference).
        while not any((cache / ".locks").glob("*.lock")):
            assert sweep.poll() is None and time.monotonic() < deadline, sweep.communicate()
            time.sleep(0.02)
        if target == "group":
            os.killpg(sweep.pid, signal.SIGINT)
        else:
            sweep.send_signal(signal.SIGINT)
        out, err = sweep.communicate(timeout=120)
    finally:
        if sweep.poll() is None:
            os.killpg(sweep.pid, signal.SIGKILL)
            sweep.wait()
    assert sweep.returncode == 130, err
    assert err == INTERRUPTED + "\n"
    kept = {row.cell_key for row in ResultsStore(results).query()} if results.exists() else set()
    assert len(kept) < 4
    if target != "group":  # the resume is the same either way: checked once
        return
    again = subprocess.run(_sweep(cache, results), cwd=ROOT, env=env, capture_output=True,
                           text=True, timeout=300)
    assert again.returncode == 0, again.stderr
    assert f"4 cells: {4 - len(kept)} done, {len(kept)} skipped" in again.stdout
    assert len({row.cell_key for row in ResultsStore(results).query()}) == 4
