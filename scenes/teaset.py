"""TEASET (thesis table 4.1): the Utah teapot with cups and saucers on a table.

The thesis's TEASET is not public. The Utah teapot (npm ``teapot@1.0.0``, 992 triangles,
public domain) stands with four procedural cups (lathe walls with torus handles) on saucers on a
low-tessellation table (boxes) over a two-triangle floor.
"""

from __future__ import annotations

import math

from prtbench.scene import params as P
from prtbench.scene.geometry import grid_plane
from prtbench.scene.model import Scene, SceneObject
from prtbench.scene.registry import register_scene
from scenes.common import assemble, asset_mesh, check_variant, material
from scenes.primitives import box, lathe, merge, rotate_y, rotate_z, torus, transformed, translate

TABLE_HEIGHT = 0.75


def cup(*, radius: float = 0.042, height: float = 0.075, wall: float = 0.004) -> list:
    """A cup (closed wall solid, open at the top) with a handle on its +x side."""
    r0, r1 = 0.7 * radius, radius
    profile = [(0, 0), (r0, 0), (r0, 0), (r1, height), (r1, height), (r1 - wall, height),
               (r1 - wall, height), (r0 - wall, wall), (r0 - wall, wall), (0, wall)]
    body = lathe(profile, segments=48)
    handle = torus(major=0.022, minor=0.0045, arc_degrees=220, segments=16, sides=8)
    # The arc opens towards −x, its ends touching the wall at mid height.
    handle = transformed(handle, translate(r1 * 0.93 + 0.006, 0.55 * height, 0.0)
                         @ rotate_z(-110.0))
    return [body, handle]


def saucer(*, radius: float = 0.075) -> object:
    """A shallow closed dish."""
    foot = 0.45 * radius
    profile = [(0, 0), (foot, 0), (foot, 0), (foot, 0.006), (radius, 0.016), (radius, 0.016),
               (radius, 0.02), (radius, 0.02), (foot, 0.01), (0, 0.01)]
    return lathe(profile, segments=48)


@register_scene("teaset", params={"table_subdivisions": P.grid_subdivisions()})
def build(*, variant: str = "diffuse", table_subdivisions: int = 1) -> Scene:
    """The teapot, four cups on saucers, a table and a floor.

    Parameters
    ----------
    variant : {"diffuse", "glossy"}
        Glossy: porcelain (ks 0.25, s 128) and varnished table (ks 0.2, s 48).
    table_subdivisions : int
        Table-top quads per side k (the top face is a 2·k²-triangle grid; 1 is the minimum).
    """
    check_variant(variant)
    top_size = (1.3, 0.9)
    top = grid_plane(top_size, table_subdivisions, center=(0.0, TABLE_HEIGHT, 0.0))
    body = [box((top_size[0], 0.04, top_size[1]), center=(0.0, TABLE_HEIGHT - 0.02 - 1e-4, 0.0))]
    for sx in (-1, 1):
        for sz in (-1, 1):
            body.append(box((0.06, TABLE_HEIGHT - 0.04, 0.06),
                            center=(sx * 0.58, (TABLE_HEIGHT - 0.04) / 2, sz * 0.38)))
    # The top face is its own grid so its tessellation can be varied; the slab below it is a
    # closed box whose top face lies 0.1 mm lower (hidden, never z-fighting).
    teapot = asset_mesh("teapot", "teapot.js", height=0.17, rotate_y_degrees=-30.0,
                        position=(0.0, TABLE_HEIGHT, -0.05))
    cups, saucers = [], []
    for k, (x, z) in enumerate(((-0.38, 0.2), (0.38, 0.22), (-0.4, -0.22), (0.36, -0.25))):
        angle = math.degrees(math.atan2(z, x))
        placed = translate(x, TABLE_HEIGHT + 0.01, z) @ rotate_y(-angle + 180)
        saucers.append(transformed(saucer(), translate(x, TABLE_HEIGHT, z)))
        cups += [transformed(part, placed) for part in cup()]
    porcelain = material(variant, "porcelain", (0.82, 0.80, 0.75), ks=0.25, shininess=128.0)
    objects = [
        SceneObject("floor", grid_plane(4.0, 1), material(variant, "floor", (0.45, 0.42, 0.40))),
        SceneObject("table_top", top, material(variant, "table_top", (0.50, 0.32, 0.18),
                                               ks=0.2, shininess=48.0)),
        SceneObject("table", merge(body), material(variant, "table", (0.42, 0.27, 0.15))),
        SceneObject("teapot", teapot, porcelain),
        SceneObject("cups", merge(cups), porcelain),
        SceneObject("saucers", merge(saucers), material(variant, "saucers", (0.55, 0.65, 0.75),
                                                        ks=0.25, shininess=128.0)),
    ]
    return assemble("teaset", objects, variant=variant,
                    params={"table_subdivisions": table_subdivisions},
                    center=(0.0, TABLE_HEIGHT + 0.05, 0.0), orbit_radius=1.25, orbit_height=0.65,
                    default_light="sky", exposure=1.1,
                    substitution="Utah teapot with procedural cups stands in for the thesis's "
                                 "TEASET")
