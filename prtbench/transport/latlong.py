"""The lat-long mapping of environment maps (DESIGN.md §3), exactly Mitsuba 3's ``envmap``: texel
directions, the inverse mapping and exact per-row solid angles; and the SH projection of a
bilinearly interpolated map (tensor Gauss–Legendre inside each interpolation cell).
"""

from __future__ import annotations

import math

import numpy as np

from prtbench.api.errors import InvalidInputError
from prtbench.transport.sh import project

# --- the mapping ------------------------------------------------------------------------------

def lat_long_directions(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Unit directions of lat-long coordinates (Mitsuba's ``envmap`` convention).

    Parameters
    ----------
    u, v : ndarray, shape (...)
        Lat-long coordinates, φ = 2πu, θ = πv.

    Returns
    -------
    ndarray, shape (..., 3), float64
        ``(sin φ sin θ, cos θ, −cos φ sin θ)``.
    """
    u, v = np.broadcast_arrays(np.asarray(u, dtype=np.float64), np.asarray(v, dtype=np.float64))
    phi, theta = 2.0 * np.pi * u, np.pi * v
    sin_t = np.sin(theta)
    return np.stack([np.sin(phi) * sin_t, np.cos(theta), -np.cos(phi) * sin_t], axis=-1)

#: (largest cell width × bands, Gauss–Legendre nodes per cell and axis) for the SH projection:
#: measured to keep a constant map's projection error below 1e-8 (a 1024x512 map needs 2 nodes
#: up to 32 bands; a 64x32 map 4 nodes at 8 bands).
SH_NODE_RULE = ((0.2, 2), (0.8, 3), (1.7, 4), (3.4, 5))

SH_MAX_NODES = 8


def lat_long_uv(dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lat-long coordinates of directions (inverse of :func:`lat_long_directions`).

    Parameters
    ----------
    dirs : ndarray, shape (..., 3)
        Directions (normalised here).

    Returns
    -------
    u : ndarray, shape (...), in [0, 1)
    v : ndarray, shape (...), in [0, 1]
    """
    d = np.asarray(dirs, dtype=np.float64)
    if d.shape[-1:] != (3,):
        raise InvalidInputError(f"directions must have shape (..., 3), got {d.shape}")
    norm = np.linalg.norm(d, axis=-1, keepdims=True)
    if not np.all(np.isfinite(norm) & (norm > 0)):
        raise InvalidInputError(
            f"{int(np.sum(~(np.isfinite(norm) & (norm > 0))))} directions are zero or not finite")
    d = d / norm
    u = np.arctan2(d[..., 0], -d[..., 2]) / (2.0 * np.pi)
    u = u - np.floor(u)
    u = np.where(u >= 1.0, 0.0, u)  # -tiny + 1 rounds to 1.0
    v = np.arccos(np.clip(d[..., 1], -1.0, 1.0)) / np.pi
    return u, v


def _cos_minus_sinc(x: np.ndarray) -> np.ndarray:
    """cos x − sin x / x without cancellation for small x (series below 0.5)."""
    x = np.asarray(x, dtype=np.float64)
    x2 = x * x
    series = np.zeros_like(x)
    term_sign = -1.0
    power = np.ones_like(x)
    for k in range(1, 12):
        power = power * x2
        series = series + term_sign * power * (2 * k) / math.factorial(2 * k + 1)
        term_sign = -term_sign
    with np.errstate(invalid="ignore", divide="ignore"):
        direct = np.cos(x) - np.sin(x) / np.where(x == 0, 1.0, x)
    return np.where(x < 0.5, series, direct)


def row_solid_angle_factors(height: int) -> np.ndarray:
    """∫ hat_j(θ) sin θ dθ per sample row j (rows at θ_j = πj/(H−1)), (H,), summing to 2.

    Each interpolation cell [θ_j, θ_j+1] with midpoint c and half-width x contributes
    A = cos c · (cos x − sin x/x) + sin c · sin x to its upper row (weight 1 − t) and
    B = −cos c · (cos x − sin x/x) + sin c · sin x to its lower row (weight t); A + B is the
    cell's exact ∫ sin θ dθ = 2 sin c sin x.
    """
    cells = height - 1
    x = 0.5 * np.pi / cells
    c = (np.arange(cells) + 0.5) * np.pi / cells
    f = float(_cos_minus_sinc(np.array(x)))
    upper = np.cos(c) * f + np.sin(c) * math.sin(x)
    lower = -np.cos(c) * f + np.sin(c) * math.sin(x)
    out = np.zeros(height)
    out[:-1] += upper
    out[1:] += lower
    return out


def nodes_per_cell(height: int, bands: int) -> int:
    """Gauss–Legendre nodes per cell and axis to project ``bands`` bands (``SH_NODE_RULE``)."""
    width_times_bands = np.pi / (height - 1) * bands
    for limit, nodes in SH_NODE_RULE:
        if width_times_bands <= limit:
            return nodes
    return SH_MAX_NODES


def project_bilinear(image: np.ndarray, bands: int) -> np.ndarray:
    """SH projection of the bilinear lat-long interpolant of ``image`` (H, W, 3) -> (bands², 3).

    Tensor Gauss–Legendre inside every interpolation cell: in θ (with the exact sin θ Jacobian;
    θ rather than cos θ nodes because the interpolant is linear in θ and so smooth in θ even at
    the poles) and in φ between neighbouring column samples (periodic: a composite rule on an
    equispaced periodic grid integrates every e^{imφ}, |m| < W, exactly). Rows of cells are
    processed in chunks to bound memory.
    """

    img = np.asarray(image, dtype=np.float64)
    h, w, _ = img.shape
    n_coeffs = bands * bands
    cells_v = h - 1
    d_theta = np.pi / cells_v
    d_phi = 2.0 * np.pi / w
    nodes = nodes_per_cell(h, bands)
    g_t, gw_t = np.polynomial.legendre.leggauss(nodes)
    g_p, gw_p = g_t, gw_t
    t_nodes = 0.5 * (g_t + 1.0)  # fractions in [0, 1] of the cell
    s_nodes = 0.5 * (g_p + 1.0)

    # φ: nodes between column samples i and i+1 (sample i at φ = d_phi (i + ½)).
    phi = d_phi * (np.arange(w)[:, None] + 0.5 + s_nodes[None, :])          # (W, nφ)
    w_phi = np.broadcast_to(0.5 * d_phi * gw_p[None, :], phi.shape)
    s = np.broadcast_to(s_nodes[None, :], phi.shape)
    col0 = np.broadcast_to(np.arange(w)[:, None], phi.shape)
    col1 = (col0 + 1) % w
    phi, w_phi, s, col0, col1 = (a.reshape(-1) for a in (phi, w_phi, s, col0, col1))
    sin_p, cos_p = np.sin(phi), np.cos(phi)

    coeffs = np.zeros((n_coeffs, 3))
    # ~32 MB of SH values per chunk.
    rows_per_chunk = max(1, int(4_000_000 // (len(phi) * nodes * n_coeffs)))
    for start in range(0, cells_v, rows_per_chunk):
        cells = np.arange(start, min(start + rows_per_chunk, cells_v))
        theta0 = cells * d_theta
        theta = theta0[:, None] + d_theta * t_nodes[None, :]                  # (C, nθ)
        w_theta = 0.5 * d_theta * gw_t[None, :] * np.sin(theta)
        exact = np.cos(theta0) - np.cos(theta0 + d_theta)                     # cell ∫ sin θ dθ
        w_theta = w_theta * (exact / w_theta.sum(axis=1))[:, None]
        t = np.broadcast_to(t_nodes[None, :], theta.shape)
        row0 = np.broadcast_to(cells[:, None], theta.shape)
        theta, w_theta, t, row0 = (a.reshape(-1) for a in (theta, w_theta, t, row0))
        sin_t, cos_t = np.sin(theta), np.cos(theta)

        # Row-interpolated values at the two bracketing columns, then linear in φ.
        top0, top1 = img[row0][:, col0], img[row0][:, col1]                   # (Cθ, Wφ, 3)
        bot0, bot1 = img[row0 + 1][:, col0], img[row0 + 1][:, col1]
        tt = t[:, None, None]
        ss = s[None, :, None]
        values = ((1 - tt) * ((1 - ss) * top0 + ss * top1)
                  + tt * ((1 - ss) * bot0 + ss * bot1))
        dirs = np.stack([np.outer(sin_t, sin_p), np.broadcast_to(cos_t[:, None], values.shape[:2]),
                         -np.outer(sin_t, cos_p)], axis=-1)
        weights = np.outer(w_theta, w_phi)
        coeffs += project(values.reshape(-1, 3), dirs.reshape(-1, 3), weights.reshape(-1), bands)
    return coeffs
