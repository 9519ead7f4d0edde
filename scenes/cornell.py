"""CORNELL: a Cornell box lit by the environment through a skylight and its open front.

Environment-lit PRT has no area light, so the box's ceiling has a square skylight where the
classic box has its lamp; the front (+z) is open for the cameras. Red left wall, green right
wall, white floor, ceiling and back wall, a tall and a short block. Each wall is its own
closed slab (surfaces are one-sided) and its own object.
"""

from __future__ import annotations

from prtbench import scene_params as P
from prtbench.scene import Scene, SceneObject, register_scene

from .common import assemble, check_variant, material
from .primitives import box, merge, rotate_y, transformed, translate

SIZE = 1.0     # inner edge length
WALL = 0.04    # slab thickness


@register_scene("cornell", params={"skylight": P.real(low=0.0, high=0.9 * SIZE)})
def build(*, variant: str = "diffuse", skylight: float = 0.3) -> Scene:
    """The Cornell box (inner size 1, floor at y = 0, centred on x = z = 0).

    Parameters
    ----------
    variant : {"diffuse", "glossy"}
        Glossy: the tall block is glossy (ks 0.5, s 64) and the floor slightly (ks 0.15, s 32).
    skylight : float
        Side of the square opening in the ceiling (0 closes it).
    """
    check_variant(variant)
    h, t = SIZE / 2, WALL
    outer = SIZE + 2 * t
    white = (0.73, 0.71, 0.68)
    ceiling_y = SIZE + t / 2
    s = min(max(float(skylight), 0.0), 0.9 * SIZE) / 2
    if s > 0:
        # Four slabs framing the skylight.
        ceiling = merge([
            box((outer, t, h + t - s), center=(0.0, ceiling_y, -(s + (h + t - s) / 2))),
            box((outer, t, h - s), center=(0.0, ceiling_y, s + (h - s) / 2)),
            box((h + t - s, t, 2 * s), center=(-(s + (h + t - s) / 2), ceiling_y, 0.0)),
            box((h + t - s, t, 2 * s), center=(s + (h + t - s) / 2, ceiling_y, 0.0)),
        ])
    else:
        ceiling = box((outer, t, SIZE + t), center=(0.0, ceiling_y, -t / 2))
    tall = transformed(box((0.3, 0.6, 0.3)), translate(-0.17, 0.3, -0.15) @ rotate_y(17.0))
    short = transformed(box((0.3, 0.3, 0.3)), translate(0.18, 0.15, 0.14) @ rotate_y(-17.0))
    objects = [
        SceneObject("floor", box((outer, t, SIZE + t), center=(0.0, -t / 2, -t / 2)),
                    material(variant, "floor", white, ks=0.15, shininess=32.0)),
        SceneObject("ceiling", ceiling, material(variant, "ceiling", white)),
        SceneObject("back", box((outer, SIZE, t), center=(0.0, h, -h - t / 2)),
                    material(variant, "back", white)),
        SceneObject("left", box((t, SIZE, SIZE), center=(-h - t / 2, h, 0.0)),
                    material(variant, "left", (0.63, 0.065, 0.05))),
        SceneObject("right", box((t, SIZE, SIZE), center=(h + t / 2, h, 0.0)),
                    material(variant, "right", (0.14, 0.45, 0.091))),
        SceneObject("tall_block", tall, material(variant, "tall_block", white, ks=0.5,
                                                 shininess=64.0)),
        SceneObject("short_block", short, material(variant, "short_block", white)),
    ]
    return assemble("cornell", objects, variant=variant, params={"skylight": skylight},
                    center=(0.0, h, 0.0), orbit_radius=2.6, orbit_height=0.05,
                    start_degrees=-15.0, arc_degrees=30.0, fov_y=35.0,
                    default_light="sky", exposure=3.5)
