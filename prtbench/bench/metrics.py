"""Image metrics on display images (DESIGN.md §7).

Every metric is computed on display images (``prtbench.io.imageio.display``: exposure → sRGB →
clip to [0, 1]) as float, twice: over the full frame (what the papers report) and over the
geometry mask (what users should read: background pixels are 0 in both images and would
otherwise dilute every error). HDR-FLIP (``flip_hdr``) is the extra on linear images.

Each metric is a per-pixel map reduced by a function of its mean, so the masked variant is the
same reduction over the mask's pixels: masked PSNR comes from the masked MSE, masked SSIM and
FLIP are means of their maps over the mask. SSIM's map excludes the 3-pixel border that
scikit-image's mean excludes, so the full-frame value is exactly scikit-image's.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np

from prtbench.api.errors import InvalidInputError, UnknownNameError

_SSIM_WINDOW = 7


def _squared_error(test: np.ndarray, reference: np.ndarray) -> np.ndarray:
    return np.mean((test - reference) ** 2, axis=-1)


def _absolute_error(test: np.ndarray, reference: np.ndarray) -> np.ndarray:
    return np.mean(np.abs(test - reference), axis=-1)


def _ssim_map(test: np.ndarray, reference: np.ndarray) -> np.ndarray:
    from skimage.metrics import structural_similarity

    side = min(test.shape[:2])
    window = min(_SSIM_WINDOW, side if side % 2 else side - 1)  # odd, fits the image
    if window < 3:
        raise InvalidInputError(f"SSIM needs images of at least 3x3 pixels, got {test.shape[1]}x{test.shape[0]}")
    _, ssim = structural_similarity(test, reference, channel_axis=-1, data_range=1.0,
                                    win_size=window, full=True)
    pixel = ssim.mean(axis=-1)
    pad = (window - 1) // 2  # scikit-image's mean skips this border; NaN keeps the maps equal
    pixel[:pad], pixel[-pad:], pixel[:, :pad], pixel[:, -pad:] = np.nan, np.nan, np.nan, np.nan
    return pixel


def _flip_map(test: np.ndarray, reference: np.ndarray) -> np.ndarray:
    import flip_evaluator

    error, _, _ = flip_evaluator.evaluate(reference.astype(np.float32), test.astype(np.float32),
                                          "LDR", applyMagma=False)
    return np.asarray(error, dtype=np.float64).reshape(test.shape[:2])


def _flip_hdr_map(test: np.ndarray, reference: np.ndarray) -> np.ndarray:
    import flip_evaluator

    test = np.maximum(test, 0.0).astype(np.float32)
    reference = np.maximum(reference, 0.0).astype(np.float32)
    if not reference.any():
        if not test.any():
            return np.zeros(test.shape[:2])
        # FLIP derives its exposure range from the reference and terminates the process for a
        # black one; take the range from the test image instead.
        _, _, used = flip_evaluator.evaluate(test, test, "HDR", applyMagma=False, computeMeanError=False)
        params = {"startExposure": used["startExposure"], "stopExposure": used["stopExposure"]}
    else:
        params = {}
    error, _, _ = flip_evaluator.evaluate(reference, test, "HDR", applyMagma=False, parameters=params)
    return np.asarray(error, dtype=np.float64).reshape(test.shape[:2])


def _psnr_from_mse(mse: float) -> float:
    return math.inf if mse == 0.0 else -10.0 * math.log10(mse)


@dataclass(frozen=True)
class MetricSpec:
    """A registered metric.

    Attributes
    ----------
    name : str
    higher_is_better : bool
    pixel_map : callable (test, reference) -> ndarray, shape (H, W)
        Per-pixel term; NaN marks pixels the metric leaves out (SSIM's border).
    reduce : callable float -> float
        The metric from the mean of ``pixel_map`` over the counted pixels.
    hdr : bool
        Whether it reads linear HDR images instead of display images.
    """

    name: str
    higher_is_better: bool
    pixel_map: Callable[[np.ndarray, np.ndarray], np.ndarray]
    reduce: Callable[[float], float]
    hdr: bool = False

    def fn(self, test: np.ndarray, reference: np.ndarray, *, mask: np.ndarray | None = None) -> float:
        """The metric of ``test`` against ``reference`` (H, W, 3), over ``mask`` if given."""
        test, reference = _check_pair(test, reference, hdr=self.hdr)
        return _reduce(self, self.pixel_map(test, reference), mask)


METRICS: dict[str, MetricSpec] = {
    spec.name: spec for spec in (
        MetricSpec("mae", False, _absolute_error, float),
        MetricSpec("rmse", False, _squared_error, math.sqrt),
        MetricSpec("psnr", True, _squared_error, _psnr_from_mse),
        MetricSpec("ssim", True, _ssim_map, float),
        MetricSpec("flip", False, _flip_map, float),
        MetricSpec("flip_hdr", False, _flip_hdr_map, float, hdr=True),
    )
}
LDR_METRICS = tuple(name for name, spec in METRICS.items() if not spec.hdr)


def _check_pair(test, reference, *, hdr: bool) -> tuple[np.ndarray, np.ndarray]:
    test = np.asarray(test, dtype=np.float64)
    reference = np.asarray(reference, dtype=np.float64)
    kind = "HDR" if hdr else "display"
    if test.shape != reference.shape or test.ndim != 3 or test.shape[2] != 3:
        raise InvalidInputError(f"{kind} images must both be (H, W, 3); got test {test.shape}, "
                                f"reference {reference.shape}")
    for label, image in (("test", test), ("reference", reference)):
        bad = int(np.count_nonzero(~np.isfinite(image)))
        if bad:
            raise InvalidInputError(f"{label} {kind} image has {bad} non-finite values; accepted: finite")
        if not hdr and (image.min() < -1e-6 or image.max() > 1 + 1e-6):
            raise InvalidInputError(f"{label} display image spans [{image.min():.4g}, {image.max():.4g}]; "
                                    "accepted: [0, 1] (pass imageio.display(hdr))")
    if not hdr:
        test, reference = np.clip(test, 0.0, 1.0), np.clip(reference, 0.0, 1.0)
    return test, reference


def _check_mask(mask, shape) -> np.ndarray:
    mask = np.asarray(mask)
    if mask.shape != shape[:2]:
        raise InvalidInputError(f"mask shape {mask.shape}; accepted: {shape[:2]} (the image's H, W)")
    return mask.astype(bool)


def _reduce(spec: MetricSpec, pixel: np.ndarray, mask: np.ndarray | None) -> float:
    if mask is not None:
        pixel = pixel[_check_mask(mask, pixel.shape)]
    counted = pixel[~np.isnan(pixel)]
    if counted.size == 0:  # an empty mask: the metric is undefined, not perfect
        return math.nan
    return float(spec.reduce(float(np.mean(counted))))


def compute_metrics(test_display: np.ndarray, reference_display: np.ndarray, *,
                    mask: np.ndarray | None = None, names: Iterable[str] | None = None,
                    test_hdr: np.ndarray | None = None,
                    reference_hdr: np.ndarray | None = None) -> dict[str, float]:
    """All (or the named) metrics of a test image against a reference.

    Parameters
    ----------
    test_display, reference_display : ndarray, shape (H, W, 3)
        Display images in [0, 1].
    mask : ndarray, shape (H, W), bool, optional
        Geometry pixels; adds ``"<name>_masked"`` entries.
    names : iterable of str, optional
        Metric names (keys of :data:`METRICS`); default: every LDR metric, plus ``flip_hdr``
        when both HDR images are given.
    test_hdr, reference_hdr : ndarray, shape (H, W, 3), optional
        Linear images for the HDR metrics.

    Returns
    -------
    dict of str to float
        ``{"mae": …, "mae_masked": …, "psnr": inf, …}``; an empty mask gives NaN masked values.
    """
    have_hdr = test_hdr is not None and reference_hdr is not None
    names = list(names) if names is not None else [*LDR_METRICS, *(["flip_hdr"] if have_hdr else [])]
    for name in names:
        if name not in METRICS:
            raise UnknownNameError("metric", name, METRICS)
    test, reference = _check_pair(test_display, reference_display, hdr=False)
    if mask is not None:
        mask = _check_mask(mask, test.shape)
    if any(METRICS[name].hdr for name in names):
        if not have_hdr:
            raise InvalidInputError("flip_hdr needs test_hdr= and reference_hdr= (linear images)")
        test_linear, reference_linear = _check_pair(test_hdr, reference_hdr, hdr=True)
        if test_linear.shape != test.shape:
            raise InvalidInputError(f"HDR images {test_linear.shape} differ from display images {test.shape}")
    results: dict[str, float] = {}
    maps: dict[object, np.ndarray] = {}  # rmse and psnr share the squared-error map
    for name in names:
        spec = METRICS[name]
        pair = (test_linear, reference_linear) if spec.hdr else (test, reference)
        if spec.pixel_map not in maps:
            maps[spec.pixel_map] = spec.pixel_map(*pair)
        results[name] = _reduce(spec, maps[spec.pixel_map], None)
        if mask is not None:
            results[f"{name}_masked"] = _reduce(spec, maps[spec.pixel_map], mask)
    return results


def higher_is_better(key: str) -> bool:
    """Direction of a metric or result key (``"psnr"``, ``"psnr_masked"``)."""
    name = key[:-len("_masked")] if key.endswith("_masked") else key
    if name not in METRICS:
        raise UnknownNameError("metric", name, METRICS)
    return METRICS[name].higher_is_better


def error_map(test_display: np.ndarray, reference_display: np.ndarray) -> np.ndarray:
    """The FLIP error map in the magma colour map, for PNG output.

    Returns
    -------
    ndarray, shape (H, W, 3), float32 in [0, 1]
    """
    import flip_evaluator

    test, reference = _check_pair(test_display, reference_display, hdr=False)
    coloured, _, _ = flip_evaluator.evaluate(reference.astype(np.float32), test.astype(np.float32),
                                             "LDR", applyMagma=True, computeMeanError=False)
    return np.clip(np.asarray(coloured, dtype=np.float32).reshape(test.shape), 0.0, 1.0)


def psnr_ceiling(noise_rmse_display: float) -> float:
    """The highest PSNR measurable against a reference whose own display-space noise RMSE is
    ``noise_rmse_display``: a perfect method still differs from the reference by that noise.
    """
    noise = float(noise_rmse_display)
    if not noise >= 0.0 or math.isinf(noise):
        raise InvalidInputError(f"reference noise RMSE {noise_rmse_display!r}; accepted: finite >= 0")
    return _psnr_from_mse(noise * noise)
