"""Bit-identity check of the wavelet transport precompute across code changes.

    python benchmarks/wavelet_bits.py save REF.npz      # before a change
    python benchmarks/wavelet_bits.py compare REF.npz   # after it: exit 1 unless every array
                                                        # is np.array_equal to the reference

Computes :func:`prtbench.transport.wavelet.transport.compute_wavelet_transport` on ``plants`` and
``sphere-over-plane`` over a spread of options (the benchmark's case, float32/int8 storage,
texel subsamples, the unshadowed and visibility-only transports, lobes), and stores every array
of every transport. A speedup of the precompute must leave all of them unchanged.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

#: (case name, scene, points, compute_wavelet_transport options).
CASES = (
    ("plants-bench", "plants", 512, dict(n=32, keep=0.25, storage="float16")),
    ("plants-f32-all", "plants", 256, dict(n=16, keep=1.0, storage="float32")),
    ("plants-int8-k40", "plants", 256, dict(n=16, keep=40, storage="int8")),
    ("plants-ss2", "plants", 128, dict(n=8, keep=0.1, texel_samples=2, storage="float16")),
    ("plants-vis-only", "plants", 128, dict(n=16, keep=0.25, cosine=False)),
    ("plants-unshadowed", "plants", 128, dict(n=16, keep=0.25, visibility=False)),
    ("sphere-bench", "sphere-over-plane", 512, dict(n=32, keep=0.25, storage="float16")),
    ("sphere-f32-k7", "sphere-over-plane", 256, dict(n=16, keep=7, storage="float32")),
    ("sphere-lobes", "sphere-over-plane", 128, dict(n=8, keep=0.5, lobes=True)),
)


def _lobes(sl: slice, dirs_t: np.ndarray) -> np.ndarray:
    """Two deterministic per-ray factors (c, 2, R) for the ``lobes`` option."""
    c = sl.stop - sl.start
    up = np.maximum(dirs_t[2], 0).astype(np.float32)
    side = (0.5 + 0.5 * dirs_t[0]).astype(np.float32)
    per_point = (1.0 + np.arange(sl.start, sl.stop, dtype=np.float32) % 3)[:, None, None]
    return np.stack([up, side])[None] * per_point * np.ones((c, 1, 1), np.float32)


def transports() -> dict[str, np.ndarray]:
    """Every array of every case's transport, as ``{"case/array": array}``."""
    from prtbench.scene.registry import get_scene
    from prtbench.transport.raytrace import Tracer
    from prtbench.transport.wavelet.transport import compute_wavelet_transport

    out = {}
    scenes = {}
    for name, scene_name, n_points, options in CASES:
        if scene_name not in scenes:
            scene = get_scene(scene_name)
            scenes[scene_name] = (scene, Tracer.from_scene(scene), *scene.merged()[:2])
        scene, tracer, positions, normals = scenes[scene_name]
        pick = np.linspace(0, len(positions) - 1, min(n_points, len(positions))).astype(int)
        options = dict(options)
        if options.pop("lobes", False):
            options.update(lobes=_lobes, n_lobes=2)
        transport, stats = compute_wavelet_transport(
            scene, positions[pick], normals[pick], progress=False, tracer=tracer, **options)
        for key, array in transport.arrays().items():
            out[f"{name}/{key}"] = np.asarray(array)
        out[f"{name}/rays"] = np.array(stats["rays"])
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("action", choices=("save", "compare"))
    parser.add_argument("reference", type=Path)
    args = parser.parse_args()
    arrays = transports()
    if args.action == "save":
        np.savez(args.reference, **arrays)
        print(f"saved {len(arrays)} arrays to {args.reference}")
        return 0
    with np.load(args.reference) as ref:
        names = sorted(set(ref.files) | set(arrays))
        bad = [k for k in names if k not in ref.files or k not in arrays
               or ref[k].dtype != arrays[k].dtype or not np.array_equal(ref[k], arrays[k])]
    print(f"{len(names) - len(bad)}/{len(names)} arrays bit-identical"
          + (f"; differ: {', '.join(bad)}" if bad else ""))
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
