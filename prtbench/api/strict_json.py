"""Strict JSON text for the results store and ``summary.json`` (DESIGN.md §10).

Python's :mod:`json` writes ``NaN`` and ``Infinity`` as bare tokens, which SQLite's
``json_extract`` and every strict parser reject. Every row and summary prtbench writes goes
through :func:`dumps`, which writes a non-finite float as ``null``; the row's ``status`` and
``status_reason`` say why a value is missing.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any


def finite_or_none(value: Any) -> Any:
    """``value`` with every non-finite float (NaN, ±inf, numpy scalars too) replaced by None.

    Mappings, lists and tuples are walked; numpy scalars and arrays become Python values.
    """
    if hasattr(value, "tolist") and type(value).__module__ == "numpy":
        value = value.tolist()  # numpy scalar or array: Python float/int/list
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, Mapping):
        return {key: finite_or_none(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [finite_or_none(item) for item in value]
    return value


def _default(value: Any) -> Any:
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"{type(value).__name__} is not JSON-serialisable")


def dumps(value: Any, **options: Any) -> str:
    """Strict JSON text of ``value``: non-finite floats as ``null``, never ``NaN``/``Infinity``.

    ``options`` go to :func:`json.dumps` (``sort_keys``, ``indent``); ``allow_nan`` is always
    False, so a non-finite value that escaped conversion raises rather than being written.
    """
    return json.dumps(finite_or_none(value), allow_nan=False, default=_default, **options)


def non_finite_keys(values: Mapping[str, Any]) -> list[str]:
    """Keys of ``values`` whose float value is NaN or infinite, in order, as ``key=value``."""
    out = []
    for key, value in values.items():
        try:
            number = float(value)
        except (TypeError, ValueError):
            continue
        if not math.isfinite(number):
            out.append(f"{key}={number}")
    return out
