"""Diagnose neural-wavelet's held-out-light PSNR on the must-hold's reduced case (issue #19).

Usage::

    PYTHONPATH=. python scripts/nw_holdout_experiment.py '{"steps": 600}' [variants] [--no-sh]
        [--data-only] [--scene=sphere-over-plane]

The first argument is a JSON dict of overrides on the test's ``COMPARISON`` config;
``variants`` is a comma list (default ``hashgrid,vertex``). Prints, on the test's scene, views,
size and indirect reference (the test's ``HOLDOUT_REFERENCE_SPP`` samples; ``NW_EVAL_SPP``
overrides): the black image and the SH baseline (sloan-matrix, bounces 1 minus 0, the test's
bands) on the held-out lights, then per variant the indirect masked PSNR on

* ``heldout``: the held-out lights (the must-hold's number),
* ``heldout_all``: the same with every wavelet term (k = 6N²) instead of ``light_terms``,
* ``trainlight``: training lights at rotation 0 (``train_lights[:2]``) on the same
  held-out trajectory views (separates light generalisation from view generalisation),
* ``trainfit``: PSNR of the model's prediction on its own training rows (linear, peak = the
  largest target), with the render-time k-term selection; ``trainfit_disp`` the same on
  display values (the metric's space); ``*_black`` the same for a zero prediction,

and the training loss first -> last.

The scene is the test's (``must_hold_scene``: reduced glossy four-animals, 3-band SH baseline,
the most llvmpipe's 128 MiB storage block holds on its ~85k vertices). ``--scene=
sphere-over-plane`` runs the earlier reduced case instead: a glossy sphere (24 segments) over
a glossy plane (8×8), 3 views, 5-band SH baseline.

``--data-only`` renders (and caches) the training images of the first variant and stops: the
Mitsuba renders also honour ``PRTBENCH_THREADS`` (a 4096-image build started under
``PRTBENCH_THREADS=1`` ran on one core), so build a large data set first with every core (on
the 2-core Xeon: four-animals 512 images 5.6 min, 2048 images 27.5 min; the sphere over plane
2048 images 7.3-8.3 min; on the 2-core AMD EPYC four-animals 2048 images took 70 min),
then train its variants side by side on the cached data.

Two runs at once on a 2-core machine: ``PRTBENCH_THREADS=1`` for each. Measured here (2-core
Xeon, sphere over plane, the earlier 2000-step ``COMPARISON``): about 13.8k training pixels/s
per run that way, against 3.7k per run with two threads each, so two seeds took ~4 minutes
where one took ~11. ``COMPARISON`` is now the 2048-image, 16000-step config: on four-animals
(2-core AMD EPYC, seed 1) its hash-grid and vertex variants side by side took 52 min each at
~5.3k pixels/s; ``'{"random_lights": 0, "train_views": 64, "lights_per_view": 2, "steps":
2000}'`` gives back the earlier 128-image one.
"""

from __future__ import annotations

import json
import sys
import time

import numpy as np

sys.path.insert(0, "tests/methods")

import os  # noqa: E402

from test_neural_wavelet import (  # noqa: E402
    COMPARISON,
    HOLDOUT_REFERENCE_SPP,
    MUST_HOLD_SH_BANDS,
    must_hold_scene,
)

import methods.neural_wavelet.method  # noqa: E402,F401
import prtbench  # noqa: E402
from prtbench.api.method import METHODS, load_or_precompute  # noqa: E402
from prtbench.scene.registry import get_scene  # noqa: E402
from prtbench.transport.lights import get_light# noqa: E402
from reproductions.nw_evaluate import indirect_metrics, sh_baseline  # noqa: E402

#: The test's evaluation size and reference samples (NW_EVAL_SPP overrides the latter).
W, H, SPP = 64, 48, int(os.environ.get("NW_EVAL_SPP", HOLDOUT_REFERENCE_SPP))


def psnr_over(renderer, scene, lights) -> float:
    return float(np.mean([m["psnr_masked"] for light in lights
                          for m in indirect_metrics(renderer, scene, light,
                                                    scene.trajectory.views, width=W, height=H,
                                                    spp=SPP)]))


