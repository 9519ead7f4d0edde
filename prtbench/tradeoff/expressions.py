"""Target and budget expressions of ``prtbench advise`` (``"psnr_masked>=28"``, ``"frame_ms<=33,memory<=256MiB"``).

An expression is a comma-separated list of ``NAME OP VALUE[UNIT]`` fragments, OP one of
``>=``, ``<=``, ``>``, ``<``. NAME is a metric key of :data:`prtbench.bench.metrics.METRICS`, full
frame or masked (``psnr``, ``psnr_masked``, ``flip_masked``, …), or a cost kind (``frame_ms``,
``memory``, ``precompute``, ``ops``). Costs take units and are held in one base unit each:
milliseconds for ``frame_ms`` (``ms``, ``s``), bytes for ``memory`` (``B``, ``KiB``, ``MiB``,
``GiB``), seconds for ``precompute`` (``ms``, ``s``); ``ops`` is a plain count; PSNR accepts
``dB``. Parsing is strict: anything else is one :class:`~prtbench.api.errors.InvalidInputError`
naming the bad fragment and what is accepted. A constraint in the "wrong" direction for its
metric (``flip_masked>=0.1``) is legal and is simply evaluated as written.
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass

from prtbench.api.errors import InvalidInputError, PrtbenchError
from prtbench.bench.metrics import METRICS, higher_is_better

#: Cost kind -> (base unit, accepted units and their factor to the base unit).
COST_UNITS: dict[str, tuple[str, dict[str, float]]] = {
    "frame_ms": ("ms", {"ms": 1.0, "s": 1000.0}),
    "memory": ("B", {"B": 1.0, "KiB": 1024.0, "MiB": 1024.0 ** 2, "GiB": 1024.0 ** 3}),
    "precompute": ("s", {"ms": 1e-3, "s": 1.0}),
    "ops": ("", {}),
}
COSTS = tuple(COST_UNITS)
OPERATORS = (">=", "<=", ">", "<")

_FRAGMENT = re.compile(
    r"^\s*(?P<name>[A-Za-z_][A-Za-z0-9_]*)\s*(?P<op>>=|<=|>|<)\s*"
    r"(?P<value>[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(?P<unit>[A-Za-z]*)\s*$")


def metric_names() -> tuple[str, ...]:
    """Every metric key a target may name: each metric of :mod:`prtbench.bench.metrics`, full and masked."""

    return tuple(key for name in METRICS for key in (name, f"{name}_masked"))


@dataclass(frozen=True)
class Constraint:
    """One ``NAME OP VALUE`` fragment, its value in the base unit of NAME.

    Attributes
    ----------
    name : str
        A metric key (``psnr_masked``) or a cost kind (``frame_ms``).
    op : str
        ``>=``, ``<=``, ``>`` or ``<``.
    value : float
        Threshold in the base unit (ms, bytes, seconds, count, or the metric's own scale).
    text : str
        The fragment as the user wrote it (for messages).
    kind : str
        ``metric`` or ``cost``.
    """

    name: str
    op: str
    value: float
    text: str
    kind: str

    def holds(self, x: float | None) -> bool:
        """Whether measured ``x`` satisfies the constraint (a missing or NaN value never does)."""
        if x is None or not math.isfinite(float(x)):
            return False
        x = float(x)
        return {">=": x >= self.value, "<=": x <= self.value, ">": x > self.value,
                "<": x < self.value}[self.op]

    def shortfall(self, x: float | None) -> float:
        """0 when it holds, else the distance to the threshold relative to it (inf if unmeasured)."""
        if self.holds(x):
            return 0.0
        if x is None or not math.isfinite(float(x)):
            return math.inf
        # A strict inequality met with equality still misses by a hair.
        return max(abs(float(x) - self.value) / max(abs(self.value), 1e-9), 1e-12)

    @property
    def grows_with_model(self) -> bool | None:
        """Does a richer model (more bands, texels, probes) keep this satisfied (True), break
        it (False), or is it not monotone in the model (None)?

        A richer model is assumed more accurate and more expensive: a metric bound in its
        better direction (``psnr>=``, ``flip<=``) stays met, a cost ceiling (``frame_ms<=``)
        stays broken once broken.
        """
        lower_bound = self.op in (">=", ">")
        if self.kind == "cost":
            return None if lower_bound else False

        return lower_bound == higher_is_better(self.name)

    def describe(self) -> str:
        """``psnr_masked >= 28`` with the value in the name's base unit."""
        unit = COST_UNITS[self.name][0] if self.kind == "cost" else ""
        return f"{self.name} {self.op} {self.value:g}{(' ' + unit) if unit else ''}"


def _accepted(kinds: tuple[str, ...]) -> str:
    parts = []
    if "metric" in kinds:
        parts.append(f"metrics {', '.join(metric_names())}")
    if "cost" in kinds:
        parts.append("costs " + ", ".join(
            f"{c} ({'/'.join(u)})" if u else c for c, (_, u) in COST_UNITS.items()))
    return "; ".join(parts) + f"; operators {', '.join(OPERATORS)}"


def _unit_factor(option: str, fragment: str, name: str, unit: str, kinds) -> float:
    if name in COST_UNITS:
        base, units = COST_UNITS[name]
        if not unit:
            return 1.0
        match = {u.lower(): u for u in units}.get(unit.lower())
        if match is None:
            accepted = ", ".join(units) or "none (a plain count)"
            raise InvalidInputError(f"{option} fragment '{fragment}': unit '{unit}' for {name}; "
                                    f"accepted: {accepted}")
        return units[match]
    if unit and not (unit.lower() == "db" and name.startswith("psnr")):
        raise InvalidInputError(f"{option} fragment '{fragment}': metric {name} takes no unit "
                                f"'{unit}'{' (dB only for psnr)' if unit.lower() == 'db' else ''}; "
                                f"accepted: a plain number")
    return 1.0


def parse_constraints(text: str, *, option: str = "--target",
                      kinds: tuple[str, ...] = ("metric", "cost")) -> list[Constraint]:
    """Parse a comma-separated expression into constraints, strictly.

    Parameters
    ----------
    text : str
        E.g. ``"psnr_masked>=28, flip_masked<=0.1"`` or ``"frame_ms<=33,memory<=256MiB"``.
    option : str
        The CLI option it came from, for messages.
    kinds : tuple of str
        What the names may be: ``"metric"``, ``"cost"`` or both.

    Returns
    -------
    list of Constraint
        In the order written.

    Raises
    ------
    InvalidInputError
        An empty expression or fragment, a fragment that does not parse, an unknown name, a
        name of a kind not accepted here, a bad unit, or a negative cost.
    """
    metrics, accepted = metric_names(), _accepted(kinds)
    if not isinstance(text, str) or not text.strip():
        raise InvalidInputError(f"{option} is empty; accepted: NAME OP VALUE[,...] with {accepted}")
    out = []
    for fragment in text.split(","):
        fragment = fragment.strip()
        match = _FRAGMENT.match(fragment)
        if match is None:
            raise InvalidInputError(f"{option} fragment '{fragment}' does not parse; accepted: "
                                    f"NAME OP VALUE[UNIT] (e.g. psnr_masked>=28, memory<=256MiB) "
                                    f"with {accepted}")
        name, op = match["name"], match["op"]
        kind = "metric" if name in metrics else "cost" if name in COST_UNITS else None
        if kind is None or kind not in kinds:
            known = [*(metrics if "metric" in kinds else ()), *(COSTS if "cost" in kinds else ())]
            close = difflib.get_close_matches(name, known, n=1, cutoff=0.6)
            what = "unknown name" if kind is None else f"{kind} not accepted in {option}"
            raise InvalidInputError(f"{option} fragment '{fragment}': {what} '{name}'"
                                    f"{f'; did you mean {close[0]!r}?' if close else ''}; "
                                    f"accepted: {accepted}")
        value = float(match["value"]) * _unit_factor(option, fragment, name, match["unit"], kinds)
        if kind == "cost" and value < 0:
            raise InvalidInputError(f"{option} fragment '{fragment}': negative {name}; accepted: "
                                    "a value >= 0")
        out.append(Constraint(name, op, value, fragment, kind))
    return out


def row_value(row: Mapping, constraint: Constraint, cost_fn) -> float | None:
    """The measured quantity ``constraint`` bounds, from an (aggregated) result row.

    Metrics come from ``row["metrics"]``; costs from ``cost_fn(row, kind)``.
    """
    if constraint.kind == "metric":
        value = (row.get("metrics") or {}).get(constraint.name)
        return None if value is None else float(value)
    try:
        return float(cost_fn(row, constraint.name))
    except PrtbenchError:  # e.g. a cost kind this build cannot compute: the user must see it
        raise
    except (KeyError, TypeError, ValueError):  # a row without that measurement
        return None
