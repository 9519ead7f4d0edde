#!/usr/bin/env python3
"""Regenerate the committed reports from one clean commit, recording the machine's load.

``make reports`` runs this script; it is the only way the committed ``reports/`` should be
regenerated (DESIGN.md §20: every committed report comes from one clean commit on an idle
machine). Usage::

    scripts/reports_guard.py check
    scripts/reports_guard.py run [--profile quick] [--results PATH] [--log PATH]
        [--start-at TARGET] [--make MAKE] TARGET...

``check`` refuses a dirty tree in one line (exit 2). ``run`` checks, then runs ``make TARGET
PROFILE=<profile>`` for each target in turn, and around each one records the 1-minute load
average before and after (a line on stderr, a row of ``--log``), warning in one line when it
exceeds :data:`prtbench.bench.reproduction.BUSY_LOAD_PER_CORE` × the core count. After each
target it checks that HEAD and the tree have not changed (another person committing or editing
mid-run would make the later reports name another or a ``+dirty`` commit), and stops if they
have. A target that fails does not stop the others; the run exits 1 naming every failed one.

Dirty means ``git status --porcelain`` lists anything but

* changes under ``reports/``: they are what this run writes, and
  :func:`prtbench.store.results.git_sha` does not count them either;
* untracked files under ``out/``, ``results/`` and the cache (``$PRTBENCH_CACHE`` where it is
  inside the tree): scratch output, not code.

Untracked files anywhere else count (a new method folder not yet committed would be measured
but be in no commit). ``ALLOW_DIRTY=1`` (or ``--allow-dirty``) runs anyway, with a warning: the
reports then name a ``+dirty`` commit and ``tests/test_reports_provenance.py`` fails on them.

The rows go to a results store of their own, ``results/reports-<commit>.sqlite`` (unless
``$PRTBENCH_RESULTS`` or ``--results`` names one), so that nothing measured at another commit
(the Pareto fronts read every stored row of a scene) reaches the reports, and a run
interrupted at this commit resumes into the same store. ``PRTBENCH_RESULTS=<that file> make
report`` builds the comparison site from it.
"""

from __future__ import annotations

import argparse
import csv
import os
import subprocess
import sys
import time
from collections.abc import Sequence
from datetime import datetime, timezone
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: Untracked files under these top-level folders are scratch output, never code.
SCRATCH_FOLDERS = ("out", "results")
#: Changes under these folders are what ``make reports`` writes.
OUTPUT_FOLDERS = ("reports",)
#: Columns of the ``--log`` CSV (one row per target).
LOG_COLUMNS = ("target", "git_sha", "profile", "results", "started_utc", "wall_s", "exit_status",
               "load_before", "load_after", "cores", "busy")
DEFAULT_LOG = Path("out") / "reports" / "provenance.csv"


class GuardError(Exception):
    """A one-line refusal (``prtbench: error: ...``, exit 2)."""


def _git(*args: str) -> str:
    done = subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True,
                          check=False)
    if done.returncode != 0:
        raise GuardError(f"git {' '.join(args)} failed: {done.stderr.strip() or done.returncode}")
    return done.stdout


def head_sha() -> str:
    """The commit checked out (40 hex digits)."""
    return _git("rev-parse", "HEAD").strip()


def _under(path: str, folders: Sequence[str]) -> bool:
    return any(path == f or path.startswith(f.rstrip("/") + "/") for f in folders)


def _cache_folder() -> list[str]:
    """``$PRTBENCH_CACHE`` relative to the tree, where it is inside it (else nothing)."""
    cache = os.environ.get("PRTBENCH_CACHE")
    if not cache:
        return []
    try:
        return [Path(cache).resolve().relative_to(ROOT).as_posix()]
    except ValueError:
        return []


