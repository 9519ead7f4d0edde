"""Scenes from asset files (DESIGN.md §16): glTF/GLB, OBJ+MTL, PLY, OFF and STL via trimesh.

``get_scene(path, variant=..., scale=..., up=..., ground=...)`` builds a :class:`Scene` of the
same kind as the built-in ones: world-space objects with §4 materials, a 30-view orbit (or the
file's camera), default light ``sky``.

Import
------
- Every mesh node of the file's scene graph becomes one object, its vertices moved by the
  node's ``world_from_object`` transform (normals by its inverse transpose; a mirroring
  transform flips the winding so faces stay front-facing).
- ``up=z`` turns +Z-up files into our +Y up (x, y, z) → (x, z, −y); ``scale`` multiplies
  positions after that. Nothing else is normalised: file units are scene units.
- Repairs, counted in :class:`ImportReport`: degenerate faces (repeated indices or zero area)
  and duplicate faces are removed, unused vertices dropped, vertex normals computed
  (angle-weighted) where the file has none. Non-manifold edges (shared by more than two
  faces) are counted and reported, not fatal. Vertices are never welded (UV seams stay).
- ``ground=true`` adds the papers' two-triangle ground plane (kd 0.6, facing +Y) under the
  bounds, twice the larger horizontal extent wide.

Material mapping onto the one BRDF of §4 (kd, ks, Phong exponent s)
--------------------------------------------------------------------
===================  =====================================================================
source               mapping
===================  =====================================================================
OBJ/MTL              kd = Kd, ks = Ks, s = Ns (clamped to [0, 10⁴]);
                     map_Kd → kd texture (sRGB decoded to linear, times Kd when given)
glTF metallic-       kd = baseColor·(1 − metallic), ks = mix(0.04, baseColor, metallic),
roughness            α = roughness², s = 2/α² − 2 clamped to [1, 10⁴];
                     baseColorTexture → kd texture (sRGB → linear, times the kd factor);
                     normalTexture → normal map; glTF defaults metallic = roughness = 1.
                     metallicRoughnessTexture and emissive are ignored with a warning.
no material          diffuse kd = 0.7; variant ``glossy``: kd = 0.7, ks = 0.3, s = 64
(PLY/OFF/STL, …)     (vertex colours are ignored with a warning)
===================  =====================================================================

The ``diffuse`` variant keeps kd only (ks = 0) for every material, as the built-in scenes'
diffuse variants do, so diffuse-only methods run on any file; ``glossy`` keeps the mapped ks
and s. Colour factors pass through trimesh as 8-bit values (steps of 1/255).

Identity
--------
The scene name is ``<file stem>-<10 hex digits>``: a content hash of the file's bytes, of its
sidecar files (an OBJ's ``.mtl`` and texture maps, a ``.gltf``'s external buffers and images)
and of the import parameters, so every cache keyed by :meth:`Scene.content_hash` (artifacts,
transfer, references) keys on the file's content; ``params`` records the file name and hash
for the results store.
"""

from __future__ import annotations

import hashlib
import json
import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from . import scene_params as P
from .cache import content_key
from .errors import InvalidInputError

#: File suffixes read as scenes (lower case).
SUFFIXES = (".glb", ".gltf", ".obj", ".ply", ".off", ".stl")
#: Bump when the import changes what a file builds (invalidates every file scene's caches).
FILE_SCENE_VERSION = 1
#: Bounds diagonal accepted after ``scale`` (wider than this cannot be right for any asset).
MIN_DIAGONAL, MAX_DIAGONAL = 1e-6, 1e6
#: The import parameters (``--scene-param``), checked by :func:`prtbench.scene_params.check_params`.
PARAMS = {"scale": P.length(low=0.0, high=1e12), "up": P.choice("y", "z"), "ground": P.flag()}
DEFAULTS = {"scale": 1.0, "up": "y", "ground": False}
#: Materials of files without any (DESIGN §4 values).
DEFAULT_KD = 0.7
GLOSSY_DEFAULT = {"kd": 0.7, "ks": 0.3, "shininess": 64.0}
GROUND_KD = 0.6
#: Orbit framing: elevation of the cameras and their vertical field of view.
ORBIT_ELEVATION_DEG, ORBIT_FOV_DEG, ORBIT_VIEWS = 25.0, 45.0, 30


