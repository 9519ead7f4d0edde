"""Intervals on the numbers that decide a ranking (docs/PROTOCOL.md).

Two sources of uncertainty are counted:

* the reference's own Monte Carlo noise. The runner's path reference is the mean of two
  independent half-sample renders, so the RMSE of its noise (display space, masked) is known
  per view (:class:`prtbench.render.reference.Reference`, ``noise_rmse_display``). Against a
  noisy reference the measured MSE of a method image is the MSE against the noise-free image
  plus the noise's variance s², give or take the noise's own sampling spread
  √((4·MSE·s² + 2·s⁴) / N) over N masked pixels. :func:`metric_interval` turns that into the
  interval of the masked PSNR that the noise-free comparison may have: 95 %, i.e. two standard
  errors, plus the whole bias s² on the optimistic side.
* the spread over views. A configuration's score is the mean over its views; across views the
  score varies (different surfaces, shadows, highlights), and :func:`over_views` widens the
  mean of the per-view intervals by Student's t times the standard error of the mean (n ≥ 2).

A verdict ("A beats B", "meets the target") holds only beyond these intervals.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

#: Student's t quantile (two-sided 95 %) by degrees of freedom; large n tends to 1.96.
_T95 = {1: 12.706, 2: 4.303, 3: 3.182, 4: 2.776, 5: 2.571, 6: 2.447, 7: 2.365, 8: 2.306,
        9: 2.262, 10: 2.228, 15: 2.131, 20: 2.086, 30: 2.042}
#: The smallest MSE an interval reports (PSNR 100 dB): a reference as noisy as the error leaves
#: the upper bound unbounded, which this caps.
_MSE_FLOOR = 1e-10


def t95(dof: int) -> float:
    """Two-sided 95 % quantile of Student's t with ``dof`` degrees of freedom."""
    if dof < 1:
        return math.inf
    if dof > 30:
        return 1.96
    return _T95[max(k for k in _T95 if k <= dof)]  # the tabulated dof at or below: wider


def psnr(mse: float) -> float:
    return -10.0 * math.log10(max(mse, _MSE_FLOOR))


def metric_interval(psnr_masked: float | None, *, noise_rmse: float | None,
                    pixels: int | None) -> tuple[float | None, float | None]:
    """(lo, hi) of a view's masked PSNR allowed by the reference's noise.

    Parameters
    ----------
    psnr_masked : float or None
        The measured masked PSNR (display space, data range 1).
    noise_rmse : float or None
        RMSE of the reference's own noise over the same pixels (display space).
    pixels : int or None
        Masked pixels the PSNR averages over.

    Returns
    -------
    (float, float) or (None, None)
        None where the PSNR or the noise is unknown (a method reference has no noise: the
        interval is then the value itself).
    """
    if psnr_masked is None or not math.isfinite(psnr_masked):
        return None, None
    if noise_rmse is None:
        return None, None
    if noise_rmse <= 0.0:
        return psnr_masked, psnr_masked
    mse = 10.0 ** (-psnr_masked / 10.0)
    s2 = float(noise_rmse) ** 2
    n = max(int(pixels or 1), 1)
    spread = 2.0 * math.sqrt((4.0 * mse * s2 + 2.0 * s2 * s2) / n)
    return psnr(mse + spread), psnr(mse - s2 - spread)


def over_views(values: Sequence[float], los: Sequence[float | None],
               his: Sequence[float | None]) -> tuple[float, float, float]:
    """(mean, lo, hi) of a score over views: the mean of the views' intervals, widened by
    t₀.₉₇₅ · sd / √n for the spread over views (no widening for one view). A view without an
    interval counts as its value."""
    n = len(values)
    if not n:
        return math.nan, math.nan, math.nan
    mean = sum(values) / n
    lo = sum(v if lo_ is None else lo_ for v, lo_ in zip(values, los)) / n
    hi = sum(v if hi_ is None else hi_ for v, hi_ in zip(values, his)) / n
    if n >= 2:
        sd = math.sqrt(sum((v - mean) ** 2 for v in values) / (n - 1))
        half = t95(n - 1) * sd / math.sqrt(n)
        lo, hi = lo - half, hi + half
    return mean, lo, hi
