"""Wavelet transport throughput against raw embree, and relighting cost against k (issue #17).

    python benchmarks/bench_wavelet.py [--scene plants] [--points 2048] [--cubemap 32]
                                       [--threads 1,CORES] [--rounds 3] [--no-relight]

1. Precompute: :func:`prtbench.transport.wavelet.transport.compute_wavelet_transport` (rays, trace,
   Haar, truncation, sparse build) against a bare embreex ``OCCLUDED`` query over exactly the
   rays it traces (same origins, directions, chunking into ≤ 2²¹-ray calls), both on the same
   number of precompute threads, for each of ``--threads`` (default: 1 and all usable cores),
   best wall time of ``--rounds`` interleaved rounds. Target: ratio >= 0.8. It prints one
   ``TARGET`` line per thread count, the load average (other processes lower every ratio;
   the 1-thread ratio is the least sensitive) and whether every thread count gave the same
   bits.
2. Relighting: :meth:`SparseTransport.relight` (the per-frame CPU product, plus the light's
   Haar transform and the k-term selection) against k = 32 … 256 and against the kept fraction
   of transport coefficients, median of 50 frames.

Not a test (timings differ between machines and this one is shared): it prints, asserts nothing
about timing.
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
    from prtbench.transport.raytrace import offset_origins
    from prtbench.transport.wavelet.cubemap import subsample_pattern
    from prtbench.transport.wavelet.transport import cosines

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
    parser.add_argument("--threads", default=None,
                        help="comma-separated thread counts (default: 1 and all usable cores)")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--no-relight", action="store_true", help="skip part 2")
    args = parser.parse_args()

    from prtbench.scene.registry import get_scene
    from prtbench.transport.lights import get_light
    from prtbench.transport.parallel import available_cores, map_chunks, parallel_chunks
    from prtbench.transport.raytrace import CHUNK_RAYS, Tracer
    from prtbench.transport.wavelet import haar
    from prtbench.transport.wavelet.cubemap import light_cubemap
    from prtbench.transport.wavelet.selection import select_terms
    from prtbench.transport.wavelet.transport import compute_wavelet_transport

    counts = sorted({int(t) for t in args.threads.split(",")} if args.threads
                    else {1, available_cores()})
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

    def on_threads(fn, threads):
        def call():
            os.environ["PRTBENCH_THREADS"] = str(threads)
            return fn()
        return call

    calls = {(name, t): on_threads(fn, t) for t in counts
             for name, fn in (("raw", raw), ("wavelet", wavelet))}
    bits, stats = {}, {}
    for (name, t), fn in calls.items():  # warm-up, and each thread count's result
        result = fn()
        if name == "wavelet":
            transport, stats[t] = result
            bits[t] = [a.tobytes() for a in transport.arrays().values()]
    load_before = os.getloadavg()[0]
    times = {key: [] for key in calls}
    for _ in range(args.rounds):  # interleaved: every variant sees the same load fluctuations
        for key, fn in calls.items():
            times[key].append(_best(fn, 1))
    load_after = os.getloadavg()[0]
    rays = len(origins)
    assert all(s["rays"] == rays for s in stats.values()), (stats, rays)
    print(f"{scene.name}: {len(points)} points × 6·{n}² texels, {rays} rays traced "
          f"(of {stats[counts[0]]['candidate_rays']}), best of {args.rounds} interleaved "
          f"rounds, load average {load_before:.2f} -> {load_after:.2f}")
    for t in counts:
        t_raw, t_wav = min(times["raw", t]), min(times["wavelet", t])
        ratio = t_raw / t_wav
        print(f"  {t} thread(s): raw embree {rays / t_raw / 1e6:6.2f} Mrays/s ({t_raw:.2f} s), "
              f"wavelet precompute {rays / t_wav / 1e6:6.2f} Mrays/s ({t_wav:.2f} s)")
        print(f"  TARGET wavelet transport rays/s >= 0.8 x raw embree, {t} thread(s): ratio "
              f"{ratio:.3f} -> {'met' if ratio >= 0.8 else 'NOT met'}")
    same = all(bits[t] == bits[counts[0]] for t in counts)
    print(f"  results bit-identical across {', '.join(map(str, counts))} thread(s): "
          f"{'yes' if same else 'NO'}")
    if args.no_relight:
        return 0 if same else 1
    os.environ["PRTBENCH_THREADS"] = str(counts[-1])

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
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())
