"""User-facing errors.

Every mistake a user can make (an unknown name, a bad value, a missing asset) raises a
:class:`PrtbenchError` whose message is one line naming the bad value and what is accepted.
The CLI prints that line and exits with status 2; it never shows a traceback for these.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable


class PrtbenchError(Exception):
    """A user-facing error: one line, naming the bad value and what is accepted."""

    exit_code = 2


class UnknownNameError(PrtbenchError, KeyError):
    """An unknown registry name (scene, light, method, metric, table, config key)."""

    def __init__(self, kind: str, name: str, known: Iterable[str]):
        known = sorted(known)
        self.kind, self.name, self.known = kind, name, known
        close = difflib.get_close_matches(name, known, n=1, cutoff=0.5)
        hint = f"; did you mean '{close[0]}'?" if close else ""
        super().__init__(f"unknown {kind} '{name}'{hint} known: {', '.join(known) or '(none)'}")

    def __str__(self) -> str:  # KeyError would quote the message otherwise
        return self.args[0]


class AssetMissingError(PrtbenchError):
    """An asset-backed scene was asked for before its asset was fetched."""


class InvalidInputError(PrtbenchError, ValueError):
    """A value outside what is accepted (bad texels, degenerate inputs, bad CLI values)."""
