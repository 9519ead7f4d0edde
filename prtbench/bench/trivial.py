"""Trivial images from a reference: the floor every method's gate must clear (issue #12).

A metric threshold means nothing unless it sits above what an image with no light transport in
it scores against the same reference. Two such images are built from the reference itself:

* ``flat``: every geometry pixel set to the mean display colour of the reference over the mask
  (per channel); background pixels are the reference's own (0 for every method);
* ``half``: the reference at half its linear radiance (a method that got the light's scale
  wrong by 2×, the most common bug of a transfer or SH normalisation).

For shadowed methods a third one, the *unshadowed render* (the same method with its
``visibility`` knob off, i.e. unoccluded transfer), is produced by the caller
(:mod:`prtbench.bench.regress`) because it needs the method's own precompute; :func:`visibility_knob`
says whether a method has one and, if not, why.

:func:`beats` is the gate: a method beats a trivial image when its masked PSNR is at least
:data:`PSNR_MARGIN_DB` higher and its masked FLIP at least :data:`FLIP_MARGIN` lower.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from prtbench.api.errors import InvalidInputError
from prtbench.bench.metrics import compute_metrics
from prtbench.io.imageio import display

#: Masked PSNR (dB) a method must score above every trivial image: the regression tolerance on
#: masked PSNR (:data:`prtbench.bench.regress.TOLERANCES`): every run is gated, so a run that passes
#: is at least one tolerance away from every trivial image, not merely close to its baseline.
PSNR_MARGIN_DB = 1.0
#: Masked FLIP (lower is better) a method must score below every trivial image; likewise the
#: FLIP tolerance. Measured on the smoke cases: methods 0.15-0.27, flat images 0.38-0.71,
#: half-bright 0.46-0.55, unshadowed renders 0.18-0.27.
FLIP_MARGIN = 0.02
#: The two metrics the gate reads.
GATE_METRICS = ("psnr_masked", "flip_masked")


def trivial_images(reference_hdr: np.ndarray, mask: np.ndarray, *,
                   exposure: float = 1.0) -> dict[str, np.ndarray]:
    """The trivial display images of one reference view.

    Parameters
    ----------
    reference_hdr : ndarray, shape (H, W, 3)
        Linear reference radiance (background 0).
    mask : ndarray, shape (H, W), bool
        Geometry pixels (:func:`prtbench.transport.raytrace.geometry_mask`); must not be empty.
    exposure : float
        The scene's display exposure.

    Returns
    -------
    dict of str to ndarray, shape (H, W, 3), float32 in [0, 1]
        ``{"flat": …, "half": …}``.
    """

    ref = np.asarray(reference_hdr, dtype=np.float64)
    mask = np.asarray(mask, dtype=bool)
    if ref.ndim != 3 or ref.shape[2] != 3 or mask.shape != ref.shape[:2]:
        raise InvalidInputError(f"reference {ref.shape} and mask {mask.shape}; accepted: "
                                "(H, W, 3) and (H, W)")
    if not mask.any():
        raise InvalidInputError("the geometry mask is empty: no trivial image (and no masked "
                                "metric) is defined")
    ref_d = display(ref, exposure=exposure)
    flat = ref_d.copy()
    flat[mask] = ref_d[mask].mean(axis=0)  # (3,) mean display colour over the geometry
    return {"flat": flat, "half": display(0.5 * ref, exposure=exposure)}


def trivial_scores(reference_hdr: np.ndarray, mask: np.ndarray, *,
                   exposure: float = 1.0) -> dict[str, dict[str, float]]:
    """Metrics (:func:`prtbench.bench.metrics.compute_metrics`) of each trivial image.

    Returns
    -------
    dict of str to dict of str to float
        ``{"flat": {"psnr_masked": …, "flip_masked": …, …}, "half": {…}}``.
    """

    ref_d = display(reference_hdr, exposure=exposure)
    return {name: compute_metrics(image, ref_d, mask=mask)
            for name, image in trivial_images(reference_hdr, mask, exposure=exposure).items()}


def beats(method: Mapping[str, float], trivial: Mapping[str, float]) -> bool:
    """Whether ``method``'s metrics clear ``trivial``'s by both margins (NaN never does)."""
    psnr, flip = float(method["psnr_masked"]), float(method["flip_masked"])
    t_psnr, t_flip = float(trivial["psnr_masked"]), float(trivial["flip_masked"])
    # Written so that a NaN anywhere compares False, i.e. fails.
    return bool(psnr >= t_psnr + PSNR_MARGIN_DB and flip <= t_flip - FLIP_MARGIN)


def gate_failures(method: Mapping[str, float],
                  trivials: Mapping[str, Mapping[str, float]]) -> list[str]:
    """One line per trivial image that ``method`` does not beat (empty: the gate passes)."""
    return [f"does not beat the {name} image by {PSNR_MARGIN_DB} dB / {FLIP_MARGIN} FLIP: "
            f"psnr_masked {float(method['psnr_masked']):.3f} vs {float(t['psnr_masked']):.3f}, "
            f"flip_masked {float(method['flip_masked']):.4f} vs {float(t['flip_masked']):.4f}"
            for name, t in trivials.items() if not beats(method, t)]


def visibility_knob(method_cls) -> str | None:
    """``None`` if ``method_cls.Config`` has a ``visibility`` knob, else the reason it has none.

    A method without the knob states why in a ``no_visibility_reason`` class attribute.
    """
    if "visibility" in getattr(method_cls.Config, "__dataclass_fields__", {}):
        return None
    return method_cls.no_visibility_reason or (
        f"method '{method_cls.name}' has no visibility knob")
