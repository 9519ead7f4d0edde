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
  positions after that: it states the file's unit (``scale=0.001`` for millimetres in metres),
  which ``Scene.world_from_canonical`` and the stored rows record.
- Canonical frame (DESIGN.md §22, :mod:`prtbench.scene.frame`): the world positions are read
  and transformed in float64, then the scene (its ground and views too) is centred and scaled
  to a bounds diagonal of 2 before it is cast to float32. The image therefore depends neither
  on ``scale`` nor on where the file places the scene: millimetres or kilometres, at the
  origin or 10⁷ from it. Only non-finite coordinates and zero extent are refused.
- Repairs, counted in :class:`ImportReport`: degenerate faces (repeated indices or zero area)
  and duplicate faces are removed, unused vertices dropped, vertex normals computed
  (angle-weighted) where the file has none. Non-manifold edges (shared by more than two
  faces) are counted and reported, not fatal. Vertices are never welded (UV seams stay).
- A file with more triangles than this machine's memory holds through a run (512 B each,
  the built-in scenes' estimate) is refused naming the limit (:func:`check_triangles`).
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

import dataclasses
import hashlib
from pathlib import Path
from typing import Any

import numpy as np

from prtbench.api import config
from prtbench.api.cache import content_key
from prtbench.api.errors import InvalidInputError
from prtbench.scene import params as P
from prtbench.scene.files.materials import DEFAULT_KD, GLOSSY_DEFAULT, phong_exponent
from prtbench.scene.files.reader import load, objects_of, sidecars
from prtbench.scene.files.report import ImportReport
from prtbench.scene.files.views import file_views, ground, ground_bounds, orbit
from prtbench.scene.frame import bounds_of, canonical_from_world, with_frame
from prtbench.scene.model import VARIANTS, Scene, Trajectory
from prtbench.scene.params import check_extent, check_params

__all__ = ["SUFFIXES", "PARAMS", "DEFAULT_KD", "GLOSSY_DEFAULT", "ImportReport",
           "build_file_scene", "check_triangles", "is_scene_path", "phong_exponent",
           "read_scene_file", "scene_files"]

#: File suffixes read as scenes (lower case).
SUFFIXES = (".glb", ".gltf", ".obj", ".ply", ".off", ".stl")
#: Bump when the import changes what a file builds (invalidates every file scene's caches).
#: 2: the canonical frame.
FILE_SCENE_VERSION = 2
#: The import parameters (``--scene-param``), checked by :func:`prtbench.scene.params.check_params`.
PARAMS = {"scale": P.length(low=0.0, high=1e12), "up": P.choice("y", "z"), "ground": P.flag()}
DEFAULTS = {"scale": 1.0, "up": "y", "ground": False}


def is_scene_path(name: str) -> bool:
    """Whether ``--scene name`` means a file: an accepted suffix, or a path to an existing file.

    A bare word (``plants``) stays a registry name even if a file of that name exists here.
    """
    text = str(name)
    if text.lower().endswith(SUFFIXES):
        return True
    return ("/" in text or "\\" in text) and Path(text).exists()


def check_triangles(label: str, n_triangles: int, *, budget: int | None = None) -> None:
    """Refuse a file whose triangles exceed what a run can hold in ``budget`` bytes.

    The same estimate as the built-in scenes' geometry parameters
    (:data:`prtbench.scene.params.BYTES_PER_TRIANGLE` bytes per triangle through a run, against
    :func:`prtbench.api.config.memory_budget`), so the limit is stated in triangles; methods with
    their own limits (a per-vertex matrix's ``max_bytes``) check them in ``validate``.

    Raises
    ------
    InvalidInputError
        One line naming the file, its triangles and the largest accepted count.
    """

    budget = config.memory_budget() if budget is None else budget
    config.check_memory(f"{label} with {n_triangles} triangles",
                        float(n_triangles) * P.BYTES_PER_TRIANGLE, budget=budget,
                        accepted=f"at most {budget // P.BYTES_PER_TRIANGLE} triangles")


