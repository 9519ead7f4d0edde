"""TRM ("two Roza, one Monkey", PRTT Fig. 3/4): two busts and a creature on a ground plane.

Neither ROZA nor the paper's Monkey is public: two copies of the snowden bust stand in for the
two Rozas and the CGAL armadillo (52k triangles) for the Monkey. Four objects (ground, two
busts, armadillo) make the scene's four texture-set pieces (PRTT Fig. 3).
"""

from __future__ import annotations

from prtbench.scene import params as P
from prtbench.scene.geometry import grid_plane
from prtbench.scene.model import Scene, SceneObject
from prtbench.scene.registry import register_scene
from scenes.bust import RESOLUTIONS, bust_mesh
from scenes.common import assemble, asset_mesh, check_variant, material


@register_scene("trm", params={"resolution": P.choice(*RESOLUTIONS),
                                  "ground_subdivisions": P.grid_subdivisions()})
def build(*, variant: str = "diffuse", resolution: str = "hi", ground_subdivisions: int = 1,
          ) -> Scene:
    """Two snowden busts and the armadillo on a 2·k²-triangle ground.

    Parameters
    ----------
    variant : {"diffuse", "glossy"}
        Glossy: polished busts (ks 0.3, s 64), lacquered armadillo (ks 0.4, s 96).
    resolution : {"lo", "hi"}
        Bust resolution (38k or 109k triangles each).
    ground_subdivisions : int
        Ground quads per side k.
    """
    check_variant(variant)
    left = bust_mesh(resolution, height=1.0, rotate_y_degrees=25.0, position=(-0.75, 0.0, -0.1))
    right = bust_mesh(resolution, height=1.0, rotate_y_degrees=-25.0, position=(0.75, 0.0, -0.1))
    # The armadillo file is y-up and faces −z; turn it to face +z (the front of the orbit).
    creature = asset_mesh("cgal-meshes", "armadillo.off", height=0.8, rotate_y_degrees=180.0,
                          position=(0.0, 0.0, 0.35))
    objects = [
        SceneObject("ground", grid_plane(5.0, ground_subdivisions),
                    material(variant, "ground", (0.5, 0.5, 0.5))),
        SceneObject("bust_left", left, material(variant, "bust_left", (0.72, 0.68, 0.62),
                                                ks=0.3, shininess=64.0)),
        SceneObject("bust_right", right, material(variant, "bust_right", (0.62, 0.66, 0.72),
                                                  ks=0.3, shininess=64.0)),
        SceneObject("armadillo", creature, material(variant, "armadillo", (0.55, 0.4, 0.25),
                                                    ks=0.4, shininess=96.0)),
    ]
    return assemble("trm", objects, variant=variant,
                    params={"resolution": resolution, "ground_subdivisions": ground_subdivisions},
                    center=(0.0, 0.45, 0.0), orbit_radius=2.8, orbit_height=0.9,
                    default_light="sky", exposure=0.7,
                    substitution="two snowden busts and the CGAL armadillo stand in for TRM "
                                 "(two Roza, one Monkey)")
