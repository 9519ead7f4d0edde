"""LION: the CGAL lion head mounted on a plaque standing on a ground plane.

From Debian ``libcgal-demo`` (``data/meshes/lion-head.off``, 17k triangles): a sculpted head
with deep, high-frequency occlusion around the eyes, ears and mouth, a stand-in for the papers'
Monkey-like single-object scenes. The file's head is cut flat at the back (a hole, closed here
by a fan); it is turned so the cut is vertical and mounted on a plaque like a trophy.
"""

from __future__ import annotations

import numpy as np

from prtbench.scene import params as P
from prtbench.scene.geometry import grid_plane
from prtbench.scene.model import Scene, SceneObject
from prtbench.scene.registry import register_scene
from scenes.common import assemble, asset_mesh, check_variant, material
from scenes.primitives import box

#: Outward normal of the flat cut at the back of the head, in file coordinates (measured by a
#: plane fit to the file's one boundary loop).
_CUT_NORMAL = np.array([0.277075, -0.361823, -0.890120])


def _rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(3, 3) smallest rotation taking unit vector ``a`` to unit vector ``b`` (Rodrigues)."""
    a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
    v, c = np.cross(a, b), float(np.dot(a, b))
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + vx @ vx / (1 + c)


#: Turns the file's head (already y-up, facing +z) so its cut faces −z exactly.
LION_UPRIGHT = _rotation_between(_CUT_NORMAL, np.array([0.0, 0.0, -1.0]))


def lion_mesh(*, height: float = 0.7, rotate_y_degrees: float = 0.0,
              position: tuple[float, float, float] = (0.0, 0.0, 0.0)):
    """The lion head, y-up, facing +z (its cut towards −z), lowest point at ``position``."""
    return asset_mesh("cgal-meshes", "lion-head.off", height=height, object_from_file=LION_UPRIGHT,
                      rotate_y_degrees=rotate_y_degrees, position=position)


@register_scene("lion", params={"ground_subdivisions": P.grid_subdivisions()})
def build(*, variant: str = "diffuse", ground_subdivisions: int = 1) -> Scene:
    """The lion head on a plaque over a 2·k²-triangle ground.

    Parameters
    ----------
    variant : {"diffuse", "glossy"}
        Glossy: bronze-like head (ks 0.45, s 64).
    ground_subdivisions : int
        Ground quads per side k.
    """
    check_variant(variant)
    head = lion_mesh(position=(0.0, 0.3, 0.0))
    lo, hi = head.positions.min(axis=0), head.positions.max(axis=0)
    back = float(lo[2]) + 0.01  # the plaque's front sinks 1 cm into the head's flat back
    plaque = box((1.0, hi[1] + 0.15, 0.06), center=(0.0, (hi[1] + 0.15) / 2, back - 0.03))
    objects = [
        SceneObject("ground", grid_plane(4.0, ground_subdivisions),
                    material(variant, "ground", (0.5, 0.5, 0.5))),
        SceneObject("plaque", plaque, material(variant, "plaque", (0.35, 0.22, 0.12), ks=0.2,
                                               shininess=32.0)),
        SceneObject("lion", head, material(variant, "lion", (0.7, 0.5, 0.3), ks=0.45,
                                           shininess=64.0)),
    ]
    return assemble("lion", objects, variant=variant,
                    params={"ground_subdivisions": ground_subdivisions},
                    center=(0.0, 0.55, 0.0), orbit_radius=2.0, orbit_height=0.5,
                    start_degrees=-75.0, arc_degrees=150.0, default_light="sky", exposure=0.8,
                    substitution="CGAL lion-head stands in for the papers' Monkey")
