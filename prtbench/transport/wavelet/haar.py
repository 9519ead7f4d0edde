"""Orthonormal non-standard 2-D Haar transform of cubemap faces, vectorised over many signals.

Non-standard decomposition (Stollnitz, DeRose and Salesin; Ng 2003): each step replaces every
2×2 block (p, q / r, s) of the current low-pass image by its average and three details,

    LL = (p + q + r + s)/2     LH = (p − q + r − s)/2
    HL = (p + q − r − s)/2     HH = (p − q − r + s)/2

(an orthogonal, symmetric 4×4 matrix, so the transform is orthonormal: Parseval holds and the
inverse is the same matrix), then recurses on the LL image until one texel is left: a scaling
coefficient per face plus the quadtree of wavelet coefficients. The layout is the usual
in-place one: after the step on an s×s image, LL sits in ``[:s/2, :s/2]``, LH in
``[:s/2, s/2:s]``, HL in ``[s/2:s, :s/2]`` and HH in ``[s/2:s, s/2:s]``; the scaling
coefficient ends in ``[0, 0]``. A coefficient in a detail quadrant of an s×s step at
``(r, c)`` (relative to the quadrant) is supported on the (2N/s)² texels of rows
``r·2N/s …`` and columns ``c·2N/s …``.

Flat index of coefficient ``(f, r, c)`` of a 6×N×N cubemap: ``f·N² + r·N + c``.

Solid-angle weights: none here. The transform is applied to the light's texel-mean radiance and
to the transport with texel solid angles folded in (see :mod:`prtbench.transport.wavelet`), so the dot
product of coefficient vectors is the cubemap integral.
"""

from __future__ import annotations

import numpy as np

from prtbench.api.errors import InvalidInputError
from prtbench.transport.wavelet.cubemap import check_resolution, texel_solid_angles


def _check(x: np.ndarray) -> int:
    if x.ndim < 2 or x.shape[-1] != x.shape[-2]:
        raise InvalidInputError(f"Haar input shape {x.shape}; accepted: (..., N, N)")
    return check_resolution(x.shape[-1], what="Haar face size")


def forward(x: np.ndarray, *, dtype=np.float64) -> np.ndarray:
    """Non-standard Haar coefficients of square images.

    Parameters
    ----------
    x : ndarray, shape (..., N, N)
        Any leading axes (signals, faces, channels before the face axes); N a power of two.
    dtype : numpy dtype
        Arithmetic and result type: float64 (default; Parseval to 1e-12) or float32 (bulk
        transport, stored at float32 or less anyway: relative rounding ~1e-7 per level).

    Returns
    -------
    ndarray, shape (..., N, N), ``dtype``
        Coefficients in the in-place layout of the module docstring.
    """
    out = np.array(x, dtype=dtype, copy=True)
    _check(out)
    # Each level as a horizontal then a vertical pair pass into a reused buffer, then one
    # scaling: the same sums in the same order as ll = ½((p+q)+(t+u)) etc., so the same bits
    # as the four-quadrant form, with no temporaries (~20 % faster on bulk float32 transport).
    buffer = np.empty_like(out)
    half = out.dtype.type(0.5)
    s = out.shape[-1]
    while s > 1:
        h = s // 2
        block, pairs = out[..., :s, :s], buffer[..., :s, :s]
        left, right = block[..., 0::2], block[..., 1::2]
        np.add(left, right, out=pairs[..., :h])  # horizontal sums | differences
        np.subtract(left, right, out=pairs[..., h:])
        top, bottom = pairs[..., 0::2, :], pairs[..., 1::2, :]
        np.add(top, bottom, out=block[..., :h, :])  # vertical sums: ll | lh
        np.subtract(top, bottom, out=block[..., h:, :])  # vertical differences: hl | hh
        block *= half
        s = h
    return out


def inverse(c: np.ndarray) -> np.ndarray:
    """Images from their non-standard Haar coefficients (exact inverse of :func:`forward`).

    Parameters
    ----------
    c : ndarray, shape (..., N, N)

    Returns
    -------
    ndarray, shape (..., N, N), float64
    """
    out = np.array(c, dtype=np.float64, copy=True)
    n = _check(out)
    s = 2
    while s <= n:
        h = s // 2
        ll, lh = out[..., :h, :h].copy(), out[..., :h, h:s].copy()
        hl, hh = out[..., h:s, :h].copy(), out[..., h:s, h:s].copy()
        block = np.empty((*out.shape[:-2], h, 2, h, 2))
        block[..., :, 0, :, 0] = 0.5 * (ll + lh + hl + hh)
        block[..., :, 0, :, 1] = 0.5 * (ll - lh + hl - hh)
        block[..., :, 1, :, 0] = 0.5 * (ll + lh - hl - hh)
        block[..., :, 1, :, 1] = 0.5 * (ll - lh - hl + hh)
        out[..., :s, :s] = block.reshape(*out.shape[:-2], s, s)
        s *= 2
    return out


def support_solid_angles(n: int) -> np.ndarray:
    """Solid angle of the support of every coefficient of a 6×N×N cubemap, (6, N, N) float64.

    A detail coefficient's support is the texel block it differences; the scaling coefficient's
    is the whole face (4π/6). Used by the area-weighted selection (Ng 2003).
    """
    n = check_resolution(n)
    level = texel_solid_angles(n)
    out = np.zeros((6, n, n))
    s = n
    while s > 1:
        h = s // 2
        parent = level.reshape(6, h, 2, h, 2).sum(axis=(2, 4))
        out[:, :h, h:s] = parent
        out[:, h:s, :h] = parent
        out[:, h:s, h:s] = parent
        level = parent
        s = h
    out[:, 0, 0] = level[:, 0, 0]
    return out


def support_texels(n: int) -> np.ndarray:
    """Side length in texels of every coefficient's support, (N, N) int64 (same on each face)."""
    n = check_resolution(n)
    out = np.full((n, n), n, dtype=np.int64)
    s = n
    while s > 1:
        h = s // 2
        out[:h, h:s] = out[h:s, :h] = out[h:s, h:s] = n // h
        s = h
    return out
