"""Strict configuration dataclasses.

Every method (and every other configurable piece) declares a ``Config`` dataclass whose fields
are its knobs, each documented with :func:`knob`. Configs are built only through
:func:`from_dict` / :func:`with_overrides`, which reject unknown keys and values that do not
parse as the field's type, naming the key and the accepted ones.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import typing
from collections.abc import Iterable, Mapping
from typing import Any, TypeVar

from prtbench.api.errors import InvalidInputError, UnknownNameError

C = TypeVar("C")


def knob(default: Any, doc: str, *, choices: Iterable[Any] | None = None, low: float | None = None,
         high: float | None = None) -> Any:
    """A documented dataclass field with optional accepted choices or numeric bounds."""
    meta = {"doc": doc, "choices": tuple(choices) if choices is not None else None,
            "low": low, "high": high}
    if isinstance(default, (list, dict)):
        return dataclasses.field(default_factory=lambda: type(default)(default), metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


#: Seeds go to numpy, torch and Mitsuba; Mitsuba's are uint32.
SEED_HIGH = 2**32 - 1


def seed_knob(doc: str, default: int = 0) -> Any:
    """A random-seed knob: integers in [0, 2³² − 1] (what every RNG here accepts)."""
    return knob(default, doc, low=0, high=SEED_HIGH)


def memory_budget() -> int:
    """Bytes one run may take: this machine's physical memory (16 GiB if unknown)."""
    try:
        return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (ValueError, OSError, AttributeError):
        return 16 << 30


def format_bytes(n: float) -> str:
    """``n`` bytes as a short string (``74.5 GiB``)."""
    for unit, size in (("TiB", 1 << 40), ("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)):
        if n >= size:
            return f"{n / size:.1f} {unit}"
    return f"{int(n)} B"


def check_memory(what: str, need: float, *, accepted: str = "", budget: int | None = None,
                 ) -> None:
    """Refuse a configuration whose memory estimate ``need`` (bytes) exceeds the budget.

    Parameters
    ----------
    what : str
        The values that make the estimate, e.g. a method's name and ``texture_resolution=8192``.
    need : float
        Estimated bytes.
    accepted : str
        What would fit (appended to the message), e.g. ``"texture_resolution <= 5000"``.
    budget : int, optional
        Bytes available (default :func:`memory_budget`).
    """
    budget = memory_budget() if budget is None else budget
    if need > budget:
        fits = f"{accepted} " if accepted else ""
        raise InvalidInputError(f"{what} would need {format_bytes(need)}; accepted: {fits}"
                                f"(≤ {format_bytes(budget)}, this machine's memory)")


def _coerce(cls: type, field: dataclasses.Field, value: Any) -> Any:
    hints = typing.get_type_hints(cls)
    tp = hints.get(field.name, Any)
    origin = typing.get_origin(tp)
    args = [a for a in typing.get_args(tp) if a is not type(None)]
    if origin in (typing.Union, getattr(__import__("types"), "UnionType", None)) and args:
        if value is None or (isinstance(value, str) and value.lower() == "none"):
            return None
        tp = args[0]
    bad = InvalidInputError(
        f"config key '{field.name}' of {cls.__name__} expects {getattr(tp, '__name__', tp)}, "
        f"got {value!r}")
    try:
        if tp is bool:
            if isinstance(value, str):
                low = value.lower()
                if low not in ("true", "false", "1", "0", "yes", "no", "on", "off"):
                    raise bad
                value = low in ("true", "1", "yes", "on")
            elif not isinstance(value, (bool, int)):
                raise bad
            value = bool(value)
        elif tp is int:
            if isinstance(value, float) and not value.is_integer():
                raise bad
            value = int(value)
        elif tp is float:
            value = float(value)
        elif tp is str:
            value = str(value)
        elif typing.get_origin(tp) is tuple or tp is tuple:
            if isinstance(value, str):
                value = json.loads(value) if value.startswith("[") else value.split(",")
            inner = typing.get_args(tp)
            value = tuple(inner[0](v) if inner else v for v in value)
    except (TypeError, ValueError, json.JSONDecodeError) as exc:
        if isinstance(exc, InvalidInputError):
            raise
        raise bad from None
    meta = field.metadata
    if meta.get("choices") and value not in meta["choices"]:
        raise InvalidInputError(
            f"config key '{field.name}' of {cls.__name__} got {value!r}; "
            f"accepted: {', '.join(map(str, meta['choices']))}")
    # Bounds apply to a number, or to each element of a tuple of numbers.
    items = value if isinstance(value, tuple) else (value,)
    if isinstance(value, float) and not math.isfinite(value) and (
            meta.get("low") is not None or meta.get("high") is not None):
        raise InvalidInputError(
            f"config key '{field.name}' of {cls.__name__} got {value!r}; accepted: finite "
            f"numbers in [{meta.get('low')}, {meta.get('high')}]")
    for bound, ok in (("low", lambda v, b: v >= b), ("high", lambda v, b: v <= b)):
        b = meta.get(bound)
        if b is not None and value is not None and not all(ok(v, b) for v in items):
            raise InvalidInputError(
                f"config key '{field.name}' of {cls.__name__} got {value!r}; accepted: "
                f"[{meta.get('low')}, {meta.get('high')}]")
    return value


def from_dict(cls: type[C], values: Mapping[str, Any] | None = None) -> C:
    """Build ``cls`` from ``values``; unknown keys and unparsable values are errors."""
    values = dict(values or {})
    fields = {f.name: f for f in dataclasses.fields(cls)}
    for key in values:
        if key not in fields:
            raise UnknownNameError(f"config key for {cls.__name__}", key, fields)
    kwargs = {k: _coerce(cls, fields[k], v) for k, v in values.items()}
    base = cls(**kwargs)
    # Validate defaults too (keeps choices/bounds honest).
    for f in dataclasses.fields(cls):
        if f.name not in kwargs:
            _coerce(cls, f, getattr(base, f.name))
    return base


def parse_overrides(pairs: Iterable[str]) -> dict[str, str]:
    """Parse ``["key=value", ...]`` (the CLI's ``--set``) into a dict of strings."""
    out: dict[str, str] = {}
    for pair in pairs:
        key, sep, value = pair.partition("=")
        if not sep or not key:
            raise InvalidInputError(f"--set expects key=value, got '{pair}'")
        out[key.strip()] = value.strip()
    return out


def with_overrides(config: C, overrides: Mapping[str, Any]) -> C:
    """A copy of ``config`` with ``overrides`` applied strictly."""
    merged = {**to_dict(config), **dict(overrides)}
    return from_dict(type(config), merged)


def to_dict(config: Any) -> dict[str, Any]:
    """Plain JSON-able dict of a config dataclass."""
    return {f.name: (list(v) if isinstance(v := getattr(config, f.name), tuple) else v)
            for f in dataclasses.fields(config)}


def describe(cls: type) -> list[tuple[str, Any, str]]:
    """``(name, default, doc)`` for each knob of a config class."""
    rows = []
    for f in dataclasses.fields(cls):
        default = f.default if f.default is not dataclasses.MISSING else f.default_factory()
        rows.append((f.name, default, f.metadata.get("doc", "")))
    return rows
