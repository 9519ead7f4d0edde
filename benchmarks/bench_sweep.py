"""Wall time of the 24-cell quick sweep on 2 Dask workers versus 1 (issue #13; not a test).

    python benchmarks/bench_sweep.py [--sweep sweeps/plants-quick24.toml] [--workers 1,2]
    python benchmarks/bench_sweep.py --workers 1x2,1x1,2x1

A run ``W`` is W workers with the default threads (each worker's share of the cores: one
worker alone gets them all); ``WxT`` holds every worker to T threads (``--worker-threads``).
``1x1`` against ``2x1`` is Dask's own scaling with one thread per worker (the issue's
configuration); ``1`` against ``2`` is what a user gains over one worker that already uses
every core for its tracing and rasterising.

Both runs do the same work from the same start: each gets a fresh artifact cache holding only
the path-traced references (rendered once beforehand, shared, so the concurrent first cells do
not race to render the same reference) and a fresh results store. The times include starting
the LocalCluster; an untimed serial warm-up of one cell per method comes first (caches outside
the artifact cache would otherwise favour the later runs). Prints both times, the ratio, the
workers' CPU time (how many cores each run kept busy: llvmpipe and the tracer are
multi-threaded, so one worker already uses more than one core at times) and the load average
(other processes on the machine distort it: run it on a quiet machine).
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sweep", default=str(ROOT / "sweeps" / "plants-quick24.toml"))
    parser.add_argument("--workers", default="1,2",
                        help="runs to time, comma-separated: W (workers) or WxT (T threads each)")
    parser.add_argument("--profile", default=None)
    args = parser.parse_args()
    os.environ.setdefault("DRJIT_LIBLLVM_PATH", "/usr/lib/x86_64-linux-gnu/libLLVM-19.so")

    from prtbench.tradeoff.grid import load_sweep, prepare_cell
    from prtbench.tradeoff.sweep import run_cells

    work = Path(tempfile.mkdtemp(prefix="bench-sweep-"))
    try:
        warm = work / "warm"
        os.environ["PRTBENCH_CACHE"] = str(warm)
        sweep = load_sweep(args.sweep, profile=args.profile)
        cells = list(sweep.cells)
        print(f"{args.sweep}: {len(cells)} cells, profile {sweep.profile}, "
              f"{os.cpu_count()} cores", flush=True)
        start = time.perf_counter()
        _render_references(cells, sweep.profile, prepare_cell)
        print(f"references (shared by both runs): {time.perf_counter() - start:.1f} s", flush=True)
        start = time.perf_counter()
        _warm_up(cells, sweep.profile, work, warm / "references", run_cells)
        print(f"warm-up (one cell per method, serial, untimed): "
              f"{time.perf_counter() - start:.1f} s", flush=True)
        times = {}
        for spec in args.workers.split(","):
            n, threads = _run_spec(spec)
            name = f"{n}x{threads}" if threads else str(n)
            cache = work / f"cache-{name}"
            shutil.copytree(warm / "references", cache / "references")
            os.environ["PRTBENCH_CACHE"] = str(cache)
            load = os.getloadavg()
            cpu0 = _children_cpu()
            start = time.perf_counter()
            outcome = run_cells(cells, profile=sweep.profile,
                                results_path=work / f"r{name}.sqlite", workers=n,
                                worker_threads=threads, progress=False)
            times[(n, threads)] = time.perf_counter() - start
            cpu = _children_cpu() - cpu0  # the workers, reaped when the cluster closed
            failed = outcome.count("failed")
            busy = sum(c.seconds for c in outcome.results)
            wall = times[(n, threads)]
            print(f"{n} worker(s), {_threads_label(threads)}: {wall:.1f} s wall ({outcome.count('done')} done, "
                  f"{failed} failed; {busy:.1f} s in cells; worker CPU {cpu:.1f} s = "
                  f"{cpu / wall:.2f} cores busy); load average before "
                  f"{load[0]:.2f}, after {os.getloadavg()[0]:.2f}", flush=True)
        for (n, threads), t in times.items():
            for (base_n, base_threads), base in times.items():
                if base_n == 1 and n > 1 and (threads is None or base_threads in (None, threads)):
                    print(f"speed-up {n} workers vs 1 ({_threads_label(threads)} vs "
                          f"{_threads_label(base_threads)}): {base / t:.2f}x "
                          f"(target >= 1.7x on 2 cores)")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return 0


def _warm_up(cells, profile: str, work: Path, references: Path, run_cells) -> None:
    """One cell per method, serially, into a throwaway cache and store.

    Caches outside ``PRTBENCH_CACHE`` (Dr.Jit's compiled kernels on disk, the OS's file cache
    of the libraries) otherwise favour whichever run comes later: measured without it, the
    same 1-worker run took 95.4 s first and 77.2 s third.
    """
    firsts = list({cell.method: cell for cell in cells}.values())
    cache = work / "cache-warm-up"
    shutil.copytree(references, cache / "references")
    os.environ["PRTBENCH_CACHE"] = str(cache)
    run_cells(firsts, profile=profile, results_path=work / "warm-up.sqlite", workers=0,
              progress=False)
    shutil.rmtree(cache, ignore_errors=True)


def _run_spec(spec: str) -> tuple[int, int | None]:
    """``"W"`` → (W, None); ``"WxT"`` → (W, T)."""
    workers, _, threads = spec.strip().partition("x")
    return int(workers), int(threads) if threads else None


def _threads_label(threads: int | None) -> str:
    return f"{threads} thread(s) each" if threads else "default threads"


def _children_cpu() -> float:
    import resource

    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _render_references(cells, profile: str, prepare_cell) -> None:
    """The path references of every distinct (scene, light, views) of ``cells``, into the cache."""
    from prtbench.render.reference import render_references

    seen = set()
    for cell in cells:
        prepared = prepare_cell(cell, profile=profile, reuse=True)
        bounces = int(getattr(prepared.config, "bounces", 0))
        key = (prepared.scene.content_hash(), prepared.light.name, len(prepared.scene.trajectory),
               bounces)
        if key in seen or cell.reference != "path":
            continue
        seen.add(key)
        render_references(prepared.scene, prepared.light, prepared.scene.trajectory.views,
                          width=prepared.width, height=prepared.height,
                          spp=prepared.profile.reference_spp, bounces=bounces)


if __name__ == "__main__":
    sys.exit(main())
