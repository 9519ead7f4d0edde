"""BUST: a scanned bust on a ground plane, standing in for the thesis's ROZA.

ROZA (a scanned bust with hair, thesis table 4.1 and PRTT Fig. 5) is not public. The
``snowden`` npm package (MIT) is a scanned bust with similar high-frequency detail in the hair
and face: ``lo.js`` has 38k triangles, ``hi.js`` 109k.
"""

from __future__ import annotations

from prtbench.api.errors import InvalidInputError
from prtbench.scene import params as P
from prtbench.scene.geometry import grid_plane
from prtbench.scene.model import Scene, SceneObject
from prtbench.scene.registry import register_scene
from scenes.common import assemble, asset_mesh, check_variant, material

SUBSTITUTION = "snowden scan (npm snowden@1.0.1) stands in for the thesis's Roza"
#: The package's build script already turned the scan y-up; its face looks towards (−x, +z),
#: so a 45° turn about +Y makes it face +z.
SNOWDEN_FACING_DEGREES = 45.0
RESOLUTIONS = {"lo": "lo.js", "hi": "hi.js"}


def bust_mesh(resolution: str, *, height: float, rotate_y_degrees: float = 0.0,
              position: tuple[float, float, float] = (0.0, 0.0, 0.0)):
    """The snowden bust, y-up, facing +z after ``rotate_y_degrees``, standing at ``position``."""
    if resolution not in RESOLUTIONS:
        raise InvalidInputError(f"bust resolution '{resolution}'; accepted: lo, hi")
    return asset_mesh("snowden", RESOLUTIONS[resolution], height=height,
                      rotate_y_degrees=SNOWDEN_FACING_DEGREES + rotate_y_degrees,
                      position=position)


@register_scene("bust", params={"resolution": P.choice(*RESOLUTIONS),
                                   "ground_subdivisions": P.grid_subdivisions()})
def build(*, variant: str = "diffuse", resolution: str = "lo", ground_subdivisions: int = 1,
          ) -> Scene:
    """The snowden bust (height 1) on a ground plane.

    Parameters
    ----------
    variant : {"diffuse", "glossy"}
        Glossy: polished stone bust (ks 0.3, s 64).
    resolution : {"lo", "hi"}
        38k or 109k triangles.
    ground_subdivisions : int
        Ground quads per side k (2·k² triangles).
    """
    check_variant(variant)
    bust = bust_mesh(resolution, height=1.0)
    objects = [
        SceneObject("ground", grid_plane(4.0, ground_subdivisions),
                    material(variant, "ground", (0.5, 0.5, 0.5))),
        SceneObject("bust", bust, material(variant, "bust", (0.72, 0.68, 0.62), ks=0.3,
                                           shininess=64.0)),
    ]
    return assemble("bust", objects, variant=variant,
                    params={"resolution": resolution, "ground_subdivisions": ground_subdivisions},
                    center=(0.0, 0.5, 0.0), orbit_radius=1.9, orbit_height=0.45,
                    default_light="sky", exposure=0.7, substitution=SUBSTITUTION)
