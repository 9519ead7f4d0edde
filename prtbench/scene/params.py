"""Declared scene-builder parameters: type, accepted range and memory estimate.

Scene builders take keyword parameters (``--scene-param key=value`` on the command line). Each
registered builder declares its parameters once, with :func:`register_scene`'s ``params``, as
:class:`SceneParam` objects built by :func:`length`, :func:`count`, :func:`seed`,
:func:`real`, :func:`flag` or :func:`choice`. :func:`check_params` then checks every value in
one place, before anything is built: the type, finiteness, the range, and for parameters that
grow the geometry an upper bound derived from memory (a value whose estimate exceeds the
machine's memory is refused naming the bytes, instead of failing deep inside numpy).

After a scene is built, :func:`check_extent` refuses what no frame can render: bounds with
non-finite coordinates or zero extent. Any other size and position is accepted: the scene is
then rendered in its canonical frame (:mod:`prtbench.scene.frame`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from prtbench.api import config as config_mod
from prtbench.api.config import SEED_HIGH as CONFIG_SEED_HIGH
from prtbench.api.config import format_bytes
from prtbench.api.errors import InvalidInputError
from prtbench.scene.frame import diagonal

#: Resident bytes one triangle costs through a run. Measured (ru_maxrss) on a 2M-triangle
#: plane: 117 B/triangle for the build, 231 with the Embree tracer, 320 with the Mitsuba
#: scene; rounded up to leave room for a method's per-vertex transfer.
BYTES_PER_TRIANGLE = 512

#: Largest length a scene builder's parameter accepts (:func:`length`). Scenes themselves have
#: no size limit (they are rendered in their canonical frame); this bounds the builders' inputs.
MAX_DIAGONAL = 1e6
#: Seeds go to numpy, torch and Mitsuba; Mitsuba's are uint32.
SEED_HIGH = CONFIG_SEED_HIGH


@dataclass(frozen=True)
class SceneParam:
    """A scene builder parameter's type and accepted values.

    Attributes
    ----------
    kind : type
        ``int``, ``float``, ``bool`` or ``str``.
    low, high : float or None
        Inclusive bounds (``low_open``: ``low`` itself excluded).
    low_open : bool
    choices : tuple or None
        Accepted values for strings.
    triangles : callable or None
        Triangles the value builds (upper estimate), for the memory bound.
    extra_bytes : callable or None
        Other bytes the value allocates (e.g. a marching-cubes grid).
    """

    kind: type
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    choices: tuple[Any, ...] | None = None
    triangles: Callable[[float], float] | None = None
    extra_bytes: Callable[[float], float] | None = None

    def bytes(self, value: float) -> float:
        """Estimated bytes for ``value`` (0 without an estimate)."""
        total = 0.0
        if self.triangles is not None:
            total += float(self.triangles(value)) * BYTES_PER_TRIANGLE
        if self.extra_bytes is not None:
            total += float(self.extra_bytes(value))
        return total

    def memory_high(self, budget: int) -> int | None:
        """Largest integer value whose estimate fits ``budget`` (None without an estimate)."""
        if self.triangles is None and self.extra_bytes is None:
            return None
        lo = int(self.low if self.low is not None else 0)
        hi = int(self.high) if self.high is not None else 1 << 40
        if self.bytes(hi) <= budget:
            return hi
        if self.bytes(lo) > budget:
            return lo - 1
        while hi - lo > 1:  # estimates grow with the value: bisect
            mid = (lo + hi) // 2
            lo, hi = (mid, hi) if self.bytes(mid) <= budget else (lo, mid)
        return lo

    def accepted(self, budget: int) -> str:
        """The accepted values, for error messages."""
        if self.choices is not None:
            return ", ".join(map(str, self.choices))
        if self.kind is bool:
            return "true or false"
        high = self.high
        mem = self.memory_high(budget) if self.kind is int else None
        if mem is not None:
            high = mem if high is None else min(high, mem)
        if self.kind is int:
            text = f"integers {int(self.low) if self.low is not None else '-inf'}.." \
                   f"{int(high) if high is not None else 'inf'}"
        else:
            left = "(" if self.low_open else "["
            low = "-inf" if self.low is None else f"{self.low:g}"
            text = f"finite numbers in {left}{low}, {'inf' if high is None else f'{high:g}'}]"
        if mem is not None:
            text += f" (≤ {format_bytes(budget)}, this machine's memory)"
        return text


def length(*, low: float = 0.0, high: float = MAX_DIAGONAL) -> SceneParam:
    """A positive, finite length (size, radius, height) in scene units."""
    return SceneParam(float, low=low, high=high, low_open=True)


def count(*, low: int = 1, high: int | None = None,
          triangles: Callable[[float], float] | None = None,
          extra_bytes: Callable[[float], float] | None = None) -> SceneParam:
    """An integer count (subdivisions, segments); ``triangles`` bounds it by memory."""
    return SceneParam(int, low=low, high=high, triangles=triangles, extra_bytes=extra_bytes)


def grid_subdivisions() -> SceneParam:
    """Quads per side k of a grid plane: 2·k² triangles."""
    return count(triangles=lambda k: 2.0 * k * k)


def seed(*, high: int = SEED_HIGH) -> SceneParam:
    """A random seed in [0, ``high``] (default 2³² − 1)."""
    return SceneParam(int, low=0, high=high)


def real(*, low: float | None = None, high: float | None = None) -> SceneParam:
    """A finite float in [low, high]."""
    return SceneParam(float, low=low, high=high)


def flag() -> SceneParam:
    """A boolean."""
    return SceneParam(bool)


def choice(*values: str) -> SceneParam:
    """One of ``values``."""
    return SceneParam(str, choices=tuple(values))


def _parse(scene: str, key: str, value: Any, spec: SceneParam, budget: int) -> Any:
    bad = InvalidInputError(f"scene '{scene}' parameter {key}={value!r}; accepted: "
                            f"{spec.accepted(budget)}")
    if spec.kind is bool:
        if isinstance(value, str):
            low = value.strip().lower()
            if low not in ("true", "false", "1", "0", "yes", "no"):
                raise bad
            return low in ("true", "1", "yes")
        if isinstance(value, (bool, np.bool_)) or value in (0, 1):
            return bool(value)
        raise bad
    if spec.kind is str:
        if not isinstance(value, str) or (spec.choices is not None and value not in spec.choices):
            raise bad
        return value
    try:
        number = float(value.strip()) if isinstance(value, str) else float(value)
    except (TypeError, ValueError):
        raise bad from None
    if isinstance(value, bool) or not math.isfinite(number):
        raise bad
    if spec.kind is int:
        if not number.is_integer():
            raise bad
        number = int(number)
    if spec.low is not None and (number < spec.low or (spec.low_open and number == spec.low)):
        raise bad
    if spec.high is not None and number > spec.high:
        raise bad
    need = spec.bytes(number)
    if need > budget:
        tris = f"{spec.triangles(number):.3g} triangles " if spec.triangles is not None else ""
        raise InvalidInputError(
            f"scene '{scene}' parameter {key}={value!r} would build {tris}"
            f"({format_bytes(need)}); accepted: {spec.accepted(budget)}")
    return number


def check_params(scene: str, specs: Mapping[str, SceneParam], values: Mapping[str, Any], *,
                 budget: int | None = None) -> dict[str, Any]:
    """``values`` parsed and checked against ``specs`` (keys without a spec pass unchanged).

    Raises
    ------
    InvalidInputError
        A value of the wrong type, not finite, outside its range or too large for memory
        (one line naming the parameter, the value and what is accepted).
    """
    budget = config_mod.memory_budget() if budget is None else budget
    return {key: (_parse(scene, key, value, specs[key], budget) if key in specs else value)
            for key, value in values.items()}


def check_extent(name: str, lo: np.ndarray, hi: np.ndarray, params: Mapping[str, Any]) -> None:
    """Refuse world bounds that no frame can render: non-finite coordinates or zero extent.

    Every other size and position is accepted: the scene is rendered in its canonical frame
    (:mod:`prtbench.scene.frame`), which is fitted from these bounds in float64.

    Parameters
    ----------
    name : str
        The scene (named in the message).
    lo, hi : ndarray, shape (3,)
        The scene's bounds in the user's world, float64.
    params : mapping
        The parameters it was built with (named in the message).

    Raises
    ------
    InvalidInputError
        One line naming the scene, its parameters, the bounds and what is accepted: non-finite
        coordinates, or a bounds diagonal that is zero (every vertex at one point) or too small
        for float64 to scale (below its smallest normal number, 2.2e-308).
    """
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    shown = ", ".join(f"{k}={v!r}" for k, v in params.items()) or "defaults"
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
        raise InvalidInputError(
            f"scene '{name}' ({shown}) has non-finite coordinates (bounds {_triple(lo)} .. "
            f"{_triple(hi)}); accepted: finite coordinates of any size")
    diag = diagonal(lo, hi)
    tiny = float(np.finfo(np.float64).tiny)
    if not diag >= tiny:
        where = (f"every vertex at {_triple(lo)}" if diag == 0.0
                 else f"below float64's smallest normal number {tiny:.3g}")
        raise InvalidInputError(
            f"scene '{name}' ({shown}) has zero extent (bounds diagonal {diag:.3g}: {where}); "
            "accepted: a bounds diagonal > 0 (of any size)")
    if not math.isfinite(diag):
        raise InvalidInputError(
            f"scene '{name}' ({shown}) has bounds diagonal {diag:.3g} (bounds {_triple(lo)} .. "
            f"{_triple(hi)}); accepted: a finite bounds diagonal")


def _triple(v: np.ndarray) -> str:
    return "(" + ", ".join(f"{c:.6g}" for c in v) + ")"
