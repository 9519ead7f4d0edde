"""A renderer's ``memory_breakdown`` with the method's own data under readable names.

The engine baselines (AO / bent normals, lightmaps, probe volumes) name what they upload
(``gpu: probe pool (engine, l2, ...)``) so that ``prtbench describe`` and the tests can read,
for example, the bytes per probe; everything else the renderer holds (the mesh's buffers, the
render target, CPU arrays kept for the per-light fold) is found by
:func:`prtbench.api.residency.resident_parts`, so that the GL part of the breakdown is what the
renderer allocated (docs/PROTOCOL.md; a test checks it within 1 %).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from types import SimpleNamespace
from typing import Any

from prtbench.api.residency import resident_parts

#: The attribute under which the named objects are walked first (and then left out).
_NAMED = "__named_parts__"


def named_breakdown(renderer: Any, named: Mapping[str, int],
                    objects: Iterable[Any]) -> dict[str, int]:
    """``named`` (labels with their ``gpu: `` / ``cpu: `` prefix) plus every other resident part.

    Parameters
    ----------
    renderer
        The renderer whose attributes :func:`resident_parts` walks.
    named : mapping of str to int
        The method's own parts, counted by size at upload (so they stay readable after
        :meth:`release`).
    objects : iterable
        The GL objects and arrays counted in ``named``: the walk reaches them first and leaves
        them out, under whatever attribute (or alias) the renderer holds them, so nothing
        counts twice.
    """
    proxy = SimpleNamespace(**{_NAMED: list(objects)})
    proxy.__dict__.update((k, v) for k, v in vars(renderer).items() if k != _NAMED)
    rest = {k: v for k, v in resident_parts(proxy).items()
            if not k.split(": ", 1)[1].startswith(_NAMED)}
    return {**{k: int(v) for k, v in named.items() if v > 0}, **rest}