@dataclass
class ImportReport:
    """What importing a file did, for ``prtbench scene info``.

    Attributes
    ----------
    path : str
    sha256 : str
        Hash of the file and its sidecar files.
    sidecars : list of str
        Sidecar files hashed with it.
    degenerate_faces, duplicate_faces, non_manifold_edges : int
        Faces removed, and edges shared by more than two faces (kept).
    normals_computed : int
        Objects whose vertex normals were computed (the file had none).
    skipped : list of str
        Non-triangle geometry left out (point clouds, lines).
    warnings : list of str
        Ignored features (emissive, vertex colours, …).
    cameras : int
        Views taken from the file's cameras.
    """

    path: str
    sha256: str
    sidecars: list[str] = field(default_factory=list)
    degenerate_faces: int = 0
    duplicate_faces: int = 0
    non_manifold_edges: int = 0
    normals_computed: int = 0
    skipped: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    cameras: int = 0


def is_scene_path(name: str) -> bool:
    """Whether ``--scene name`` means a file: an accepted suffix, or a path to an existing file.

    A bare word (``plants``) stays a registry name even if a file of that name exists here.
    """
    text = str(name)
    if text.lower().endswith(SUFFIXES):
        return True
    return ("/" in text or "\\" in text) and Path(text).exists()


def build_file_scene(path: str, *, variant: str = "diffuse", **params: Any):
    """The :class:`~prtbench.scene.Scene` of the asset file ``path``.

    Parameters
    ----------
    path : str
        A .glb/.gltf/.obj/.ply/.off/.stl file.
    variant : {"diffuse", "glossy"}
    **params
        ``scale`` (float > 0), ``up`` ("y" or "z"), ``ground`` (bool); strings are parsed.

    Raises
    ------
    InvalidInputError
        One line naming the file and the problem (see :func:`read_scene_file`).
    """
    return read_scene_file(path, variant=variant, **params)[0]


def read_scene_file(path: str, *, variant: str = "diffuse", **params: Any):
    """Import ``path``; returns ``(scene, report)``. Writes nothing.

    Raises
    ------
    InvalidInputError
        Missing file, unsupported suffix, unknown parameter, a file trimesh cannot parse, a
        glTF whose buffer or image is missing, no triangles, NaN/Inf positions, or a bounds
        diagonal outside [1e-6, 1e6] after ``scale``.
    """
    from .scene import VARIANTS, Scene, SceneObject, Trajectory
    from .scene_params import check_extent, check_params

    file = Path(path)
    label = f"scene file '{path}'"
    if variant not in VARIANTS:
        raise InvalidInputError(f"unknown variant '{variant}'; known: {', '.join(VARIANTS)}")
    for key in params:
        if key not in PARAMS:
            raise InvalidInputError(f"{label} has no parameter '{key}'; accepted: "
                                    f"{', '.join(PARAMS)}")
    values = {**DEFAULTS, **check_params(str(path), PARAMS, params)}
    if file.suffix.lower() not in SUFFIXES:
        raise InvalidInputError(f"{label}: unsupported extension '{file.suffix}'; accepted: "
                                f"{', '.join(SUFFIXES)}")
    if not file.is_file():
        raise InvalidInputError(f"{label}: no such file")
    sidecars = _sidecars(file, label)
    digest = hashlib.sha256()
    for f in [file, *sidecars]:
        digest.update(f.name.encode() + b"\0" + f.read_bytes())
    report = ImportReport(path=str(path), sha256=digest.hexdigest(),
                          sidecars=[str(s) for s in sidecars])

    tm_scene = _load(file, label)
    objects = _objects(tm_scene, values, variant, label, report)
    lo, hi = _bounds(objects)
    diag = float(np.linalg.norm(hi - lo))
    if not MIN_DIAGONAL <= diag <= MAX_DIAGONAL:
        hint = 2.0 / diag if diag > 0 else None
        raise InvalidInputError(
            f"{label}: bounds diagonal {diag:.3g} after scale={values['scale']:g}; accepted: "
            f"{MIN_DIAGONAL:g}..{MAX_DIAGONAL:g}"
            + (f" (hint: --scene-param scale={hint:.3g} makes it about 2)" if hint else ""))
    if values["ground"]:
        objects.append(_ground(lo, hi, variant))
    views = _file_views(tm_scene, values)
    report.cameras = len(views)
    if not views:
        views = _orbit(lo, hi)
    key = content_key("scene-file", FILE_SCENE_VERSION, report.sha256, values)
    name = f"{file.stem}-{key[:10]}"
    scene = Scene(name, objects, variant=variant, default_light="sky",
                  trajectory=Trajectory(tuple(views)), exposure=0.7,
                  params={"file": file.name, "file_sha256": report.sha256, **values})
    check_extent(scene, values)
    return scene, report


