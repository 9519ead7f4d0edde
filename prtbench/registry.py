"""Registries with lazy entries.

A registry maps a name to an object (a scene builder, a light, a method class, a table). Entries
are either registered eagerly with the :meth:`Registry.register` decorator when their module is
imported, or declared lazily as ``"module:attr"`` strings, normally through the package
entry-point group ``prtbench.<kind>s`` in ``pyproject.toml``. Listing names never imports a lazy
module, so ``prtbench list`` stays instant and free of torch, moderngl, embreex and mitsuba.
:meth:`Registry.summaries` does import the entries' modules, which is cheap because plug-in
modules import their heavy backends inside the functions that use them (a test checks it).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Iterator
from importlib import metadata
from typing import Generic, TypeVar

from .errors import UnknownNameError

T = TypeVar("T")


class Registry(Generic[T]):
    """A name -> object map whose entries may be lazy ``"module:attr"`` references.

    Parameters
    ----------
    kind
        What the entries are ("scene", "method", ...), used in error messages.
    entry_point_group
        Package entry-point group whose entries are added lazily, e.g. ``"prtbench.methods"``.
    """

    def __init__(self, kind: str, *, entry_point_group: str | None = None):
        self.kind = kind
        self._objects: dict[str, T] = {}
        self._lazy: dict[str, str] = {}
        self._group = entry_point_group
        self._group_loaded = entry_point_group is None

    def _load_group(self) -> None:
        if self._group_loaded:
            return
        self._group_loaded = True
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

    def add_lazy(self, name: str, target: str) -> None:
        """Declare ``name`` as provided by ``"module:attr"``, imported on first use."""
        self._lazy[name] = target

    def names(self) -> list[str]:
        """All names, sorted, without importing any lazy module."""
        self._load_group()
        return sorted(set(self._objects) | set(self._lazy))

    def __contains__(self, name: object) -> bool:
        return name in self.names()

    def __iter__(self) -> Iterator[str]:
        return iter(self.names())

    def get(self, name: str) -> T:
        """The object for ``name``; an :class:`UnknownNameError` lists the known names."""
        if name in self._objects:
            return self._objects[name]
        self._load_group()
        if name not in self._lazy:
            raise UnknownNameError(self.kind, name, self.names())
        module_name, _, attr = self._lazy[name].partition(":")
        module = importlib.import_module(module_name)
        # The module's decorator normally registered the object on import; fall back to attr.
        if name not in self._objects:
            self._objects[name] = getattr(module, attr)
        return self._objects[name]

    def summaries(self, attribute: str = "summary") -> dict[str, str]:
        """``name -> one line``: each entry's ``attribute`` (e.g. a method class's ``summary``).

        Imports every lazy module, which must not import torch, moderngl, embreex or mitsuba at
        module level. An entry whose module cannot be imported gets the import error's first
        line instead, so one broken plug-in does not hide the others.
        """
        out = {}
        for name in self.names():
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