def dirty_entries(porcelain: str, *, cache_folders: Sequence[str] = ()) -> list[str]:
    """The ``git status --porcelain -z`` entries that make the tree dirty, as ``XY path``.

    Parameters
    ----------
    porcelain : str
        Output of ``git status --porcelain=v1 -z --untracked-files=all``.
    cache_folders : sequence of str
        Folders (relative to the tree) whose untracked files are ignored besides
        :data:`SCRATCH_FOLDERS`.

    Returns
    -------
    list of str
        What counts (see the module docstring), in git's order.
    """
    items = porcelain.split("\0")
    entries, i = [], 0
    while i < len(items):
        item = items[i]
        i += 1
        if len(item) < 4:
            continue
        status, path = item[:2], item[3:]
        if status[0] in "RC":  # -z puts a rename's source path in the next item
            i += 1
        if _under(path, OUTPUT_FOLDERS):
            continue
        if status == "??" and _under(path, (*SCRATCH_FOLDERS, *cache_folders)):
            continue
        entries.append(f"{status} {path}")
    return entries


def tree_changes() -> list[str]:
    """:func:`dirty_entries` of this checkout."""
    return dirty_entries(_git("status", "--porcelain=v1", "-z", "--untracked-files=all"),
                         cache_folders=_cache_folder())


def _summary(entries: Sequence[str]) -> str:
    shown = ", ".join(entries[:3])
    return f"{len(entries)} change(s): {shown}{', ...' if len(entries) > 3 else ''}"


def check_clean(*, allow_dirty: bool) -> str:
    """HEAD's commit if the tree is clean; a GuardError (or, allowed, a warning) otherwise."""
    sha = head_sha()
    changes = tree_changes()
    if changes and not allow_dirty:
        raise GuardError(f"make reports needs a clean tree at one commit ({_summary(changes)}); "
                         "commit or stash them, or run with ALLOW_DIRTY=1 (the reports then "
                         "name a +dirty commit)")
    if changes:
        _warn(f"the tree is dirty ({_summary(changes)}); ALLOW_DIRTY=1: the reports will name "
              f"{sha}+dirty")
    return sha


def make_dry_run() -> bool:
    """Whether make runs with ``-n`` (its single-letter flags lead ``$MAKEFLAGS``)."""
    words = os.environ.get("MAKEFLAGS", "").split()
    return bool(words) and not words[0].startswith("-") and "n" in words[0]


def load_1min() -> float | None:
    """The 1-minute load average (None where the OS has none)."""
    try:
        return float(os.getloadavg()[0])
    except (AttributeError, OSError):
        return None


def busy_threshold(cores: int) -> float:
    """The load above which timings are not representative (the reports use the same)."""
    from prtbench.bench.reproduction import BUSY_LOAD_PER_CORE

    return BUSY_LOAD_PER_CORE * cores


def _warn(message: str) -> None:
    print(f"prtbench: warning: {message}", file=sys.stderr, flush=True)


def _fmt_load(load: float | None) -> str:
    return "n/a" if load is None else f"{load:.2f}"