# --- reading ----------------------------------------------------------------------------------

def _sidecars(file: Path, label: str) -> list[Path]:
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


def _load(file: Path, label: str):
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


def _objects(tm_scene, values: dict[str, Any], variant: str, label: str,
             report: ImportReport) -> list:
    import trimesh

    from .scene import SceneObject, TriangleMesh

    basis = np.eye(4)
    if values["up"] == "z":
        basis[:3, :3] = [[1, 0, 0], [0, 0, 1], [0, -1, 0]]
    basis[:3, :3] *= values["scale"]
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
        material = _material(geom, variant, uvs is not None, report, str(node))
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
    from .geometry import degenerate_faces, remove_duplicate_faces

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


# --- materials --------------------------------------------------------------------------------

def _srgb_to_linear(c: np.ndarray) -> np.ndarray:
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def _image(img, name: str, *, srgb: bool, factor=None):
    """A :class:`Texture` from a PIL image (flipped so row 0 is v = 0), or None."""
    from .scene import Texture

    if img is None:
        return None
    try:
        rgb = np.asarray(img.convert("RGB"), dtype=np.float32) / 255.0
    except Exception as exc:  # PIL raises on truncated or undecodable data
        raise InvalidInputError(f"texture '{name}' cannot be decoded ({exc})") from None
    rgb = _srgb_to_linear(rgb) if srgb else rgb
    if factor is not None:
        rgb = rgb * np.asarray(factor, dtype=np.float32)[:3]
    return Texture(np.ascontiguousarray(np.clip(rgb[::-1], 0.0, 1.0)), name=name)


def _rgb(value, default: float) -> tuple[float, float, float]:
    if value is None:
        return (default,) * 3
    v = np.asarray(value, dtype=np.float64).ravel()[:3]
    if np.asarray(value).dtype == np.uint8 or v.max() > 1.0:
        v = v / 255.0
    return tuple(float(c) for c in np.clip(v, 0.0, 1.0))


def _material(geom, variant: str, has_uv: bool, report: ImportReport, node: str):
    from trimesh.visual.material import PBRMaterial, SimpleMaterial

    from .scene import Material

    visual = geom.visual
    mat = getattr(visual, "material", None)
    glossy = variant == "glossy"
    if isinstance(mat, PBRMaterial):
        return _pbr(mat, glossy, has_uv, report, node)
    if isinstance(mat, SimpleMaterial):
        return _mtl(mat, glossy, has_uv, report, node)
    if getattr(visual, "kind", None) in ("vertex", "face"):
        report.warnings.append(f"{node}: vertex/face colours ignored (default material)")
    if glossy:
        g = GLOSSY_DEFAULT
        return Material(kd=(g["kd"],) * 3, ks=(g["ks"],) * 3, shininess=g["shininess"],
                        name="default-glossy")
    return Material(kd=(DEFAULT_KD,) * 3, name="default")


def _mtl(mat, glossy: bool, has_uv: bool, report: ImportReport, node: str):
    from .scene import Material

    extra = getattr(mat, "kwargs", {}) or {}
    kd = _rgb(extra["kd"], 1.0) if "kd" in extra else _rgb(mat.diffuse, 1.0)
    ks = _rgb(extra["ks"], 0.0) if "ks" in extra else (0.0, 0.0, 0.0)
    ns = float(extra.get("ns", mat.glossiness if mat.glossiness is not None else 1.0))
    name = str(mat.name or node)
    kd_value: Any = kd
    if mat.image is not None:
        if has_uv:
            kd_value = _image(mat.image, f"{name}:map_Kd", srgb=True,
                              factor=kd if "kd" in extra else None)
        else:
            report.warnings.append(f"{node}: map_Kd ignored (no texture coordinates)")
    if not glossy:
        return Material(kd=kd_value, name=name)
    return Material(kd=kd_value, ks=ks, shininess=float(np.clip(ns, 0.0, 1e4)), name=name)


def phong_exponent(roughness: float) -> float:
    """Phong exponent of a glTF roughness: α = r², s = 2/α² − 2, clamped to [1, 10⁴]."""
    alpha = max(float(roughness), 0.0) ** 2
    if alpha <= 0.0:
        return 1e4
    return float(np.clip(2.0 / alpha ** 2 - 2.0, 1.0, 1e4))