def train_fit(artifact, config) -> float:
    """PSNR (peak = max target) of the trained model on its training rows, render-time k."""
    import torch

    from methods.neural_wavelet.data import build_dataset
    from methods.neural_wavelet.model import NeuralWaveletModel
    from methods.neural_wavelet.train import _tensors
    from prtbench.transport.wavelet.selection import select_terms

    scene = _scene()
    data = build_dataset(scene, config, progress=False)
    model = NeuralWaveletModel.from_arrays(artifact.arrays)
    inputs = _tensors(data, "cpu")
    from prtbench.io import imageio

    err, peak, count = 0.0, float(np.max(data["target"])), 0
    derr, dzero = 0.0, 0.0
    zero = float(np.mean(data["target"].astype(np.float64) ** 2))
    with torch.no_grad():
        for l in range(len(data["coeffs"])):
            rows = np.flatnonzero(data["light"] == l)
            if not len(rows):
                continue
            coeffs = data["coeffs"][l]
            terms = select_terms(coeffs, config.light_terms, rule="magnitude")
            lj = torch.as_tensor(coeffs[terms])
            for start in range(0, len(rows), 4096):
                idx = torch.as_tensor(rows[start:start + 4096])
                pred = model.radiance(inputs.rows(idx), terms, lj).numpy()
                want = data["target"][idx.numpy()]
                err += float(((pred - want) ** 2).sum())
                count += pred.size
                dw = imageio.display(want, exposure=scene.exposure)
                derr += float(((imageio.display(pred, exposure=scene.exposure) - dw) ** 2).sum())
                dzero += float((dw ** 2).sum())
    return (float(10 * np.log10(peak ** 2 / (err / count))),
            float(10 * np.log10(peak ** 2 / zero)),
            float(10 * np.log10(count / derr)), float(10 * np.log10(count / dzero)))


#: The scene (``--scene=NAME``): the must-hold's reduced four-animals by default.
SCENE = next((a.split("=", 1)[1] for a in sys.argv if a.startswith("--scene=")), "four-animals")
#: SH bands of the baseline per scene (four-animals: the test's, the most llvmpipe holds).
SH_BANDS = {"four-animals": MUST_HOLD_SH_BANDS, "sphere-over-plane": 5}


def _scene():
    if SCENE == "four-animals":
        return must_hold_scene()
    if SCENE != "sphere-over-plane":
        raise SystemExit(f"--scene={SCENE}; accepted: {', '.join(SH_BANDS)}")
    return get_scene("sphere-over-plane", variant="glossy", sphere_segments=24,
                     plane_subdivisions=8).with_views(3)


def _config(cls, extra: dict, features: str, **more):
    """The test's ``COMPARISON`` config with ``extra`` and ``more`` over it (quick profile)."""
    return cls.make_config({**COMPARISON, **extra, "features": features, **more},
                           profile="quick")


def main() -> None:
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    extra = json.loads(args[0]) if args else {}
    variants = args[1].split(",") if len(args) > 1 else ["hashgrid", "vertex"]
    print(f"prtbench from {prtbench.__file__}; scene {SCENE}; overrides {extra}", flush=True)
    cls = METHODS.get("neural-wavelet")
    scene = _scene()
    t0 = time.time()
    if "--data-only" in sys.argv:
        from methods.neural_wavelet.data import build_dataset

        config = _config(cls, extra, variants[0])
        data = build_dataset(scene, config, progress=True)
        print(f"data: {len(data['target'])} rows | wall {time.time() - t0:.0f} s", flush=True)
        return
    heldout = [get_light(n) for n in {**COMPARISON, **extra}["heldout_lights"]]

    class Black:
        def indirect(self, view, light):
            return np.zeros((H, W, 3), np.float32)

    print(f"black heldout {psnr_over(Black(), scene, heldout):.2f}", flush=True)
    if "--no-sh" not in sys.argv:
        sh = sh_baseline(scene, width=W, height=H, bounces=1, sh_bands=SH_BANDS[SCENE])
        try:
            print(f"sh heldout {psnr_over(sh, scene, heldout):.2f}", flush=True)
        finally:
            sh.release()
    for features in variants:
        config = _config(cls, extra, features)
        artifact = load_or_precompute(cls, scene, config, progress=False)
        m = artifact.meta
        train_lights = [get_light(n) for n in config.train_lights[:2]]
        out = {}
        renderer = cls.renderer(scene, artifact, config, width=W, height=H)
        try:
            out["heldout"] = psnr_over(renderer, scene, heldout)
            out["trainlight"] = psnr_over(renderer, scene, train_lights)
        finally:
            renderer.release()
        full = _config(cls, extra, features, light_terms=6 * config.cubemap ** 2)
        renderer = cls.renderer(scene, artifact, full, width=W, height=H)
        try:
            out["heldout_all"] = psnr_over(renderer, scene, heldout)
        finally:
            renderer.release()
        (out["trainfit"], out["trainfit_black"], out["trainfit_disp"],
         out["trainfit_disp_black"]) = train_fit(artifact, config)
        print(f"{features}: " + " ".join(f"{k} {v:.2f}" for k, v in out.items())
              + f" | {m['data_images']} images {m['data_rows']} rows, train {m['train_s']:.0f} s "
              f"{m['pixels_per_s']:.0f} px/s, loss {m['loss_first']:.4g} -> {m['loss_last']:.4g}"
              f" | wall {time.time() - t0:.0f} s", flush=True)


if __name__ == "__main__":
    main()
