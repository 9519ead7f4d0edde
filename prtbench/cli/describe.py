"""``prtbench describe METHOD``: a method's summary, paper and every knob of its config.

The knob rows come from :func:`prtbench.api.config.describe` (name, default, docstring); the type
and the accepted values are read from the same dataclass fields and their :func:`knob`
metadata, so what is printed is what ``--set KEY=VALUE`` accepts.
"""

from __future__ import annotations

import argparse
import dataclasses
import textwrap
import typing
from typing import Any

from prtbench.api import config as config_mod
from prtbench.api.method import METHODS


def type_name(tp: Any) -> str:
    """Readable name of a field's type: ``int``, ``float | None``, ``tuple[int, ...]``."""
    if isinstance(tp, type) and not typing.get_args(tp):
        return tp.__name__
    return str(tp).replace("typing.", "").replace("NoneType", "None")


def accepted(field: dataclasses.Field, tp: Any = None) -> str:
    """What a knob accepts, from its :func:`prtbench.api.config.knob` metadata and type."""
    meta = field.metadata
    if tp is bool:
        return "true, false"
    if meta.get("choices"):
        return ", ".join(map(str, meta["choices"]))
    low, high = meta.get("low"), meta.get("high")
    if low is not None and high is not None:
        return f"[{_number(low)}, {_number(high)}]"
    if low is not None:
        return f">= {_number(low)}"
    if high is not None:
        return f"<= {_number(high)}"
    return "any"


def _number(x: float) -> str:
    # Exact, not %g: a bound of 1 << 20 must read 1048576, not 1.04858e+06.
    return str(int(x)) if float(x).is_integer() and abs(x) < 1e15 else repr(x)


def _value(value: Any) -> str:
    # Spelled as --set takes it: a tuple as comma-separated items, an empty string as ''.
    if isinstance(value, (tuple, list)):
        return ",".join(map(str, value))
    return "''" if value == "" else str(value)


def knob_rows(config_cls: type) -> list[dict[str, str]]:
    """One row per knob: ``name``, ``type``, ``default``, ``accepted``, ``doc`` (all strings)."""
    hints = typing.get_type_hints(config_cls)
    fields = {f.name: f for f in dataclasses.fields(config_cls)}
    return [{"name": name, "type": type_name(hints.get(name, Any)), "default": _value(default),
             "accepted": accepted(fields[name], hints.get(name)), "doc": " ".join(doc.split())}
            for name, default, doc in config_mod.describe(config_cls)]


def format_method(name: str, method: Any, *, width: int = 100) -> str:
    """The text of ``prtbench describe NAME`` for a :class:`prtbench.api.method.Method` class."""
    rows = knob_rows(method.Config)
    lines = [f"{name}: {method.summary or '(no summary)'}",
             f"paper: {method.paper or '(none given)'}",
             f"knobs ({len(rows)}, set with --set KEY=VALUE; {method.Config.__name__}):"]
    columns = ("name", "type", "default", "accepted")
    widths = {c: max([len(c)] + [len(r[c]) for r in rows]) for c in columns}
    lines.append("  " + "  ".join(c.ljust(widths[c]) for c in columns).rstrip())
    for row in rows:
        lines.append("  " + "  ".join(row[c].ljust(widths[c]) for c in columns).rstrip())
        lines += textwrap.wrap(row["doc"], width=width, initial_indent="      ",
                               subsequent_indent="      ")
    overrides = getattr(method, "profile_overrides", {}) or {}
    if overrides:
        lines.append("profile overrides (applied before --set):")
        for profile, values in overrides.items():
            pairs = " ".join(f"{k}={_value(v)}" for k, v in values.items()) or "(none)"
            lines += textwrap.wrap(f"{profile}: {pairs}", width=width, initial_indent="  ",
                                   subsequent_indent="      ", break_on_hyphens=False)
    return "\n".join(lines)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("method")


def run(args: argparse.Namespace) -> int:
    print(format_method(args.method, METHODS.get(args.method)))
    return 0
