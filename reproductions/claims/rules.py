"""Rules: how a claim's measured cases become a verdict (:class:`prtbench.bench.claims.Decision`).

Every rule decides case by case (a scene, a configuration, a pair), then aggregates: all cases
reproduced is ``reproduced``; at least half of them the opposite way is ``contradicted``;
anything between is ``direction only``. The bands are stated in each verdict's text.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence

from prtbench.bench.claims import (
    CONTRADICTED,
    DIRECTION,
    REPRODUCED,
    Decision,
    Estimate,
    Measured,
    Missing,
)


def _case_sign(case: Estimate, *, band: tuple[float | None, float | None] | None,
               resolution: float) -> str:
    """``reproduced``, ``direction`` or ``opposite`` for one case oriented so that > 0 is the
    paper's direction."""
    if not math.isfinite(case.value):
        raise Missing(f"case {case.label or '?'} has no finite value")
    if case.value <= -resolution:
        return "opposite"
    # Beyond the interval; a case without one is beyond only a stated resolution (> 0), never
    # on its point value alone.
    beyond = (case.lo > resolution if case.lo is not None
              else resolution > 0 and case.value > resolution)
    lo, hi = band if band is not None else (None, None)
    inside = (lo is None or case.value >= lo) and (hi is None or case.value <= hi)
    return "reproduced" if beyond and inside else ("opposite" if case.value < 0 else "direction")


def _aggregate(kinds: Sequence[str], cases: Sequence[Estimate], why: str, *,
               unresolved: bool = False) -> Decision:
    """All reproduced: ``reproduced``; at least half opposite: ``contradicted`` (saying so when
    an opposite case's interval still reaches the paper's side); else ``direction only``."""
    if not kinds:
        raise Missing("no case to decide on")
    opposite = sum(k == "opposite" for k in kinds)
    if all(k == "reproduced" for k in kinds):
        return Decision(REPRODUCED, why)
    if 2 * opposite >= len(kinds):
        return Decision(CONTRADICTED, why + ("; the opposite direction is not resolved beyond "
                                             "every interval" if unresolved else ""))
    return Decision(DIRECTION, why + f"; {sum(k == 'reproduced' for k in kinds)} of "
                                     f"{len(kinds)} cases meet it")


def same_sign(*, band: tuple[float | None, float | None] | None = None, resolution: float = 0.0,
              what: str = "the difference") -> Callable[[Measured], Decision]:
    """Each case is oriented so that > 0 is the paper's direction (a difference, a log ratio).

    A case reproduces when it is positive beyond its interval (and beyond ``resolution``, the
    smallest difference the measurement resolves) and inside ``band`` (lo, hi; None = open);
    a case that carries no interval reproduces only beyond a stated ``resolution`` > 0, and is
    otherwise at most ``direction only``; it contradicts when at or below ``-resolution``. All cases reproduced: ``reproduced``; at
    least half contradicting: ``contradicted``; otherwise ``direction only``.
    """
    lo, hi = band if band is not None else (None, None)
    why = (f"{what} > 0" + (f" beyond the interval and {resolution:g}" if resolution else
                            " beyond the interval")
           + (f", within [{'-∞' if lo is None else f'{lo:g}'}, {'∞' if hi is None else f'{hi:g}'}]"
              if band is not None else ""))

    def rule(measured: Measured) -> Decision:
        kinds = [_case_sign(c, band=band, resolution=resolution) for c in measured.cases]
        unresolved = any(k == "opposite" and c.hi is not None and c.hi >= 0
                         for k, c in zip(kinds, measured.cases))
        bare = sum(c.lo is None for c in measured.cases)
        note = (f" ({bare} of {len(kinds)} case{'s' if len(kinds) != 1 else ''} without a "
                "stored interval: at most direction only)" if bare and not resolution else "")
        return _aggregate(kinds, measured.cases, why + note, unresolved=unresolved)

    return rule


