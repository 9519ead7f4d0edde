"""Reading an asset file with trimesh: sidecar files, objects in world space, repairs."""

from __future__ import annotations

import json
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InvalidInputError
from .materials import material_of
from .report import ImportReport


def import_basis(values: dict[str, Any]) -> np.ndarray:
    """(4, 4) world-from-file transform of the ``up`` and ``scale`` parameters."""
    basis = np.eye(4)
    if values["up"] == "z":  # (x, y, z) → (x, z, −y): +Z up becomes +Y up, still right-handed
        basis[:3, :3] = [[1, 0, 0], [0, 0, 1], [0, -1, 0]]
    basis[:3, :3] *= values["scale"]
    return basis


def sidecars(file: Path, label: str) -> list[Path]:
    """Files an OBJ or a .gltf refers to (hashed with it); a glTF's missing ones are errors."""
    found: list[Path] = []
    suffix = file.suffix.lower()
    if suffix == ".gltf":
        try:
            tree = json.loads(file.read_text(encoding="utf-8"))
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise InvalidInputError(f"{label}: not a glTF JSON file ({exc})") from None
        for kind in ("buffers", "images"):
            for entry in tree.get(kind, []) if isinstance(tree, dict) else []:
                uri = entry.get("uri") if isinstance(entry, dict) else None
                if not uri or uri.startswith("data:"):
                    continue
                side = file.parent / _unquote(uri)
                if not side.is_file():
                    raise InvalidInputError(f"{label}: its {kind[:-1]} '{uri}' is missing")
                if kind == "images":
                    _check_image(side, label)
                found.append(side)
    elif suffix == ".obj":
        for mtl in _directives(file, "mtllib"):
            side = file.parent / mtl
            if side.is_file():
                found.append(side)
                for tex in _directives(side, "map_kd", "map_ks", "map_ns", "norm", "map_bump",
                                       "bump"):
                    if (file.parent / tex).is_file():
                        _check_image(file.parent / tex, label)
                        found.append(file.parent / tex)
    return found


def _check_image(path: Path, label: str) -> None:
    """Refuse an image file PIL cannot decode (trimesh would silently drop the texture)."""
    from PIL import Image

    try:
        with Image.open(path) as img:
            img.load()
    except Exception as exc:  # PIL raises several kinds for truncated or foreign data
        raise InvalidInputError(f"{label}: texture '{path.name}' cannot be decoded "
                                f"({type(exc).__name__})") from None


def _unquote(uri: str) -> str:
    from urllib.parse import unquote

    return unquote(uri)


def _directives(file: Path, *keys: str) -> list[str]:
    """The last argument of each line starting with one of ``keys`` (OBJ/MTL statements)."""
    out = []
    with open(file, encoding="utf-8", errors="replace") as handle:
        for line in handle:
            parts = line.strip().split()
            if len(parts) >= 2 and parts[0].lower() in keys:
                out.append(parts[-1])
    return out


def load(file: Path, label: str):
    try:
        import trimesh
    except ImportError:  # a dependency in pyproject; say so plainly if the install lacks it
        raise InvalidInputError(f"{label}: reading scene files needs trimesh (pip install "
                                "trimesh)") from None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            # process=False: no silent vertex merging or NaN removal; we repair and count.
            return trimesh.load_scene(str(file), process=False)
    except Exception as exc:  # trimesh raises many kinds; all mean "cannot read this file"
        detail = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise InvalidInputError(f"{label}: trimesh cannot parse it ({detail[:200]})") from None


def objects_of(tm_scene, values: dict[str, Any], variant: str, label: str,
             report: ImportReport) -> list:
    import trimesh

    from ..scene import SceneObject, TriangleMesh

    basis = import_basis(values)
    objects = []
    names: set[str] = set()
    for node in tm_scene.graph.nodes_geometry:
        transform, geom_name = tm_scene.graph[node]
        geom = tm_scene.geometry[geom_name]
        if not isinstance(geom, trimesh.Trimesh) or len(geom.faces) == 0:
            report.skipped.append(f"{node} ({type(geom).__name__})")
            continue
        positions = np.asarray(geom.vertices, dtype=np.float64)
        if not np.all(np.isfinite(positions)):
            raise InvalidInputError(f"{label}: object '{node}' has NaN/Inf vertex positions")
        world = basis @ np.asarray(transform, dtype=np.float64)
        faces = np.asarray(geom.faces, dtype=np.int64)
        given = "vertex_normals" in geom._cache  # normals the file stored (process=False keeps them)
        normals = np.asarray(geom.vertex_normals, dtype=np.float64) if given else None
        uvs = getattr(geom.visual, "uv", None)
        uvs = None if uvs is None or len(uvs) != len(positions) else np.asarray(uvs, float)
        mesh = _repaired(positions, faces, normals, uvs, world, report)
        if mesh is None:
            report.skipped.append(f"{node} (only degenerate faces)")
            continue
        positions, faces, normals, uvs = mesh
        material = material_of(geom, variant, uvs is not None, report, str(node))
        name = str(node)
        while name in names:
            name += "_"
        names.add(name)
        objects.append(SceneObject(name, TriangleMesh(positions, faces, normals, uvs), material))
    if not objects:
        what = f"only {', '.join(report.skipped)}" if report.skipped else "no geometry"
        raise InvalidInputError(f"{label}: no triangles ({what}; point clouds and lines are "
                                "not surfaces)")
    return objects


def _repaired(positions, faces, normals, uvs, world, report):
    """World-space, repaired arrays ``(positions, faces, normals, uvs)`` or None if empty."""
    from ..geometry import degenerate_faces, remove_duplicate_faces

    linear = world[:3, :3]
    p = positions @ linear.T + world[:3, 3]
    if np.linalg.det(linear) < 0:  # a mirror flips orientation: keep faces front-facing
        faces = faces[:, ::-1]
    bad = degenerate_faces(p, faces)
    report.degenerate_faces += int(bad.sum())
    faces, removed = remove_duplicate_faces(faces[~bad])
    report.duplicate_faces += int(removed)
    if len(faces) == 0:
        return None
    used, inverse = np.unique(faces, return_inverse=True)
    faces = inverse.reshape(-1, 3)
    p = p[used]
    uvs = None if uvs is None else uvs[used]
    edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    report.non_manifold_edges += int(np.sum(counts > 2))
    if normals is not None:
        n = normals[used] @ np.linalg.inv(linear)  # inverse transpose, applied to rows
        length = np.linalg.norm(n, axis=1, keepdims=True)
        normals = n / np.maximum(length, 1e-300) if np.all(length > 1e-12) else None
    if normals is None:
        report.normals_computed += 1
        normals = _angle_weighted_normals(p, faces)
    return p, faces, normals, uvs


def _angle_weighted_normals(p: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(V, 3) unit vertex normals, face normals weighted by the corner angle; isolated: +Y."""
    import trimesh

    corners = trimesh.triangles.angles(p[faces])
    fn = np.cross(p[faces[:, 1]] - p[faces[:, 0]], p[faces[:, 2]] - p[faces[:, 0]])
    fn /= np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-300)
    vn = np.zeros_like(p)
    for k in range(3):
        np.add.at(vn, faces[:, k], fn * corners[:, k:k + 1])
    length = np.linalg.norm(vn, axis=1, keepdims=True)
    return np.where(length > 0, vn / np.maximum(length, 1e-300), [0.0, 1.0, 0.0])
