"""DINING-TABLE (thesis table 4.1): a table with four chairs on a low-tessellation floor.

The thesis's DINING-TABLE is not public. This procedural one has turned (lathe) legs, chairs
with spindle backs whose thin bars cast high-frequency shadows, and plates and glasses on the
table top; the floor and the table top have two triangles each.
"""

from __future__ import annotations

import numpy as np

from prtbench.scene import params as P
from prtbench.scene.geometry import grid_plane
from prtbench.scene.model import Scene, SceneObject
from prtbench.scene.registry import register_scene
from scenes.common import assemble, check_variant, material
from scenes.primitives import box, lathe, merge, rotate_y, transformed, translate, tube

TABLE_HEIGHT = 0.76
TOP = (1.8, 1.0)


def turned_leg(height: float, *, radius: float = 0.035, segments: int = 24):
    """A turned leg: foot, bulb and taper (a closed lathe solid) from y = 0 to ``height``."""
    h = height
    profile = [(0, 0), (0.7 * radius, 0), (0.7 * radius, 0), (radius, 0.04 * h),
               (0.75 * radius, 0.12 * h), (0.7 * radius, 0.45 * h), (1.25 * radius, 0.6 * h),
               (0.8 * radius, 0.72 * h), (radius, 0.82 * h), (radius, h), (radius, h), (0, h)]
    return lathe(profile, segments=segments)


def chair(*, seat: float = 0.46, width: float = 0.46) -> list:
    """A chair facing +z (back at −z), standing at the origin."""
    half = width / 2 - 0.03
    parts = [box((width, 0.04, width), center=(0.0, seat, 0.0))]
    for sx in (-1, 1):
        for sz in (-1, 1):
            leg = turned_leg(seat - 0.02, radius=0.022, segments=16)
            parts.append(transformed(leg, translate(sx * half, 0.0, sz * half)))
        # Back posts continue above the seat.
        parts.append(tube((sx * half, seat + 0.02, -half), (sx * half, seat + 0.5, -half - 0.03),
                          radius=0.018, segments=12))
    parts.append(box((width, 0.07, 0.03), center=(0.0, seat + 0.48, -half - 0.03)))
    for k in range(5):
        x = -half + (k + 1) * 2 * half / 6
        parts.append(tube((x, seat + 0.02, -half), (x, seat + 0.45, -half - 0.028),
                          radius=0.009, segments=8))
    return parts


def plate(*, radius: float = 0.13):
    profile = [(0, 0), (0.55 * radius, 0), (0.55 * radius, 0), (0.6 * radius, 0.008),
               (radius, 0.022), (radius, 0.022), (0.95 * radius, 0.024), (0.95 * radius, 0.024),
               (0.55 * radius, 0.012), (0, 0.012)]
    return lathe(profile, segments=48)


def glass(*, radius: float = 0.035, height: float = 0.16):
    """A stemmed glass: foot, stem and an open bowl with a wall (closed solid)."""
    w = 0.003
    profile = [(0, 0), (0.9 * radius, 0), (0.9 * radius, 0), (0.9 * radius, 0.005),
               (0.15 * radius, 0.012), (0.12 * radius, 0.45 * height),
               (0.7 * radius, 0.55 * height),
               (radius, 0.75 * height), (radius, height), (radius, height),
               (radius - w, height), (radius - w, height), (radius - w, 0.75 * height),
               (0.7 * radius - w, 0.56 * height), (0, 0.5 * height)]
    return lathe(profile, segments=32)


@register_scene("dining-table", params={"floor_subdivisions": P.grid_subdivisions()})
def build(*, variant: str = "diffuse", floor_subdivisions: int = 1) -> Scene:
    """A dining table with four chairs, plates and glasses on a 2·k²-triangle floor.

    Parameters
    ----------
    variant : {"diffuse", "glossy"}
        Glossy: varnished wood (ks 0.25, s 64), porcelain plates (ks 0.3, s 128), glasses
        (ks 0.5, s 256).
    floor_subdivisions : int
        Floor quads per side k.
    """
    check_variant(variant)
    legs = [transformed(turned_leg(TABLE_HEIGHT - 0.04), translate(sx * 0.8, 0.0, sz * 0.42))
            for sx in (-1, 1) for sz in (-1, 1)]
    apron = [box((TOP[0] - 0.12, 0.1, 0.03), center=(0.0, TABLE_HEIGHT - 0.09, sz * 0.42))
             for sz in (-1, 1)]
    apron += [box((0.03, 0.1, TOP[1] - 0.12), center=(sx * 0.8, TABLE_HEIGHT - 0.09, 0.0))
              for sx in (-1, 1)]
    top = box((TOP[0], 0.04, TOP[1]), center=(0.0, TABLE_HEIGHT - 0.02, 0.0))
    chairs = []
    for x, z, yaw in ((-0.4, 0.72, 180.0), (0.4, 0.72, 180.0), (-0.4, -0.72, 0.0),
                      (0.4, -0.72, 0.0)):
        # The chair's front (+z) faces the table.
        placed = translate(x, 0.0, z) @ rotate_y(yaw)
        chairs += [transformed(p, placed) for p in chair()]
    plates, glasses = [], []
    for x, z in ((-0.4, 0.3), (0.4, 0.3), (-0.4, -0.3), (0.4, -0.3)):
        plates.append(transformed(plate(), translate(x, TABLE_HEIGHT, z)))
        glasses.append(transformed(glass(), translate(x + 0.2 * np.sign(x), TABLE_HEIGHT,
                                                      z - 0.12 * np.sign(z))))
    wood = material(variant, "table", (0.48, 0.30, 0.16), ks=0.25, shininess=64.0)
    objects = [
        SceneObject("floor", grid_plane(5.0, floor_subdivisions),
                    material(variant, "floor", (0.62, 0.6, 0.56))),
        SceneObject("table", merge([top] + legs + apron), wood),
        SceneObject("chairs", merge(chairs), material(variant, "chairs", (0.36, 0.22, 0.12),
                                                      ks=0.25, shininess=64.0)),
        SceneObject("plates", merge(plates), material(variant, "plates", (0.85, 0.84, 0.8),
                                                      ks=0.3, shininess=128.0)),
        SceneObject("glasses", merge(glasses), material(variant, "glasses", (0.3, 0.45, 0.4),
                                                        ks=0.5, shininess=256.0)),
    ]
    return assemble("dining-table", objects, variant=variant,
                    params={"floor_subdivisions": floor_subdivisions},
                    center=(0.0, 0.45, 0.0), orbit_radius=2.7, orbit_height=1.4,
                    default_light="sky", exposure=1.1,
                    substitution="procedural table and chairs stand in for the thesis's "
                                 "DINING-TABLE")
