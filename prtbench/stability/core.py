"""The SH core at the extremes (issue #15): projection and reconstruction to 16 bands, with
and without de-ringing windows, and the Phong zonal coefficients at extreme exponents.

These rows have method ``sh-core`` in the stability table. No renderer is involved, so they
are measured in the calling process (numpy only):

* ``ringing``: for a light projected to n bands (optionally windowed, :func:`prtbench.transport.sh.window`)
  and reconstructed on a 64 × 128 direction grid, the most negative reconstructed radiance over
  the largest reconstructed radiance (0 for a non-negative reconstruction); ``rel_l2`` the
  relative L2 error of the reconstruction against the light's own radiance on that grid
  (solid-angle weighted). A ringing above :data:`RINGING_LIMIT` is ``degraded``: a PRT method
  multiplying that light by a transfer vector shows it as dark or coloured halos.
* ``phong``: the zonal coefficients of the normalised Phong lobe at 16 bands for the exponents of
  the material cases; non-finite values would be ``failed``, the exponent past the accepted
  range must be ``refused``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from prtbench.api.errors import PrtbenchError
from prtbench.stability.lights import LIGHTS as CASE_LIGHTS
from prtbench.transport import sh
from prtbench.transport.latlong import lat_long_directions

#: Ringing (negative over positive peak of the reconstruction) above which a row is degraded.
RINGING_LIMIT = 0.05
#: SH band counts per profile, and the lights and windows measured.
BANDS = {"smoke": (1, 4, 8, 16), "quick": tuple(range(1, 17))}
LIGHTS = {"smoke": ("below-horizon",), "quick": ("below-horizon", "sun-0.1deg")}
WINDOWS = ("none", "hanning", "lanczos")
#: Phong exponents (the material cases' values).
EXPONENTS = (0.0, 1.0, 1e3, 1e4, 1e5)
#: Rows and columns of the reconstruction grid.
GRID_ROWS = 64


def _grid():
    rows, cols = GRID_ROWS, 2 * GRID_ROWS
    u = (np.arange(cols) + 0.5) / cols
    v = (np.arange(rows) + 0.5) / rows
    dirs = lat_long_directions(u[None, :], v[:, None]).reshape(-1, 3)
    theta = np.pi * v
    weights = np.repeat((np.sin(theta) * (np.pi / rows) * (2 * np.pi / cols))[:, None], cols, 1)
    return dirs, weights.reshape(-1)


def _ringing_row(full: np.ndarray, light_name: str, bands: int, window_kind: str, dirs,
                 weights, truth) -> dict[str, Any]:

    # The first n² coefficients of the largest projection are the n-band projection (the basis
    # is orthonormal); the red channel: every case light is grey.
    coeffs = full[:bands * bands, 0]
    ls, _ = sh.lm_of(bands)
    coeffs = coeffs * sh.window(bands, kind=window_kind)[ls]
    recon = sh.eval_sh(dirs, bands) @ coeffs
    finite = int(np.count_nonzero(np.isfinite(recon)))
    peak = float(np.max(recon)) if finite == recon.size else math.nan
    ringing = max(0.0, -float(np.min(recon))) / peak if peak > 0 else math.nan
    err = float(np.sqrt(np.sum(weights * (recon - truth) ** 2) / np.sum(weights * truth ** 2)))
    return {"case": f"ringing {light_name} bands={bands} window={window_kind}",
            "group": "sh-core", "ringing": ringing, "rel_l2": err,
            "image_nonfinite": recon.size - finite, "bands": bands, "window": window_kind,
            "light": light_name}


def _phong_row(s: float, bands: int = 16) -> dict[str, Any]:
    row: dict[str, Any] = {"case": f"phong s={s:g} bands={bands}", "group": "sh-core",
                           "bands": bands, "shininess": s}
    try:
        g = sh.phong_zonal(s, bands)
    except PrtbenchError as exc:
        return {**row, "error_kind": "refused", "error": str(exc)}
    row["image_nonfinite"] = int(g.size - np.count_nonzero(np.isfinite(g)))
    row["zonal_peak"] = float(np.max(np.abs(g)))
    row["zonal_g0"] = float(g[0])
    return row


def classify_core(row: dict[str, Any]) -> tuple[str, str]:
    """``(outcome, reason)`` of a core row (same classes as the method cases)."""
    if row.get("error_kind") == "refused":
        return "refused", str(row.get("error", ""))
    if int(row.get("image_nonfinite") or 0):
        return "failed", f"{row['image_nonfinite']} non-finite values"
    ringing = row.get("ringing")
    if ringing is not None and not (isinstance(ringing, float) and math.isnan(ringing)):
        if ringing > RINGING_LIMIT:
            return "degraded", (f"ringing {ringing:.3f} > {RINGING_LIMIT:g} of the peak "
                                f"(rel. L2 {row['rel_l2']:.3f})")
        return "ok", f"ringing {ringing:.3f}, rel. L2 {row['rel_l2']:.3f}"
    if "zonal_g0" in row:
        return "ok", f"finite; g_0 {row['zonal_g0']:.4f}, peak {row['zonal_peak']:.4g}"
    return "failed", "nothing measured"


def core_case_names(*, profile: str) -> list[str]:
    """The case names :func:`core_rows` measures at ``profile`` (nothing computed)."""
    return [f"ringing {name} bands={bands} window={kind}" for name in LIGHTS[profile]
            for bands in BANDS[profile] for kind in WINDOWS] + [
        f"phong s={s:g} bands=16" for s in EXPONENTS]


def core_rows(*, profile: str) -> list[dict[str, Any]]:
    """Every SH-core row of ``profile``, classified (``outcome``, ``reason``, ``advice``)."""

    dirs, weights = _grid()
    rows = []
    for name in LIGHTS[profile]:
        light = CASE_LIGHTS[name].build()
        truth = light.radiance(dirs)[:, 0]
        full = light.sh(max(BANDS[profile]))  # one projection (the costly part), cached on disk
        for bands in BANDS[profile]:
            for kind in WINDOWS:
                rows.append(_ringing_row(full, name, bands, kind, dirs, weights, truth))
    rows += [_phong_row(s) for s in EXPONENTS]
    for row in rows:
        row["outcome"], row["reason"] = classify_core(row)
        row["method"] = "sh-core"
        row["note"] = "SH projection/reconstruction of the case light" if "ringing" in row \
            else "Phong zonal coefficients (moment recurrence)"
        row["advice"] = ("window the light's SH (hanning) or use fewer bands for all-frequency "
                         "light; a wavelet or per-pixel method for delta lights")
    return rows
