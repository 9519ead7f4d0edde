"""CPCA fitting time and memory against N and K, and frame time of compressed versus
uncompressed ``sloan-matrix`` in one run (issue #18 "Performance"; not a test).

    python benchmarks/bench_cpca.py [--signals 5000,20000,80000] [--clusters 16,64]
        [--dimension 256] [--pca-vectors 4] [--iterations 3] [--frames]

Fit: synthetic signals near K_true affine subspaces (what transfer looks like locally), float32
as artifacts store them. Printed per (N, K): wall time, iterations, seconds per iteration and
the fit's peak numpy allocation beyond the input (tracemalloc), as a multiple of the input:
the reassignment streams signals in chunks and clusters are fitted from their own rows, so the
extra memory stays O(cluster size · d + scratch), not O(N · K · n′); k-means initialisation is
fitted on a subsample of at most 32768 signals. ``--frames``: sloan-matrix on ``plants``
glossy (smoke profile), uncompressed and CPCA K=64 n′=4, frame time median over 20 frames.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import tracemalloc
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def _signals(n: int, d: int, *, clusters: int = 32, rank: int = 6, seed: int = 0):
    import numpy as np

    rng = np.random.default_rng(seed)
    centres = rng.normal(scale=2.0, size=(clusters, d))
    frames = rng.normal(size=(clusters, rank, d)) / np.sqrt(d)
    ids = rng.integers(0, clusters, n)
    x = np.empty((n, d), np.float32)
    # In chunks: frames[ids] for all of a dragon-sized N (871k × rank × d float64) would need
    # tens of GB for a test input.
    for lo in range(0, n, 16384):
        part = ids[lo:lo + 16384]
        x[lo:lo + len(part)] = (centres[part] + np.einsum(
            "nr,nrd->nd", rng.normal(size=(len(part), rank)), frames[part])
            + 0.01 * rng.normal(size=(len(part), d)))
    return x


def bench_fit(signals, clusters, dimension, pca_vectors, iterations) -> None:
    from prtbench.transport.compress import fit_cpca

    print("N, K, n', d, wall s, iterations, s/iteration, peak extra / input")
    for n in signals:
        x = _signals(n, dimension)
        for k in clusters:
            tracemalloc.start()
            start = time.perf_counter()
            model = fit_cpca(x, clusters=k, pca_vectors=pca_vectors, max_iterations=iterations,
                             tolerance=0.0)
            wall = time.perf_counter() - start
            _, peak = tracemalloc.get_traced_memory()
            tracemalloc.stop()
            its = len(model.history) - 1
            print(f"{n}, {k}, {pca_vectors}, {dimension}, {wall:.2f}, {its}, "
                  f"{wall / max(1, its + 1):.2f}, {peak / x.nbytes:.2f}", flush=True)


def bench_frames() -> None:
    import methods.vertex.glossy  # noqa: F401
    from prtbench.api.method import METHODS, load_or_precompute
    from prtbench.scene.registry import get_scene
    from prtbench.transport.lights import get_light

    scene = get_scene("plants", variant="glossy", ground_subdivisions=32)
    cls = METHODS.get("sloan-matrix")
    for form in ({}, {"compress": "cpca", "clusters": 64, "pca_vectors": 4}):
        config = cls.make_config(form, profile="smoke")
        artifact = load_or_precompute(cls, scene, config, progress=False)
        renderer = cls.renderer(scene, artifact, config, width=320, height=240)
        try:
            times = renderer.frame_time(scene.trajectory.views[0], get_light("sun"), warmup=3,
                                        frames=20)
            print(f"sloan-matrix {form or 'uncompressed'}: {times.median_ms:.2f} ms median "
                  f"({times.source}, {times.renderer}), resident {renderer.memory_bytes()} B",
                  flush=True)
        finally:
            renderer.release()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--signals", default="5000,20000,80000")
    parser.add_argument("--clusters", default="16,64")
    parser.add_argument("--dimension", type=int, default=256)
    parser.add_argument("--pca-vectors", type=int, default=4)
    parser.add_argument("--iterations", type=int, default=3)
    parser.add_argument("--frames", action="store_true")
    args = parser.parse_args()
    os.environ.setdefault("DRJIT_LIBLLVM_PATH", "/usr/lib/x86_64-linux-gnu/libLLVM-19.so")
    bench_fit([int(v) for v in args.signals.split(",")], [int(v) for v in args.clusters.split(",")],
              args.dimension, args.pca_vectors, args.iterations)
    if args.frames:
        bench_frames()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
