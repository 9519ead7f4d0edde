"""The outcome class of a stability case (issue #15): ok, degraded, refused or failed.

* ``failed`` — always a bug: a crash, a traceback, a hang past the timeout, a multi-line error
  message, NaN/Inf anywhere in the artifact or the image, or a finite image whose masked
  metric is NaN (nothing was measured);
* ``refused`` — a clear one-line :class:`prtbench.api.errors.PrtbenchError`: the correct answer to
  an impossible request;
* ``degraded`` — finite, but its masked PSNR against the reference is more than
  :data:`PSNR_MARGIN_DB` below the moderate case's, or its masked FLIP more than
  :data:`FLIP_MARGIN` above it; or a black light that the method renders visibly lit;
* ``ok`` — otherwise (a black light rendered black is ok: the reference is black too).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

OUTCOMES = ("ok", "degraded", "refused", "failed")
#: Masked PSNR (dB) a case may lose against the moderate case and still be ``ok``: three times
#: the regression tolerance (1 dB), well above the smoke profile's Monte-Carlo spread.
PSNR_MARGIN_DB = 3.0
#: Masked FLIP a case may gain over the moderate case and still be ``ok``.
FLIP_MARGIN = 0.05
#: Error kinds a case run reports (besides ``""``, it ran to the end).
ERROR_KINDS = ("refused", "exception", "crash", "timeout")


def _number(value: Any) -> float:
    return float(value) if value is not None else math.nan


def classify(measured: Mapping[str, Any], moderate: Mapping[str, Any] | None) -> tuple[str, str]:
    """``(outcome, reason)`` of one case.

    Parameters
    ----------
    measured : mapping
        What :func:`prtbench.stability.run.measure_case` returned: ``error_kind`` (``""`` or one
        of :data:`ERROR_KINDS`), ``error`` (the message), ``image_nonfinite``,
        ``artifact_nonfinite`` (counts), ``psnr_masked``, ``flip_masked``, ``reference_black``
        and ``image_black`` (bools).
    moderate : mapping or None
        The moderate case's ``psnr_masked`` and ``flip_masked`` (None: the case is the moderate
        one, which is compared with nothing).

    Returns
    -------
    tuple of str
        The outcome (one of :data:`OUTCOMES`) and a one-line reason.
    """
    kind, error = measured.get("error_kind", ""), str(measured.get("error", "") or "")
    if kind == "refused":
        if error.strip() and "\n" not in error.strip():
            return "refused", error.strip()
        return "failed", f"refusal without a one-line message: {error!r}"
    if kind:
        return "failed", f"{kind}: {error}".strip()
    bad = [f"{int(measured.get(key) or 0)} non-finite values in the {what}"
           for key, what in (("artifact_nonfinite", "artifact"), ("image_nonfinite", "image"))
           if int(measured.get(key) or 0) > 0]
    if bad:
        return "failed", "; ".join(bad)
    if measured.get("reference_black"):
        if measured.get("image_black"):
            return "ok", "black light, black image (as the reference)"
        return "degraded", "the reference is black but the method's image is not"
    psnr, flip = _number(measured.get("psnr_masked")), _number(measured.get("flip_masked"))
    if math.isnan(psnr) or math.isnan(flip):
        return "failed", f"masked metrics not measured (psnr {psnr}, flip {flip})"
    if moderate is None:
        return "ok", "the moderate setting"
    m_psnr, m_flip = _number(moderate.get("psnr_masked")), _number(moderate.get("flip_masked"))
    if not (math.isfinite(m_psnr) or math.isfinite(m_flip)):
        return "ok", "finite and measured; the moderate case has no measurement to compare with"
    lost = m_psnr - psnr if math.isfinite(m_psnr) else 0.0
    gained = flip - m_flip if math.isfinite(m_flip) else 0.0
    if lost > PSNR_MARGIN_DB or gained > FLIP_MARGIN:
        return "degraded", (f"masked PSNR {psnr:.2f} dB vs {m_psnr:.2f} moderate "
                            f"(-{lost:.2f} > {PSNR_MARGIN_DB:g} dB)" if lost > PSNR_MARGIN_DB else
                            f"masked FLIP {flip:.3f} vs {m_flip:.3f} moderate "
                            f"(+{gained:.3f} > {FLIP_MARGIN:g})")
    return "ok", f"within {PSNR_MARGIN_DB:g} dB / {FLIP_MARGIN:g} FLIP of the moderate setting"
