"""Degenerate views: measurements that are computed but mean nothing (DESIGN.md §10).

A black method image, a black reference, an empty geometry mask or a non-finite masked metric
(an empty mask, an all-zero light, a scene scaled to nothing) would otherwise be stored and
ranked like any number. The runner stores such a view with status ``degenerate`` and the
reason this module gives; scenes refuse what they can up front, this is the second line.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from prtbench.api import strict_json

#: A display value below half an 8-bit step prints as black.
_BLACK_DISPLAY = 0.5 / 255.0


def degenerate_reason(image: np.ndarray, test_display: np.ndarray, reference_display: np.ndarray,
                      mask: np.ndarray, values: Mapping[str, float]) -> str:
    """Why a view's measurement is meaningless, or ``""`` when it is not.

    Parameters
    ----------
    image : ndarray, shape (H, W, 3)
        The method's linear HDR image.
    test_display, reference_display : ndarray, shape (H, W, 3)
        Display-space method and reference images (what the metrics compare).
    mask : ndarray, shape (H, W), bool
        Geometry pixels.
    values : mapping
        The view's metrics.

    Returns
    -------
    str
        ``"; "``-joined reasons: a method image with non-finite values (then ``values`` are
        NaN: the metrics refuse such images) or that displays all black, a reference that
        displays all black, an empty geometry mask, masked metrics that are NaN or infinite
        (with their values).
    """
    reasons = []
    finite = np.isfinite(image)
    if not finite.any():
        reasons.append("method image has no finite pixel")
    else:
        if not finite.all():
            reasons.append(f"method image has {int(np.count_nonzero(~finite))} non-finite values")
        if not np.nanmax(np.abs(np.where(finite, test_display, 0.0))) >= _BLACK_DISPLAY:
            reasons.append("method image is all black")
    if not np.nanmax(np.abs(reference_display), initial=0.0) >= _BLACK_DISPLAY:
        reasons.append("reference image is all black")
    if not np.asarray(mask).any():
        reasons.append("geometry mask is empty (no pixel's centre ray hits the scene)")
    bad = strict_json.non_finite_keys({k: v for k, v in values.items() if k.endswith("_masked")})
    if bad:
        reasons.append(f"masked metrics not finite: {', '.join(bad)}")
    return "; ".join(reasons)
