"""Readers for the mesh formats of the pinned assets (DESIGN.md §12).

* PLY (optionally gzipped) and OFF: read by trimesh (the project's mesh library, also behind
  scenes from files, DESIGN.md §16), vertex order kept, polygons triangulated by trimesh.
* The ``snowden`` npm package's ``lo.js`` / ``hi.js``: base64 little-endian Float32 positions
  and Uint32 cells.
* The ``teapot`` npm package's ``teapot.js``: JavaScript array literals of positions and cells.

Every reader returns ``(positions (V, 3) float64, faces (F, 3) int64)``.
"""

from __future__ import annotations

import base64
import gzip
import io
import json
import re
from pathlib import Path

import numpy as np

from prtbench.api.errors import InvalidInputError

Mesh = tuple[np.ndarray, np.ndarray]


def _check(path: Path, positions: np.ndarray, faces: np.ndarray) -> Mesh:
    if len(faces) and (faces.min() < 0 or faces.max() >= len(positions)):
        raise InvalidInputError(
            f"mesh file {path}: face index outside its {len(positions)} vertices")
    return positions.astype(np.float64), faces.astype(np.int64)


# --- PLY and OFF, through trimesh -------------------------------------------------------------

def _read_with_trimesh(path: Path, file_type: str) -> Mesh:
    """``(positions, faces)`` of a PLY/OFF file as trimesh reads it, vertex order kept.

    ``process=False`` keeps the file's vertices and faces as stored (no merging, no removal:
    the scene builders repair meshes themselves, with counts); polygons come back
    triangulated by trimesh. Gzipped files are decompressed first (the Stanford dragon ships
    as ``.ply.gz``).
    """
    import trimesh

    raw = path.read_bytes()
    if raw[:2] == b"\x1f\x8b":
        raw = gzip.decompress(raw)
    try:
        mesh = trimesh.load_mesh(io.BytesIO(raw), file_type=file_type, process=False)
    except Exception as exc:  # trimesh raises many types for a malformed file
        raise InvalidInputError(f"mesh file {path}: trimesh cannot parse it as "
                                f"{file_type.upper()} ({type(exc).__name__}: {exc})") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise InvalidInputError(f"mesh file {path}: no triangles (a point cloud or an empty "
                                f"{file_type.upper()} file)")
    return _check(path, np.asarray(mesh.vertices), np.asarray(mesh.faces))


def read_ply(path: str | Path) -> Mesh:
    """Read a (gzipped) PLY triangle/polygon mesh (any PLY encoding trimesh reads)."""
    return _read_with_trimesh(Path(path), "ply")


def read_off(path: str | Path) -> Mesh:
    """Read an OFF polygon mesh (comments and per-face colours ignored)."""
    return _read_with_trimesh(Path(path), "off")


# --- JavaScript packages ----------------------------------------------------------------------

def read_snowden_js(path: str | Path) -> Mesh:
    """Read the ``snowden`` package's ``lo.js`` / ``hi.js`` (base64 Float32 / Uint32 arrays)."""
    path = Path(path)
    text = path.read_text()
    pattern = r'exports\.(positions|cells)\s*=\s*require\("\./load"\)\(\w+,\s*"([^"]*)"'
    found = dict(re.findall(pattern, text))
    if set(found) != {"positions", "cells"}:
        raise InvalidInputError(f"{path}: expected base64 'positions' and 'cells' exports")
    positions = np.frombuffer(base64.b64decode(found["positions"]), dtype="<f4").reshape(-1, 3)
    faces = np.frombuffer(base64.b64decode(found["cells"]), dtype="<u4").reshape(-1, 3)
    return _check(path, positions.astype(np.float64), faces.astype(np.int64))


def read_teapot_js(path: str | Path) -> Mesh:
    """Read the ``teapot`` package's ``teapot.js`` (JSON array literals of positions, cells)."""
    path = Path(path)
    text = path.read_text()
    arrays = {}
    for name in ("positions", "cells"):
        match = re.search(r"exports\." + name + r"\s*=\s*(\[.*?\]\])", text, flags=re.S)
        if not match:
            raise InvalidInputError(f"{path}: no 'exports.{name}' array")
        arrays[name] = np.asarray(json.loads(match.group(1)))
    return _check(path, arrays["positions"].astype(np.float64),
                  arrays["cells"].astype(np.int64).reshape(-1, 3))


def read_mesh(path: str | Path) -> Mesh:
    """Read any supported mesh file, chosen by its name."""
    name = Path(path).name.lower()
    if name.endswith((".ply", ".ply.gz")):
        return read_ply(path)
    if name.endswith(".off"):
        return read_off(path)
    if name.startswith("teapot") and name.endswith(".js"):
        return read_teapot_js(path)
    if name.endswith(".js"):
        return read_snowden_js(path)
    raise InvalidInputError(f"unknown mesh format '{name}'; accepted: .ply, .ply.gz, .off, "
                            "snowden .js, teapot.js")
