"""Wavelet transport throughput against raw embree, and relighting cost against k (issue #17).

    python benchmarks/bench_wavelet.py [--scene plants] [--points 2048] [--cubemap 32]
                                       [--threads 1] [--rounds 3]

1. Precompute: :func:`prtbench.wavelet.transport.compute_wavelet_transport` (rays, trace,
   Haar, truncation, sparse build) against a bare embreex ``OCCLUDED`` query over exactly the
   rays it traces (same origins, directions, chunking into ≤ 2²¹-ray calls), both on
   ``--threads`` precompute threads, best wall time of ``--rounds`` interleaved rounds. Target:
   ratio >= 0.8.
2. Relighting: :meth:`SparseTransport.relight` (the per-frame CPU product, plus the light's
   Haar transform and the k-term selection) against k = 32 … 256 and against the kept fraction
   of transport coefficients, median of 50 frames.

Not a test (timings differ between machines and this one is shared): it prints, asserts nothing.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def _best(fn, rounds: int) -> float:
    times = []
    for _ in range(rounds):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def _rays(tracer, points, normals, n):
    """The (origins, directions) compute_wavelet_transport traces, in its order."""
    from prtbench.raytrace import offset_origins
    from prtbench.wavelet.cubemap import subsample_pattern
    from prtbench.wavelet.transport import cosines

    dirs, _ = subsample_pattern(n, 1)
    d32 = dirs.reshape(-1, 3).astype(np.float32)
    origins = offset_origins(points, normals, diagonal=tracer.diagonal).astype(np.float32)
    pi, ri = np.nonzero(cosines(normals.astype(np.float32), np.ascontiguousarray(d32.T)) > 0)
    return np.ascontiguousarray(origins[pi]), np.ascontiguousarray(d32[ri])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--scene", default="plants")
    parser.add_argument("--points", type=int, default=2048)
    parser.add_argument("--cubemap", type=int, default=32)
    parser.add_argument("--threads", default="1")
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    os.environ["PRTBENCH_THREADS"] = args.threads

    from prtbench.lights import get_light
    from prtbench.parallel import map_chunks, parallel_chunks
    from prtbench.raytrace import CHUNK_RAYS, Tracer
    from prtbench.scene import get_scene
    from prtbench.wavelet import haar
    from prtbench.wavelet.cubemap import light_cubemap
    from prtbench.wavelet.selection import select_terms
    from prtbench.wavelet.transport import compute_wavelet_transport

    scene = get_scene(args.scene)
    positions, normals, _, _ = scene.merged()
    pick = np.linspace(0, len(positions) - 1, min(args.points, len(positions))).astype(int)
    points, nrm = positions[pick].astype(np.float64), normals[pick].astype(np.float64)
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    tracer = Tracer.from_scene(scene)
    n = args.cubemap
    origins, dirs = _rays(tracer, points, nrm, n)
    chunks = parallel_chunks(len(origins), CHUNK_RAYS)

    def raw():
        def trace(sl):
            return tracer._scene.run(origins[sl], dirs[sl], query="OCCLUDED")
        for _ in map_chunks(trace, chunks):
            pass

    def wavelet():
        return compute_wavelet_transport(scene, points, nrm, n=n, keep=0.25, storage="float16",
                                         progress=False, tracer=tracer)

    raw(), wavelet()  # warm-up
    t_raw, t_wav = [], []
    for _ in range(args.rounds):
        t_raw.append(_best(raw, 1))
        t_wav.append(_best(wavelet, 1))
    rays = len(origins)
    transport, stats = wavelet()
    assert stats["rays"] == rays, (stats["rays"], rays)
    print(f"{scene.name}: {len(points)} points × 6·{n}² texels, {rays} rays traced "
          f"(of {stats['candidate_rays']}), {args.threads} thread(s), load "
          f"{os.getloadavg()[0]:.2f}")
    print(f"  raw embree      {rays / min(t_raw) / 1e6:6.2f} Mrays/s ({min(t_raw):.2f} s)")
    print(f"  wavelet precomp {rays / min(t_wav) / 1e6:6.2f} Mrays/s ({min(t_wav):.2f} s)  "
          f"ratio {min(t_raw) / min(t_wav):.2f} (target >= 0.8)")

    light = get_light("sun")
    cube = np.moveaxis(light_cubemap(light, n), -1, 0)
    support = haar.support_solid_angles(n).reshape(-1)
    print(f"  relight (light Haar + area selection + sparse product), {len(points)} points, "
          f"median of 50 frames:")
    for keep in (0.05, 0.25, 1.0):
        t, _ = compute_wavelet_transport(scene, points, nrm, n=n, keep=keep, storage="float16",
                                         progress=False, tracer=tracer)
        row = []
        for k in (32, 64, 128, 256):
            def frame():
                coeffs = haar.forward(cube).reshape(3, -1).T
                terms = select_terms(coeffs, k, rule="area", support=support)
                return t.relight(coeffs, terms)
            frame()
            samples = []
            for _ in range(50):
                start = time.perf_counter()
                frame()
                samples.append((time.perf_counter() - start) * 1e3)
            row.append(f"k={k}: {statistics.median(samples):6.2f} ms")
        print(f"    keep={keep:<5g} ({t.nbytes / 2**20:7.2f} MiB) " + "  ".join(row))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
