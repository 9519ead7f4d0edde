"""Ground plane and views of an imported file: its camera, else an orbit framing the bounds."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from prtbench.scene.files.reader import import_basis
from prtbench.scene.geometry import grid_plane
from prtbench.scene.model import Material, SceneObject, Trajectory, View

#: Albedo of the ``ground=true`` plane.
GROUND_KD = 0.6
#: Orbit framing: elevation of the cameras, their vertical field of view, the view count.
ORBIT_ELEVATION_DEG, ORBIT_FOV_DEG, ORBIT_VIEWS = 25.0, 45.0, 30


def _ground_square(lo: np.ndarray, hi: np.ndarray) -> tuple[float, tuple[float, float, float]]:
    """Side and centre of the ``ground=true`` square under the bounds (lo, hi): twice the larger
    horizontal extent (or the height) wide, at the bounds' lowest y. Commutes with a
    similarity, so it may be placed in the canonical frame from the canonical bounds."""
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    extent = hi - lo
    size = 2.0 * float(max(extent[0], extent[2], 0.5 * extent[1]))
    return size, (float(lo[0] + hi[0]) / 2, float(lo[1]), float(lo[2] + hi[2]) / 2)


def ground_bounds(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bounds (lo, hi), float64, of the :func:`ground` plane under the bounds (lo, hi)."""
    size, center = _ground_square(lo, hi)
    c = np.asarray(center)
    half = np.array([0.5 * size, 0.0, 0.5 * size])
    return c - half, c + half


def ground(lo: np.ndarray, hi: np.ndarray, variant: str):
    """The ``ground=true`` plane (kd :data:`GROUND_KD`, facing +Y) under the bounds (lo, hi)."""
    size, center = _ground_square(lo, hi)
    return SceneObject("ground", grid_plane(size, 1, center=center),
                       Material(kd=(GROUND_KD,) * 3, name="ground"))


def file_views(tm_scene, values: dict[str, Any]) -> list:
    """The file's perspective camera (trimesh reads the first one), in our world frame."""

    try:
        if not tm_scene.has_camera:
            return []
        camera = tm_scene.camera
        world_from_camera = np.asarray(tm_scene.camera_transform, dtype=np.float64)
    except Exception:  # no (complete) camera in the file
        return []
    m = import_basis(values) @ world_from_camera
    eye = m[:3, 3]
    back = m[:3, 2] / np.linalg.norm(m[:3, 2])
    up = m[:3, 1] / np.linalg.norm(m[:3, 1])
    fov_y = float(camera.fov[1])
    if not 1.0 <= fov_y <= 170.0:
        return []
    return [View(eye=tuple(map(float, eye)), target=tuple(map(float, eye - back)),
                 up=tuple(map(float, up)), fov_y=fov_y)]


def orbit(lo: np.ndarray, hi: np.ndarray) -> list:
    """30 views on a circle above the bounds' centre, framing their bounding sphere."""

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