def _pbr(mat, glossy: bool, has_uv: bool, report: ImportReport, node: str):
    from .scene import Material

    name = str(mat.name or node)
    base = np.asarray(_rgb(mat.baseColorFactor, 1.0))
    metallic = 1.0 if mat.metallicFactor is None else float(np.clip(mat.metallicFactor, 0, 1))
    if mat.metallicFactor is None:
        report.warnings.append(f"{node}: no metallicFactor, glTF's default 1 (metal) gives kd 0")
    roughness = 1.0 if mat.roughnessFactor is None else float(np.clip(mat.roughnessFactor, 0, 1))
    kd = tuple(float(c) for c in base * (1.0 - metallic))
    ks = tuple(float(c) for c in 0.04 * (1.0 - metallic) + base * metallic)
    kd_value: Any = kd
    normal_map = None
    if getattr(mat, "baseColorTexture", None) is not None:
        if has_uv:
            kd_value = _image(mat.baseColorTexture, f"{name}:baseColor", srgb=True, factor=kd)
        else:
            report.warnings.append(f"{node}: baseColorTexture ignored (no texture coordinates)")
    if getattr(mat, "normalTexture", None) is not None and has_uv:
        normal_map = _image(mat.normalTexture, f"{name}:normal", srgb=False)
    if getattr(mat, "metallicRoughnessTexture", None) is not None:
        report.warnings.append(f"{node}: metallicRoughnessTexture ignored (factors used)")
    emissive = getattr(mat, "emissiveFactor", None)
    if getattr(mat, "emissiveTexture", None) is not None or (
            emissive is not None and np.any(np.asarray(emissive) > 0)):
        report.warnings.append(f"{node}: emission ignored (no emitters in the radiance model)")
    if not glossy:
        return Material(kd=kd_value, normal_map=normal_map, name=name)
    return Material(kd=kd_value, ks=ks, shininess=phong_exponent(roughness),
                    normal_map=normal_map, name=name)


# --- ground and views -------------------------------------------------------------------------

def _bounds(objects) -> tuple[np.ndarray, np.ndarray]:
    pts = np.concatenate([o.mesh.positions for o in objects]).astype(np.float64)
    return pts.min(axis=0), pts.max(axis=0)


def _ground(lo: np.ndarray, hi: np.ndarray, variant: str):
    from .geometry import grid_plane
    from .scene import Material, SceneObject

    extent = hi - lo
    size = 2.0 * float(max(extent[0], extent[2], 0.5 * extent[1]))
    center = ((lo[0] + hi[0]) / 2, float(lo[1]), (lo[2] + hi[2]) / 2)
    return SceneObject("ground", grid_plane(size, 1, center=center),
                       Material(kd=(GROUND_KD,) * 3, name="ground"))


def _file_views(tm_scene, values: dict[str, Any]) -> list:
    """The file's perspective camera (trimesh reads the first one), in our world frame."""
    from .scene import View

    try:
        if not tm_scene.has_camera:
            return []
        camera = tm_scene.camera
        world_from_camera = np.asarray(tm_scene.camera_transform, dtype=np.float64)
    except Exception:  # no (complete) camera in the file
        return []
    basis = np.eye(4)
    if values["up"] == "z":
        basis[:3, :3] = [[1, 0, 0], [0, 0, 1], [0, -1, 0]]
    basis[:3, :3] *= values["scale"]
    m = basis @ world_from_camera
    eye = m[:3, 3]
    back = m[:3, 2] / np.linalg.norm(m[:3, 2])
    up = m[:3, 1] / np.linalg.norm(m[:3, 1])
    fov_y = float(camera.fov[1])
    if not 1.0 <= fov_y <= 170.0:
        return []
    return [View(eye=tuple(map(float, eye)), target=tuple(map(float, eye - back)),
                 up=tuple(map(float, up)), fov_y=fov_y)]


def _orbit(lo: np.ndarray, hi: np.ndarray) -> list:
    """30 views on a circle above the bounds' centre, framing their bounding sphere."""
    from .scene import Trajectory

    center = (lo + hi) / 2
    radius = float(np.linalg.norm(hi - lo)) / 2
    # The bounding sphere fills the vertical field of view at the centre's depth (closer than
    # the fully-enclosing R / sin(fov/2); a box's corners seldom reach its sphere).
    distance = radius / math.tan(math.radians(ORBIT_FOV_DEG / 2))
    elevation = math.radians(ORBIT_ELEVATION_DEG)
    return list(Trajectory.orbit(center=tuple(map(float, center)),
                                 radius=distance * math.cos(elevation),
                                 height=distance * math.sin(elevation), n_views=ORBIT_VIEWS,
                                 fov_y=ORBIT_FOV_DEG, start_degrees=20.0).views)
