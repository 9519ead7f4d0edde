"""Registries with lazy entries.

A registry maps a name to an object (a scene builder, a light, a method class, a table). Entries
are registered eagerly with the :meth:`Registry.register` decorator when their module is
imported, or declared lazily as ``"module:attr"`` strings, which come from

* *spec modules* a registry discovers itself (``discover``: built-in methods declare theirs in
  ``methods/<family>/spec.py``, see :mod:`prtbench.api.plugins`), each entry with a one-line
  summary, so listing names and summaries imports no plug-in code at all;
* the package entry-point group ``prtbench.<kind>s`` (``pyproject.toml`` of this or another
  distribution: plug-ins from outside, and the built-in scenes, lights and reproductions).

Listing names never imports a lazy module, so ``prtbench list`` stays instant and free of
torch, moderngl, embreex and mitsuba.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Iterable, Iterator
from importlib import metadata
from typing import Generic, TypeVar

from prtbench.api.errors import PrtbenchError, UnknownNameError

T = TypeVar("T")


class Registry(Generic[T]):
    """A name -> object map whose entries may be lazy ``"module:attr"`` references.

    Parameters
    ----------
    kind
        What the entries are ("scene", "method", ...), used in error messages.
    entry_point_group
        Package entry-point group whose entries are added lazily, e.g. ``"prtbench.methods"``.
    discover
        Called once, on first use, for further lazy entries: an iterable of
        ``(name, "module:attr", summary)`` (e.g. :func:`prtbench.api.plugins.method_specs`).
    """

    def __init__(self, kind: str, *, entry_point_group: str | None = None,
                 discover: Callable[[], Iterable[tuple[str, str, str]]] | None = None):
        self.kind = kind
        self._objects: dict[str, T] = {}
        self._lazy: dict[str, str] = {}
        self._summaries: dict[str, str] = {}
        self._group = entry_point_group
        self._discover = discover
        self._loaded = entry_point_group is None and discover is None

    def _load(self) -> None:
        if self._loaded:
            return
        self._loaded = True
        if self._discover is not None:
            for name, target, summary in self._discover():
                if name in self._lazy and self._lazy[name] != target:
                    raise PrtbenchError(f"{self.kind} '{name}' is declared twice: by "
                                        f"{self._lazy[name]} and by {target}")
                self._lazy[name] = target
                self._summaries[name] = summary
        if self._group is not None:
            for ep in metadata.entry_points(group=self._group):
                self._lazy.setdefault(ep.name, ep.value)

    def register(self, name: str) -> Callable[[T], T]:
        """Decorator registering ``obj`` under ``name`` (duplicate names are an error)."""

        def decorator(obj: T) -> T:
            if name in self._objects and self._objects[name] is not obj:
                raise ValueError(f"{self.kind} '{name}' registered twice")
            self._objects[name] = obj
            return obj

        return decorator

    def add_lazy(self, name: str, target: str, summary: str | None = None) -> None:
        """Declare ``name`` as provided by ``"module:attr"``, imported on first use."""
        self._lazy[name] = target
        if summary is not None:
            self._summaries[name] = summary

    def names(self) -> list[str]:
        """All names, sorted, without importing any lazy module."""
        self._load()
        return sorted(set(self._objects) | set(self._lazy))

    def __contains__(self, name: object) -> bool:
        return name in self.names()

    def __iter__(self) -> Iterator[str]:
        return iter(self.names())

    def target(self, name: str) -> str | None:
        """The ``"module:attr"`` a lazy entry points to (None for an eager one)."""
        self._load()
        return self._lazy.get(name)

    def get(self, name: str) -> T:
        """The object for ``name``; an :class:`UnknownNameError` lists the known names."""
        self._load()
        if name not in self._objects:
            if name not in self._lazy:
                raise UnknownNameError(self.kind, name, self.names())
            module_name, _, attr = self._lazy[name].partition(":")
            module = importlib.import_module(module_name)
            # The module's decorator normally registered the object on import; else attr.
            if name not in self._objects:
                self._objects[name] = getattr(module, attr)
        obj = self._objects[name]
        # A spec names a class: the two must agree (a typo would register a method twice).
        declared = getattr(obj, "name", name) if name in self._summaries else name
        if declared != name:
            raise PrtbenchError(f"{self.kind} '{name}' ({self._lazy.get(name)}) calls itself "
                                f"'{declared}'; the spec and the class must agree")
        if name in self._summaries and isinstance(obj, type) and not obj.__dict__.get("summary"):
            obj.summary = self._summaries[name]  # the spec's line is the one summary
        return obj

    def summaries(self, attribute: str = "summary") -> dict[str, str]:
        """``name -> one line``: a spec's summary, else each entry's ``attribute``.

        Entries declared by a spec are not imported; others are (their modules must not import
        torch, moderngl, embreex or mitsuba at module level). An entry whose module cannot be
        imported gets the import error's first line instead, so one broken plug-in does not
        hide the others.
        """
        out = {}
        for name in self.names():
            if name in self._summaries and name not in self._objects:
                out[name] = " ".join(self._summaries[name].split())
                continue
            try:
                text = getattr(self.get(name), attribute, "")
            except ImportError as exc:
                first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
                text = f"(cannot import: {first})"
            out[name] = " ".join(str(text or "").split())
        return out

    def check(self, name: str) -> str:
        """Validate ``name`` without importing anything; returns it."""
        if name not in self.names():
            raise UnknownNameError(self.kind, name, self.names())
        return name
