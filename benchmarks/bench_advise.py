"""Wall time of ``advise``'s screening cells on 2 Dask workers versus 1 (issue #49; not a test).

    python benchmarks/bench_advise.py [--scene plants] [--light sky] [--workers 1,2] [--repeat 2]

The advisor runs its candidates through the one submit path (a :class:`JobPool` on a Dask
executor; each method's chain of candidates is sent as soon as a worker is free). This times
the search at the smoke profile (the screening) with the ``ops`` cost, for one worker (which
gets every core for its tracing and rasterising: ``1``), one worker held to one thread
(``1x1``), and two workers of one thread each (``2``). Each run starts from the same state: a
fresh artifact cache holding only the path references of the candidates' views (rendered
once beforehand, so neither run pays for them) and no results store; the analysis is given
(computed once), so only the evaluation differs. The verification run is serial in both.
Prints each run's screening seconds, cells, and the ratio 1 / 2 (median over ``--repeat``
pairs, run alternately), with the machine's load average.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

TARGET = "psnr_masked>=24"  # the demo's target
METHODS = ("vertex", "texture-tpfl", "irradiance-volume", "vertex-tpfl", "wavelet-vertex",
           "factored-brdf")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--scene", default="plants")
    parser.add_argument("--light", default="sky")
    parser.add_argument("--workers", default="1,1x1,2",
                        help="runs: W (workers, default threads) or WxT (T threads each)")
    parser.add_argument("--repeat", type=int, default=2)
    args = parser.parse_args()
    os.environ.setdefault("DRJIT_LIBLLVM_PATH", "/usr/lib/x86_64-linux-gnu/libLLVM-19.so")

    from prtbench.scene.registry import get_scene
    from prtbench.tradeoff import advise as advise_mod
    from prtbench.tradeoff.analyze import analyze_scene
    from prtbench.transport.lights import get_light

    work = Path(tempfile.mkdtemp(prefix="prtbench-bench-advise-"))
    warm = work / "warm-cache"
    os.environ["PRTBENCH_CACHE"] = str(warm)
    scene = get_scene(args.scene)
    analysis = analyze_scene(scene, get_light(args.light), light_changes="none",
                             render_bounces=False, progress=False)
    counts = args.workers.split(",")
    seconds: dict[str, list[float]] = {w: [] for w in counts}
    cells: dict[str, int] = {}
    try:
        # Warm-up: the references of every candidate (shared by all runs), untimed.
        _advise(advise_mod, args, analysis, workers="0", cache=warm, timed=None)
        references = warm / "references"
        for round_ in range(args.repeat):
            for workers in counts:
                cache = work / f"cache-{round_}-{workers}"
                shutil.copytree(references, cache / "references")
                timed: list[tuple[float, int]] = []
                _advise(advise_mod, args, analysis, workers=workers, cache=cache, timed=timed)
                seconds[workers].append(sum(t for t, _ in timed))
                cells[workers] = sum(n for _, n in timed)
                shutil.rmtree(cache)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    load = os.getloadavg()[0]
    for workers in counts:
        print(f"{workers} worker(s): screening {statistics.median(seconds[workers]):.1f} s "
              f"(runs {', '.join(f'{s:.1f}' for s in seconds[workers])}) for "
              f"{cells[workers]} cells")
    last = counts[-1]
    for first in counts[:-1]:
        ratios = [a / b for a, b in zip(seconds[first], seconds[last])]
        print(f"ratio {first} / {last}: median {statistics.median(ratios):.2f} "
              f"(pairs {', '.join(f'{r:.2f}' for r in ratios)})")
    print(f"1-min load at the end {load:.2f}")
    return 0


def _advise(advise_mod, args, analysis, *, workers: str, cache: Path, timed: list | None) -> None:
    """One advise with ``workers`` (``W`` or ``WxT``); the smoke searches' time into ``timed``."""
    os.environ["PRTBENCH_CACHE"] = str(cache)
    count, _, threads = workers.partition("x")
    real_search, real_make = advise_mod.search, advise_mod.make_executor

    def search(*a, **k):
        start = time.perf_counter()
        out = real_search(*a, **k)
        if timed is not None and k.get("profile") == "smoke":
            timed.append((time.perf_counter() - start, len(out)))
        return out

    def make_executor(*, workers=None):  # the threads per worker of a WxT run
        return real_make(workers=workers, threads=int(threads) if threads and workers else None)

    advise_mod.search, advise_mod.make_executor = search, make_executor
    try:
        advise_mod.advise(args.scene, args.light, target=TARGET, cost="ops", profile="smoke",
                          methods=list(METHODS), analysis=analysis, workers=int(count),
                          verify=lambda batch, *, profile: advise_mod.evaluate_jobs(
                              batch, profile=profile, store=False))
    finally:
        advise_mod.search, advise_mod.make_executor = real_search, real_make


if __name__ == "__main__":
    sys.exit(main())
