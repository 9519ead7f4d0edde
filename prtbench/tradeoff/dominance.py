"""Dominance between (error, cost) pairs: by values, or beyond the intervals (docs/PROTOCOL.md).

:func:`non_dominated` compares plain values (or whole intervals); :func:`better_beyond`
compares two configurations paired over the views both were measured on. Both read points
by duck typing (``error_lo``, ``error_hi``, ``per_view``), so this module knows no store.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from prtbench.bench.intervals import t95


def non_dominated(errors: Sequence[float], costs: Sequence[float], *,
                  higher_is_better: bool, lo: Sequence[float] | None = None,
                  hi: Sequence[float] | None = None) -> list[bool]:
    """Which (error, cost) pairs no other pair dominates.

    ``a`` dominates ``b`` when ``a``'s cost is at most ``b``'s and ``a``'s error is at least
    as good beyond the intervals -- the worst end of ``a``'s interval is no worse than the
    best end of ``b``'s -- and one of the two strictly (docs/PROTOCOL.md). Without intervals
    (``lo``/``hi`` None) they are the values themselves. Equal pairs do not dominate each
    other. Pairs with a NaN error or cost are neither dominated nor dominating: they are
    ``False`` here (the callers leave them off the front).

    Returns
    -------
    list of bool, len(errors)
    """
    sign = 1.0 if higher_is_better else -1.0
    lo = list(errors) if lo is None else [e if not math.isfinite(x) else x
                                          for e, x in zip(errors, lo)]
    hi = list(errors) if hi is None else [e if not math.isfinite(x) else x
                                          for e, x in zip(errors, hi)]
    # In "larger is better" terms: the worst and the best end of each interval.
    worst = [sign * (float(a) if sign > 0 else float(b)) for a, b in zip(lo, hi)]
    best = [sign * (float(b) if sign > 0 else float(a)) for a, b in zip(lo, hi)]
    good = [sign * float(e) for e in errors]
    costs = [float(c) for c in costs]
    valid = [math.isfinite(g) and math.isfinite(c) for g, c in zip(good, costs)]
    out = []
    for i in range(len(good)):
        if not valid[i]:
            out.append(False)
            continue
        dominated = any(valid[j] and j != i and worst[j] >= best[i] and costs[j] <= costs[i]
                        and (worst[j] > best[i] or costs[j] < costs[i])
                        for j in range(len(good)))
        out.append(not dominated)
    return out


def paired_difference(a: Any, b: Any, *, higher_is_better: bool) -> tuple[float, float]:
    """How much better ``a``'s error is than ``b``'s, with the half-width of its interval.

    Paired over the views both were measured on: the mean per-view difference (positive when
    ``a`` is better) and, as its half-width, Student's t (n − 1 degrees of freedom) times the
    standard error of the differences plus the mean reference-noise half-widths of both, taken
    in the direction of the difference (for ``a`` better: ``a``'s towards worse and ``b``'s
    towards better). Points without shared views give the difference of their means and the
    sum of their interval half-widths.

    Returns
    -------
    (mean, half) : tuple of float
        ``a`` is better beyond the intervals when ``mean - half > 0``, worse when
        ``mean + half < 0``.
    """
    sign = 1.0 if higher_is_better else -1.0
    shared = sorted(set(a.per_view) & set(b.per_view))
    if not shared:
        mean = sign * (a.error - b.error)
        if (mean >= 0) == higher_is_better:  # a's lower end against b's upper end
            half = (a.error - a.error_lo) + (b.error_hi - b.error)
        else:
            half = (a.error_hi - a.error) + (b.error - b.error_lo)
        return mean, half
    diffs, up, down = [], [], []
    for view in shared:
        (va, lo_a, hi_a), (vb, lo_b, hi_b) = a.per_view[view], b.per_view[view]
        diffs.append(sign * (va - vb))
        # Noise that could make a look better than it is (up) or worse (down), as a gain of a.
        a_worse, a_better = (va - lo_a, hi_a - va) if higher_is_better else (hi_a - va, va - lo_a)
        b_worse, b_better = (vb - lo_b, hi_b - vb) if higher_is_better else (hi_b - vb, vb - lo_b)
        up.append(a_worse + b_better)
        down.append(a_better + b_worse)
    n = len(diffs)
    mean = sum(diffs) / n
    spread = 0.0
    if n >= 2:
        sd = math.sqrt(sum((d - mean) ** 2 for d in diffs) / (n - 1))
        spread = t95(n - 1) * sd / math.sqrt(n)
    return mean, spread + sum(up if mean >= 0 else down) / n


def better_beyond(a: Any, b: Any, *, higher_is_better: bool) -> bool:
    """Whether ``a``'s error is better than ``b``'s beyond the intervals (docs/PROTOCOL.md).

    A paired comparison over the views both were measured on (:func:`paired_difference`): the
    mean per-view difference must exceed Student's t (n − 1 degrees of freedom) times its
    standard error plus the reference-noise half-widths of both (``a``'s towards worse,
    ``b``'s towards better). Points without shared views are compared by their whole intervals.
    """
    mean, half = paired_difference(a, b, higher_is_better=higher_is_better)
    return mean - half > 0.0
