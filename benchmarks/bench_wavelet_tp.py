"""Ng 2004 triple products: the Haar tree algorithm against the per-texel product (issue #17).

    python benchmarks/bench_wavelet_tp.py [--points 1024] [--cubemaps 8 16 32] [--frames 5]

Signals are real ones from ``sphere-over-plane`` (glossy): per vertex the Haar visibility
(:func:`~prtbench.transport.wavelet.transport.compute_wavelet_transport` with ``cosine=False``, truncated
to the ``keep`` fraction), the glossy Phong factor for the vertex's own mirror direction of the
first trajectory view (:func:`prtbench.transport.wavelet.brdf.project`, ``brdf_keep`` terms) and the
``sky`` light cut to its k largest (area-weighted) coefficients. For each cubemap N and each
sparsity (k, keep, brdf_keep) it times, median of ``--frames`` runs, on one thread:

* ``tree``: :func:`prtbench.transport.wavelet.triple.triple_product` from the sparse coefficients
  (including the light's parent sums, as a frame does);
* ``texel``: the product it replaces, Σ_t L_t V_t ρ̃_t over all 6N² texels per vertex from
  texel-domain arrays already in memory (the cheapest brute force: the inverse transforms are
  not timed);
* ``texel+inv``: the same from the sparse Haar coefficients (densify and inverse Haar, timed),
  the brute force a Haar store would really pay;

and prints the ratios texel/tree and (texel+inv)/tree (> 1: the tree algorithm is faster),
with the stored non-zeros per vertex that the tree algorithm's cost follows.

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

#: (light terms k, visibility kept per vertex (count, or 1.0: all), BRDF terms kept); counts
#: clip to 6N², so the tree algorithm sees the same sparsity at every N.
SPARSITIES = ((32, 32, 32), (128, 128, 64), (512, 512, 256), (None, 1.0, None))


def _median(fn, frames: int) -> float:
    times = []
    for _ in range(frames):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--points", type=int, default=1024)
    parser.add_argument("--cubemaps", type=int, nargs="+", default=[8, 16, 32])
    parser.add_argument("--frames", type=int, default=5)
    args = parser.parse_args()
    os.environ.setdefault("OMP_NUM_THREADS", "1")

    import methods.wavelet.tp as wtp  # the renderer's column → row conversion
    from prtbench.scene.registry import get_scene
    from prtbench.transport.lights import get_light
    from prtbench.transport.wavelet import brdf, haar, selection
    from prtbench.transport.wavelet.cubemap import light_cubemap
    from prtbench.transport.wavelet.transport import compute_wavelet_transport
    from prtbench.transport.wavelet.triple import (
        SparseRows,
        brute_force,
        mean_pyramid,
        triple_product,
    )

    scene = get_scene("sphere-over-plane", variant="glossy", plane_subdivisions=16)
    positions, normals, _, _ = scene.merged()
    normals = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    pick = np.random.default_rng(0).choice(len(positions), min(args.points, len(positions)),
                                           replace=False)
    pick.sort()
    positions, normals = positions[pick], normals[pick]
    eye = np.asarray(scene.trajectory.views[0].eye)
    to_eye = eye - positions
    to_eye /= np.linalg.norm(to_eye, axis=1, keepdims=True)
    reflections = brdf.reflect(to_eye, normals)
    light = get_light("sky")
    print(f"sphere-over-plane glossy, {len(pick)} vertices, sky, s = 128, one thread; "
          f"median of {args.frames} runs")
    print(f"{'N':>3} {'k':>6} {'keep':>6} {'brdf':>5} {'|V|/pt':>7} {'|G|/pt':>7} "
          f"{'tree ms':>9} {'texel ms':>9} {'+inv ms':>9} {'texel/tree':>10} {'+inv/tree':>10}")
    for n in args.cubemaps:
        m = 6 * n * n
        coeffs = haar.forward(np.moveaxis(light_cubemap(light, n), -1, 0)).reshape(3, m).T
        support = haar.support_solid_angles(n).reshape(m)
        for k, keep, brdf_keep in SPARSITIES:
            k, brdf_keep = min(k or m, m), min(brdf_keep or m, m)
            keep = keep if keep <= 1.0 else min(keep, m)
            transport, _ = compute_wavelet_transport(scene, positions, normals, n=n, keep=keep,
                                                     storage="float32", cosine=False,
                                                     progress=False)
            v = wtp._rows_from_transport(transport)
            p, c, val = brdf.project(normals, n=n, keep=brdf_keep, reflections=reflections,
                                     shininess=128.0)
            g = SparseRows.from_entries(p, c, val, n_points=len(pick), n_coeffs=m)
            terms = selection.select_terms(coeffs, k, rule="area", support=support)
            lit = np.zeros_like(coeffs)
            lit[terms] = coeffs[terms]

            def tree():
                mean = mean_pyramid(lit.T.reshape(3, 6, n, n)).reshape(3, m).T
                return triple_product(lit, v, g, light_mean=mean)

            texel_l = haar.inverse(lit.T.reshape(3, 6, n, n)).reshape(3, m)
            texel_v = haar.inverse(v.dense().reshape(-1, 6, n, n)).reshape(-1, m)
            texel_g = haar.inverse(g.dense().reshape(-1, 6, n, n)).reshape(-1, m)

            def texel():
                return (texel_v * texel_g) @ texel_l.T

            def texel_inverse():
                return brute_force(lit, v.dense(), g.dense())

            err = np.abs(tree() - texel()).max() / max(np.abs(texel()).max(), 1e-30)
            t_tree, t_texel = _median(tree, args.frames), _median(texel, args.frames)
            t_inv = _median(texel_inverse, args.frames)
            print(f"{n:>3} {k:>6} {keep:>6g} {brdf_keep:>5} {v.nnz / len(pick):>7.0f} "
                  f"{g.nnz / len(pick):>7.0f} {t_tree * 1e3:>9.2f} {t_texel * 1e3:>9.2f} "
                  f"{t_inv * 1e3:>9.2f} {t_texel / t_tree:>10.2f} {t_inv / t_tree:>10.2f}"
                  f"   (max rel. diff {err:.1e})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
