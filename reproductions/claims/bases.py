"""Counts of our own bases that computed claims check: non-zero tripling coefficients.

A tripling coefficient C_ijk = ∫ Ψ_i Ψ_j Ψ_k of a basis is what a triple product must sum over.
For real SH (:func:`prtbench.transport.sh.triple_product_sparse`, exact) the non-zeros grow as
N^(5/2) in the number of basis functions N = n²; for the orthonormal non-standard Haar basis of
a cubemap face (:mod:`prtbench.transport.wavelet.haar`) only nested supports meet, O(N log N).
The Haar count here is brute force (every basis function as an image, every product summed), an
independent check of that nesting rule; faces do not overlap, so a cubemap has six faces' worth.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from prtbench.transport import sh
from prtbench.transport.wavelet import haar


def sh_tripling_counts(bands: Sequence[int]) -> list[tuple[int, int]]:
    """(N = n², non-zero Γ_ijk) for each band count n."""
    return [(b * b, len(sh.triple_product_sparse(b)[1])) for b in bands]


def haar_tripling_counts(faces: Sequence[int]) -> list[tuple[int, int]]:
    """(N = 6·s², non-zero C_ijk) of a cubemap with s × s faces, by brute force."""
    out = []
    for s in faces:
        basis = haar.inverse(np.eye(s * s).reshape(s * s, s, s)).reshape(s * s, s * s)
        count = 0
        for row in basis:  # C_i·· = (ψ_i ψ_j) · ψ_k over the texels
            count += int(np.count_nonzero(np.abs((row * basis) @ basis.T) > 1e-9))
        out.append((6 * s * s, 6 * count))
    return out


def loglog_slope(points: Sequence[tuple[int, int]]) -> float:
    """Least-squares slope of log(count) against log(N)."""
    x = np.log([float(n) for n, _ in points])
    y = np.log([float(c) for _, c in points])
    return float(np.polyfit(x, y, 1)[0])


def last_slope(points: Sequence[tuple[int, int]]) -> float:
    """The local exponent of count in N between the two largest sizes (the asymptote's best
    estimate)."""
    (n0, c0), (n1, c1) = points[-2], points[-1]
    return math.log(c1 / c0) / math.log(n1 / n0)


def last_slope_n_log_n(points: Sequence[tuple[int, int]]) -> float:
    """The local exponent of count in N·log N between the two largest sizes: 1 for an
    O(N log N) count, above 1 for anything growing faster."""
    (n0, c0), (n1, c1) = points[-2], points[-1]
    return math.log(c1 / c0) / math.log(n1 * math.log(n1) / (n0 * math.log(n0)))