def ratio_within(paper: float | Mapping[str, float], *, factor: float
                 ) -> Callable[[Measured], Decision]:
    """Each case is a ratio of ours, compared with the paper's ratio (one, or by case label).

    Reproduced within a factor ``factor`` of the paper's; direction only on the paper's side of
    1; contradicted on the other side.
    """

    def paper_of(label: str) -> float:
        value = paper.get(label) if isinstance(paper, Mapping) else paper
        if value is None:
            raise Missing(f"no paper ratio for case '{label}'")
        return float(value)

    def rule(measured: Measured) -> Decision:
        kinds, oriented = [], []
        for case in measured.cases:
            expected = paper_of(case.label)
            if not (case.value > 0 and math.isfinite(case.value)):
                raise Missing(f"case {case.label or '?'}: ratio {case.value} is not positive")
            sign = 1.0 if expected >= 1.0 else -1.0
            o = Estimate(sign * math.log(case.value), label=case.label)
            kinds.append("reproduced" if abs(math.log(case.value / expected)) <= math.log(factor)
                         else ("direction" if o.value > 0 else "opposite"))
            oriented.append(o)
        return _aggregate(kinds, oriented, f"ratio within ×{factor:g} of the paper's, on its "
                                           "side of 1")

    return rule


def in_range(lo: float, hi: float, *, direction: tuple[float, float]
             ) -> Callable[[Measured], Decision]:
    """Each case reproduces inside [lo, hi], keeps the direction inside ``direction`` (a wider
    range), and contradicts outside it."""

    def rule(measured: Measured) -> Decision:
        kinds = []
        for case in measured.cases:
            if not math.isfinite(case.value):
                raise Missing(f"case {case.label or '?'} has no finite value")
            kinds.append("reproduced" if lo <= case.value <= hi else
                         "direction" if direction[0] <= case.value <= direction[1] else "opposite")
        return _aggregate(kinds, measured.cases, f"value in [{lo:g}, {hi:g}] (direction: "
                                                 f"[{direction[0]:g}, {direction[1]:g}])")

    return rule


def within_tolerance(tolerance: float, *, what: str = "") -> Callable[[Measured], Decision]:
    """A claim of equality: |value| ≤ ``tolerance`` reproduces; beyond it but with an interval
    reaching the tolerance is direction only; beyond it and its interval contradicts.

    ``what`` states the band in words (default ``|value| ≤ tolerance``).
    """

    def rule(measured: Measured) -> Decision:
        kinds = []
        for case in measured.cases:
            lo = case.lo if case.lo is not None else case.value
            hi = case.hi if case.hi is not None else case.value
            kinds.append("reproduced" if abs(case.value) <= tolerance else
                         "direction" if lo <= tolerance and hi >= -tolerance else "opposite")
        return _aggregate(kinds, measured.cases, what or f"|value| ≤ {tolerance:g}")

    return rule


def near_ratio(factor: float) -> Callable[[Measured], Decision]:
    """A magnitude claim: each case is ln(ours / paper); reproduced within a factor ``factor``
    either way, contradicted outside it."""
    return within_tolerance(math.log(factor), what=f"ours within ×{factor:.3g} of the paper's "
                                                   "value either way")


def near_paper(paper: Mapping[str, float], *, tolerance: float, floor: float
               ) -> Callable[[Measured], Decision]:
    """Each case (by label) reproduces within ``tolerance`` of the paper's value (its interval
    reaching the band counts), keeps the direction at or above ``floor`` (the level the claim
    asserts, e.g. "high PSNR"), and contradicts below it."""

    def rule(measured: Measured) -> Decision:
        kinds = []
        for case in measured.cases:
            if case.label not in paper:
                raise Missing(f"no paper value for case '{case.label}'")
            expected = float(paper[case.label])
            lo = case.lo if case.lo is not None else case.value
            hi = case.hi if case.hi is not None else case.value
            kinds.append("reproduced" if lo <= expected + tolerance and hi >= expected - tolerance
                         else "direction" if case.value >= floor else "opposite")
        return _aggregate(kinds, measured.cases, f"within {tolerance:g} of the paper's value "
                                                 f"(direction: at least {floor:g})")

    return rule