def build_file_scene(path: str, *, variant: str = "diffuse", **params: Any):
    """The :class:`~prtbench.scene.model.Scene` of the asset file ``path``.

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


def scene_files(path: str) -> list[Path]:
    """The files of ``--scene path``: one file, or several joined with ``+``.

    ``chair.glb+table.obj`` combines two files into one scene. A path that exists as a file is
    always that one file, even if its name contains ``+``.
    """
    text = str(path)
    if "+" not in text or Path(text).is_file():
        return [Path(text)]
    return [Path(part) for part in text.split("+")]


def read_scene_file(path: str, *, variant: str = "diffuse", **params: Any):
    """Import ``path`` (one file, or several joined with ``+``); returns ``(scene, report)``.

    Several files are one scene: their objects side by side (in each file's own coordinates,
    after the same ``scale`` and ``up``), object names prefixed by the file's stem, views from
    the first file that has a camera, identity hashed over every file in order. Writes nothing.

    Raises
    ------
    InvalidInputError
        Missing file, unsupported suffix, unknown parameter, a file trimesh cannot parse, a
        glTF whose buffer or image is missing, no triangles, NaN/Inf positions, more
        triangles than this machine's memory holds through a run (:func:`check_triangles`),
        or bounds with non-finite coordinates or zero extent
        (:func:`prtbench.scene.params.check_extent`).
    """

    files = scene_files(path)
    label = f"scene file '{path}'"
    if variant not in VARIANTS:
        raise InvalidInputError(f"unknown variant '{variant}'; known: {', '.join(VARIANTS)}")
    for key in params:
        if key not in PARAMS:
            raise InvalidInputError(f"{label} has no parameter '{key}'; accepted: "
                                    f"{', '.join(PARAMS)}")
    values = {**DEFAULTS, **check_params(str(path), PARAMS, params)}
    for file in files:
        own = f"scene file '{file}'"
        if file.suffix.lower() not in SUFFIXES:
            raise InvalidInputError(f"{own}: unsupported extension '{file.suffix}'; accepted: "
                                    f"{', '.join(SUFFIXES)} (join several files with '+')")
        if not file.is_file():
            raise InvalidInputError(f"{own}: no such file")
    report = ImportReport(path=str(path), sha256="")
    digest = hashlib.sha256()
    objects, views = [], []
    for file in files:
        own = f"scene file '{file}'"
        extra = sidecars(file, own)
        for f in [file, *extra]:
            digest.update(f.name.encode() + b"\0" + f.read_bytes())
        report.sidecars += [str(s) for s in extra]
        tm_scene = load(file, own)
        found = objects_of(tm_scene, values, variant, own, report)
        if len(files) > 1:  # node names repeat across files ("geometry_0")
            found = [dataclasses.replace(o, name=f"{file.stem}/{o.name}") for o in found]
        objects += found
        views = views or file_views(tm_scene, values)
    report.sha256 = digest.hexdigest()
    check_triangles(label, sum(len(o.faces) for o in objects))
    key = content_key("scene-file", FILE_SCENE_VERSION, report.sha256, values)
    name = f"{'+'.join(f.stem for f in files)}-{key[:10]}"
    # Bounds in the user's world, float64: of the objects, and with the ground under them.
    lo, hi = bounds_of([o.positions for o in objects])
    every_lo, every_hi = lo, hi
    if values["ground"]:
        ground_lo, ground_hi = ground_bounds(lo, hi)
        every_lo, every_hi = np.minimum(lo, ground_lo), np.maximum(hi, ground_hi)
    check_extent(name, every_lo, every_hi, {"file": str(path), **values})
    canonical = canonical_from_world(every_lo, every_hi)
    placed = [o.placed(canonical) for o in objects]
    if values["ground"]:  # the ground commutes with the frame: built from canonical bounds
        placed.append(ground(canonical.apply(lo), canonical.apply(hi), variant))
    report.cameras = len(views)
    views = ([canonical.view(v) for v in views] if views
             else orbit(canonical.apply(lo), canonical.apply(hi)))
    world_from_canonical = canonical.inverse()
    params = {"file": "+".join(f.name for f in files), "file_sha256": report.sha256, **values}
    scene = Scene(name, placed, variant=variant, default_light="sky",
                  trajectory=Trajectory(tuple(views)), exposure=0.7,
                  params=with_frame(params, world_from_canonical),
                  world_from_canonical=world_from_canonical)
    return scene, report
