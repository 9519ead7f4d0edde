"""What a renderer keeps resident, found on the renderer itself, and what it allocated.

:func:`resident_parts` walks a renderer's attributes (and the helper objects, lists and dicts
they hold) for the things that take memory while it draws the next frame: GL buffers,
textures, texture arrays, 3-D textures and renderbuffers (``gpu: <path>``), NumPy arrays and
torch tensors and modules (``cpu: <path>`` or ``gpu: <path>`` by device). Each object counts
once, under the first path that reaches it. The scene, the GL context and compiled programs
are not the renderer's memory (the application holds the scene anyway; programs are driver
state); everything else is. :meth:`prtbench.api.method.Renderer.memory_breakdown` reports it by default. Objects are
recognised by their type's module and name, so this module imports no backend.

:class:`AllocationLog` records every GL object a context allocates while it is open, so a test
can check the walk against what was really allocated (docs/PROTOCOL.md: every resident byte is
counted, within 1 %).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

#: Attributes a walk never enters: the scene (the application's), the GL context and programs.
SKIPPED = frozenset({"scene", "ctx", "program", "programs", "prepared", "config", "light"})
#: Arrays smaller than this are bookkeeping, not resident data.
MIN_ARRAY_BYTES = 1024
#: How deep the walk follows helper objects.
MAX_DEPTH = 5
_DTYPE_BYTES = {"f1": 1, "u1": 1, "i1": 1, "f2": 2, "u2": 2, "i2": 2, "f4": 4, "u4": 4, "i4": 4,
                "f8": 8}


def gl_object_bytes(obj: Any) -> int | None:
    """Bytes of a live moderngl buffer, texture or renderbuffer; None for anything else (and
    for a released object)."""
    name = type(obj).__name__
    if type(obj).__module__.split(".")[0] != "moderngl":
        return None
    if type(getattr(obj, "mglo", None)).__name__ == "InvalidObject":
        return None  # released
    if name == "Buffer":
        return int(obj.size)
    texel = int(getattr(obj, "components", 0) or 0) * _DTYPE_BYTES.get(
        str(getattr(obj, "dtype", "")), 0)
    if name in ("Texture", "Renderbuffer"):
        w, h = obj.size
        return int(w) * int(h) * texel * max(1, int(getattr(obj, "samples", 0) or 1))
    if name in ("TextureArray", "Texture3D"):
        w, h, d = obj.size
        return int(w) * int(h) * int(d) * texel
    if name == "TextureCube":
        w, h = obj.size
        return 6 * int(w) * int(h) * texel
    return None


def _tensor_part(obj: Any) -> tuple[str, int] | None:
    module = type(obj).__module__.split(".")[0]
    if module != "torch":
        return None
    if hasattr(obj, "parameters") and hasattr(obj, "buffers"):  # an nn.Module
        tensors = list(obj.parameters()) + list(obj.buffers())
    elif hasattr(obj, "element_size") and hasattr(obj, "nelement"):
        tensors = [obj]
    else:
        return None
    if not tensors:
        return None
    where = "gpu" if any(getattr(t, "is_cuda", False) for t in tensors) else "cpu"
    return where, int(sum(t.element_size() * t.nelement() for t in tensors))


def resident_parts(root: Any) -> dict[str, int]:
    """``{"gpu: transfer_buffer": bytes, "cpu: transport.values": bytes, ...}`` of ``root``."""
    parts: dict[str, int] = {}
    seen: set[int] = set()

    def visit(obj: Any, path: str, depth: int) -> None:
        if id(obj) in seen or obj is None or isinstance(obj, (str, bytes, int, float, bool)):
            return
        seen.add(id(obj))
        size = gl_object_bytes(obj)
        if size is not None:
            parts[f"gpu: {path}"] = parts.get(f"gpu: {path}", 0) + size
            return
        if isinstance(obj, np.ndarray):
            base = obj.base if isinstance(obj.base, np.ndarray) else None
            if obj.nbytes >= MIN_ARRAY_BYTES and (base is None or id(base) not in seen):
                parts[f"cpu: {path}"] = parts.get(f"cpu: {path}", 0) + int(obj.nbytes)
                if base is not None:
                    seen.add(id(base))  # a second view of the same memory counts once
            return
        tensor = _tensor_part(obj)
        if tensor is not None:
            where, size = tensor
            if hasattr(obj, "parameters"):
                for t in list(obj.parameters()) + list(obj.buffers()):
                    seen.add(id(t))
            parts[f"{where}: {path}"] = parts.get(f"{where}: {path}", 0) + size
            return
        if type(obj).__name__ == "VertexArray" and isinstance(getattr(obj, "extra", None), dict):
            # prtbench.render.gl.upload_mesh keeps the mesh's vertex and index buffers here.
            visit(obj.extra.get("buffers"), f"{path}.buffers", depth + 1)
            return
        if depth >= MAX_DEPTH or type(obj).__module__.split(".")[0] in ("moderngl", "glcontext"):
            return
        if isinstance(obj, dict):
            for key, value in obj.items():
                visit(value, f"{path}[{key}]" if isinstance(key, (str, int)) else path, depth + 1)
        elif isinstance(obj, (list, tuple, set, frozenset)):
            for i, value in enumerate(obj):
                visit(value, f"{path}[{i}]", depth + 1)
        elif hasattr(obj, "__dict__") and type(obj).__module__.split(".")[0] in (
                "prtbench", "methods") or hasattr(obj, "__dataclass_fields__"):
            for key, value in vars(obj).items():
                if key not in SKIPPED:
                    visit(value, f"{path}.{key}" if path else key, depth + 1)

    for key, value in vars(root).items():
        if key not in SKIPPED:
            visit(value, key, 0)
    return {k: v for k, v in parts.items() if v > 0}


class AllocationLog:
    """Every GL buffer, texture and renderbuffer a context allocated while the log was open."""

    METHODS = ("buffer", "texture", "depth_texture", "texture_array", "texture3d",
               "texture_cube", "renderbuffer", "depth_renderbuffer")

    def __init__(self) -> None:
        self.objects: list[Any] = []

    def alive_bytes(self) -> int:
        """Bytes of the logged objects not released since."""
        return int(sum(gl_object_bytes(o) or 0 for o in self.objects))


@contextmanager
def allocation_log() -> Iterator[AllocationLog]:
    """Record what every moderngl context allocates inside the ``with`` block."""
    import moderngl

    log = AllocationLog()
    originals = {name: getattr(moderngl.Context, name) for name in AllocationLog.METHODS
                 if hasattr(moderngl.Context, name)}

    def recording(original):
        def create(self, *args, **kwargs):
            obj = original(self, *args, **kwargs)
            log.objects.append(obj)
            return obj
        return create

    for name, original in originals.items():
        setattr(moderngl.Context, name, recording(original))
    try:
        yield log
    finally:
        for name, original in originals.items():
            setattr(moderngl.Context, name, original)
