"""Reading an asset file with trimesh: sidecar files, objects in world space, repairs.

Objects come out in the user's world units and in float64 (:class:`WorldObject`): the scene's
canonical frame is fitted to them before anything is cast to float32
(:mod:`prtbench.scene.frame`), so a file placed 10⁷ from the origin keeps its geometry.
"""

from __future__ import annotations

import base64
import io
import json
import struct
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import unquote

import numpy as np
from PIL import Image

from prtbench.api.errors import InvalidInputError
from prtbench.scene.files.materials import material_of
from prtbench.scene.files.report import ImportReport
from prtbench.scene.frame import Similarity
from prtbench.scene.geometry import degenerate_faces, remove_duplicate_faces
from prtbench.scene.model import Material, SceneObject, TriangleMesh


@dataclass(eq=False)
class WorldObject:
    """An imported, repaired object in the user's world, before the canonical frame.

    Attributes
    ----------
    name : str
    positions : ndarray, shape (V, 3), float64
        World positions (node transform, ``up`` and ``scale`` applied).
    faces : ndarray, shape (F, 3), int
    normals : ndarray, shape (V, 3), float64
        Unit normals (a similarity changes none).
    uvs : ndarray, shape (V, 2), or None
    material : Material
    """

    name: str
    positions: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    uvs: np.ndarray | None
    material: Material

    def placed(self, canonical_from_world: Similarity) -> SceneObject:
        """The scene object, its positions moved to the canonical frame, then cast to float32."""
        mesh = TriangleMesh(canonical_from_world.apply(self.positions), self.faces, self.normals,
                            self.uvs)
        return SceneObject(self.name, mesh, self.material)


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
        _check_embedded_images(tree, None, label)
    elif suffix == ".glb":
        tree, binary = _glb_chunks(file, label)
        _check_embedded_images(tree, binary, label)
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


def _check_image(path: Path | bytes, label: str, name: str | None = None) -> None:
    """Refuse an image (a file, or bytes embedded in a glTF) PIL cannot decode.

    trimesh would silently drop the texture and the scene would render untextured.
    """

    name = name or (path.name if isinstance(path, Path) else "embedded image")
    try:
        with Image.open(path if isinstance(path, Path) else io.BytesIO(path)) as img:
            img.load()
    except Exception as exc:  # PIL raises several kinds for truncated or foreign data
        raise InvalidInputError(f"{label}: texture '{name}' cannot be decoded "
                                f"({type(exc).__name__})") from None


def _glb_chunks(file: Path, label: str) -> tuple[Any, bytes]:
    """The JSON tree and the BIN chunk of a binary glTF (an unparsable file is left to trimesh).

    Layout (glTF 2.0 spec): a 12-byte header (magic ``glTF``, version, length), then chunks of
    (uint32 length, uint32 type, data); the first is JSON, an optional second is BIN.
    """
    raw = file.read_bytes()
    if len(raw) < 20 or raw[:4] != b"glTF":
        return {}, b""
    offset, tree, binary = 12, {}, b""
    while offset + 8 <= len(raw):
        length, kind = struct.unpack_from("<II", raw, offset)
        data = raw[offset + 8:offset + 8 + length]
        if kind == 0x4E4F534A:  # "JSON"
            try:
                tree = json.loads(data.decode("utf-8"))
            except (UnicodeDecodeError, json.JSONDecodeError):
                return {}, b""
        elif kind == 0x004E4942:  # "BIN\0"
            binary = data
        offset += 8 + length
    return tree, binary


def _check_embedded_images(tree: Any, binary: bytes | None, label: str) -> None:
    """Decode every image stored inside a glTF (a bufferView of the GLB's BIN chunk, or a
    ``data:`` URI) and refuse one PIL cannot read."""
    if not isinstance(tree, dict):
        return
    views = tree.get("bufferViews", [])
    for index, image in enumerate(tree.get("images", [])):
        if not isinstance(image, dict):
            continue
        name = image.get("name") or f"image {index}"
        uri = image.get("uri")
        if isinstance(uri, str) and uri.startswith("data:"):
            try:
                data = base64.b64decode(uri.split(",", 1)[1], validate=False)
            except (IndexError, ValueError):
                raise InvalidInputError(f"{label}: texture '{name}' has a malformed data URI") \
                    from None
            _check_image(data, label, name)
        elif "bufferView" in image and binary is not None:
            try:
                view = views[image["bufferView"]]
                start = int(view.get("byteOffset", 0))
                data = binary[start:start + int(view["byteLength"])]
            except (IndexError, KeyError, TypeError, ValueError):
                raise InvalidInputError(f"{label}: texture '{name}' points at a missing "
                                        "bufferView") from None
            _check_image(data, label, name)


def _unquote(uri: str) -> str:
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
               report: ImportReport) -> list[WorldObject]:
    """Every mesh node of ``tm_scene`` as a repaired :class:`WorldObject` (float64 world).

    Raises
    ------
    InvalidInputError
        NaN/Inf vertex positions, coordinates that overflow float64 once transformed, or no
        triangles at all.
    """
    import trimesh

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
        with np.errstate(over="ignore", invalid="ignore"):
            moved = positions @ world[:3, :3].T + world[:3, 3]
        if not np.all(np.isfinite(moved)):
            raise InvalidInputError(
                f"{label}: object '{node}' has non-finite coordinates once its node transform "
                f"and scale={values['scale']:g} are applied; accepted: finite coordinates of "
                "any size")
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
        objects.append(WorldObject(name, positions, faces, normals, uvs, material))
    if not objects:
        what = f"only {', '.join(report.skipped)}" if report.skipped else "no geometry"
        raise InvalidInputError(f"{label}: no triangles ({what}; point clouds and lines are "
                                "not surfaces)")
    return objects


def _repaired(positions, faces, normals, uvs, world, report):
    """World-space, repaired arrays ``(positions, faces, normals, uvs)`` or None if empty."""

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
