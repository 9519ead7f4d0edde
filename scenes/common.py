"""Pieces shared by the scene builders: material pairs, asset meshes, scene assembly."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from prtbench.api.cache import cached_arrays, content_key
from prtbench.api.errors import InvalidInputError
from prtbench.io.assets import ASSETS, asset_path
from prtbench.io.meshio import read_mesh
from prtbench.scene.geometry import (
    degenerate_faces,
    fill_holes,
    remove_duplicate_faces,
    weld_vertices,
)
from prtbench.scene.model import (
    VARIANTS,
    Material,
    Scene,
    SceneObject,
    Trajectory,
    TriangleMesh,
    vertex_normals,
)
from scenes.primitives import outward, rotate_y, transformed, translate

#: Bump when asset-mesh reading or normalisation changes (invalidates cached normalised meshes).
#: 4: PLY/OFF read by trimesh, which keeps a PLY ``float`` property float32 (the old reader
#: parsed ASCII text as float64; the dragon's positions move by up to 7e-9).
ASSET_MESH_VERSION = 4


def check_variant(variant: str) -> str:
    """``variant`` if it is a known material variant, else an InvalidInputError."""
    if variant not in VARIANTS:
        raise InvalidInputError(f"unknown variant '{variant}'; known: {', '.join(VARIANTS)}")
    return variant


def material(variant: str, name: str, kd: Sequence[float], *, ks: float = 0.0,
             shininess: float = 64.0) -> Material:
    """The ``variant`` material of an object with diffuse colour ``kd``.

    The diffuse variant is kd alone. The glossy variant adds a grey Phong lobe of albedo ``ks``
    and exponent ``shininess``, lowering kd where needed so kd + ks ≤ 1 per channel (energy
    conservation of the normalised Phong BRDF). ``ks = 0`` keeps the object diffuse in both.
    """
    check_variant(variant)
    if variant == "diffuse" or ks <= 0:
        return Material(kd=tuple(kd), name=name)
    kd_glossy = tuple(min(float(c), 1.0 - ks) for c in kd)
    return Material(kd=kd_glossy, ks=(ks, ks, ks), shininess=shininess, name=name)


def asset_mesh(asset: str, member: str, *, height: float,
               object_from_file: np.ndarray | None = None, rotate_y_degrees: float = 0.0,
               position: Sequence[float] = (0.0, 0.0, 0.0), close_holes: bool = True,
               ) -> TriangleMesh:
    """A fetched asset mesh normalised to stand on the ground.

    The file mesh is turned y-up by ``object_from_file`` (3, 3); duplicate seam vertices are
    welded; degenerate and duplicate faces (decimation fins) and unused vertices are dropped;
    holes are closed with fans (a one-sided surface would show its black inside through them);
    faces are wound outward; the mesh is scaled to ``height``, centred on its x/z bounding-box
    centre, rotated about +Y and moved so its lowest point is at ``position``. Normals are
    area-weighted vertex normals. The result is cached by the asset's pinned hash and these
    parameters.
    """

    path = asset_path(asset, member)
    basis = np.eye(3) if object_from_file is None else np.asarray(object_from_file, float)
    key = content_key("asset-mesh", ASSET_MESH_VERSION, asset, ASSETS[asset].sha256, member,
                      height, basis, rotate_y_degrees, list(position), close_holes)

    def compute() -> dict[str, np.ndarray]:
        positions, faces = read_mesh(path)
        positions, faces = weld_vertices(positions @ basis.T, faces)
        faces = faces[~degenerate_faces(positions, faces)]
        faces, _ = remove_duplicate_faces(faces)
        used, faces = np.unique(faces, return_inverse=True)
        positions, faces = positions[used], faces.reshape(-1, 3)
        if close_holes:
            positions, faces, _ = fill_holes(positions, faces)
        lo, hi = positions.min(axis=0), positions.max(axis=0)
        positions = (positions - [(lo[0] + hi[0]) / 2, lo[1], (lo[2] + hi[2]) / 2]) * (
            height / (hi[1] - lo[1]))
        faces = outward(positions, faces)
        mesh = TriangleMesh(positions, faces, vertex_normals(positions, faces))
        mesh = transformed(mesh, translate(*position) @ rotate_y(rotate_y_degrees))
        return {"positions": mesh.positions, "faces": mesh.faces, "normals": mesh.normals}

    arrays = cached_arrays("asset-mesh", key, compute)
    return TriangleMesh(arrays["positions"], arrays["faces"], arrays["normals"])


def assemble(name: str, objects: list[SceneObject], *, variant: str, params: dict[str, Any],
             center: Sequence[float], orbit_radius: float, orbit_height: float,
             default_light: str = "sky", exposure: float = 1.0, fov_y: float = 45.0,
             start_degrees: float = 20.0, arc_degrees: float = 360.0,
             substitution: str = "") -> Scene:
    """A Scene with a 30-view orbit around ``center`` at ``orbit_radius``, ``orbit_height``.

    ``start_degrees`` / ``arc_degrees`` restrict the orbit (0° is the +Z side, 90° the +X side)
    for scenes seen from one side only (a room's open corner, the Cornell box's opening).

    Builders pick ``exposure`` so that, under the default light, the median geometry pixel of
    the trajectory's direct diffuse radiance displays at about 0.63 after sRGB (linear ≈ 0.35):
    0.7 for open scenes under ``sky`` (E ≈ π on the ground, kd 0.5), more for enclosed ones.
    """
    views = Trajectory.orbit(center=tuple(float(c) for c in center), radius=orbit_radius,
                             height=orbit_height, n_views=30, fov_y=fov_y,
                             start_degrees=start_degrees, arc_degrees=arc_degrees)
    return Scene(name, objects, variant=variant, default_light=default_light, trajectory=views,
                 exposure=exposure, params=dict(params), substitution=substitution)