def _append_log(path: Path, row: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    new = not path.exists() or path.stat().st_size == 0
    with path.open("a", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=LOG_COLUMNS, lineterminator="\n")
        if new:
            writer.writeheader()
        writer.writerow(row)


def run_targets(targets: Sequence[str], *, profile: str, make: str, results: Path | None,
                log: Path, start_at: str | None, allow_dirty: bool) -> int:
    """Run each make target in turn from a clean tree; 0 when all succeeded, else 1.

    Parameters
    ----------
    targets : sequence of str
        Make targets, one report (or group of reports) each.
    profile : str
        Passed as ``PROFILE=`` to every target.
    make : str
        The make program (``$(MAKE)`` from the Makefile).
    results : Path or None
        The results store (None: ``$PRTBENCH_RESULTS``, else ``results/reports-<commit>.sqlite``).
    log : Path
        CSV the per-target records are appended to (:data:`LOG_COLUMNS`).
    start_at : str or None
        Skip the targets before this one (to resume an interrupted run at the same commit).
    allow_dirty : bool
        Run on a dirty tree (with a warning).
    """
    if start_at is not None:
        if start_at not in targets:
            raise GuardError(f"--start-at '{start_at}'; accepted: one of {', '.join(targets)}")
        targets = list(targets)[list(targets).index(start_at):]
    sha = check_clean(allow_dirty=allow_dirty)
    if results is None:
        env_results = os.environ.get("PRTBENCH_RESULTS")
        results = (Path(env_results) if env_results
                   else Path("results") / f"reports-{sha[:12]}.sqlite")
    cores = os.cpu_count() or 1
    limit = busy_threshold(cores)
    env = {**os.environ, "PRTBENCH_RESULTS": str(results)}
    if make_dry_run():  # `make -n reports` still runs this recipe (it names $(MAKE)): plan only
        print(f"[reports] would run at {sha} into {results}: "
              + " ".join(f"{make} {t} PROFILE={profile}" for t in targets), file=sys.stderr)
        return 0
    print(f"[reports] commit {sha}, profile {profile}, results store {results}, {cores} cores, "
          f"{len(targets)} target(s); per-target log {log}", file=sys.stderr, flush=True)
    failed = []
    for target in targets:
        before = load_1min()
        if before is not None and before > limit:
            _warn(f"1-min load {before:.2f} before {target} exceeds {limit:g} "
                  f"({limit / cores:g} x {cores} cores): its frame times may not be representative")
        started = datetime.now(timezone.utc).isoformat(timespec="seconds")
        clock = time.perf_counter()
        status = subprocess.run([make, "--no-print-directory", target, f"PROFILE={profile}"],
                                cwd=ROOT, env=env, check=False).returncode
        wall = time.perf_counter() - clock
        after = load_1min()
        busy = any(v is not None and v > limit for v in (before, after))
        if after is not None and after > limit:
            _warn(f"1-min load {after:.2f} after {target} exceeds {limit:g} "
                  f"({limit / cores:g} x {cores} cores): its frame times may not be representative")
        print(f"[reports] {target}: exit {status}, {wall:.0f} s, 1-min load "
              f"{_fmt_load(before)} -> {_fmt_load(after)} on {cores} cores",
              file=sys.stderr, flush=True)
        _append_log(log, {"target": target, "git_sha": sha, "profile": profile,
                          "results": str(results), "started_utc": started,
                          "wall_s": f"{wall:.1f}", "exit_status": status,
                          "load_before": _fmt_load(before), "load_after": _fmt_load(after),
                          "cores": cores, "busy": busy})
        if status != 0:
            failed.append(target)
        now = head_sha()
        if now != sha:
            raise GuardError(f"HEAD moved from {sha} to {now} during make reports (after "
                             f"{target}); rerun make reports at one commit")
        changes = tree_changes()
        if changes and not allow_dirty:
            raise GuardError(f"the tree changed during make reports (after {target}: "
                             f"{_summary(changes)}); rerun make reports on a clean tree")
    if failed:
        print(f"prtbench: {len(failed)} report target(s) failed: {', '.join(failed)}",
              file=sys.stderr)
        return 1
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="reports_guard.py", description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    check = sub.add_parser("check", help="refuse a dirty tree (exit 2)")
    run = sub.add_parser("run", help="run make targets from a clean tree, recording the load")
    for p in (check, run):
        p.add_argument("--allow-dirty", action="store_true",
                       help="run on a dirty tree (also ALLOW_DIRTY=1)")
    run.add_argument("targets", nargs="+", metavar="TARGET")
    run.add_argument("--profile", default="quick")
    run.add_argument("--make", default="make", help="the make program (default make)")
    run.add_argument("--results", default=None, type=Path,
                     help="results store (default $PRTBENCH_RESULTS, else "
                          "results/reports-<commit>.sqlite)")
    run.add_argument("--log", default=DEFAULT_LOG, type=Path,
                     help=f"per-target CSV, appended (default {DEFAULT_LOG})")
    run.add_argument("--start-at", default=None, metavar="TARGET",
                     help="skip the targets before TARGET (resume at the same commit)")
    args = parser.parse_args(argv)
    allow_dirty = args.allow_dirty or os.environ.get("ALLOW_DIRTY", "") == "1"
    try:
        if args.command == "check":
            sha = check_clean(allow_dirty=allow_dirty)
            state = "dirty tree (allowed)" if tree_changes() else "clean tree"
            print(f"[reports] {state} at {sha}", file=sys.stderr)
            return 0
        return run_targets(args.targets, profile=args.profile, make=args.make,
                           results=args.results, log=args.log, start_at=args.start_at,
                           allow_dirty=allow_dirty)
    except GuardError as exc:
        print(f"prtbench: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
