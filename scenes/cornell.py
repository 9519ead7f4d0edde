"""CORNELL: a Cornell box lit by the environment through a skylight and its open front.

Environment-lit PRT has no area light, so the box's ceiling has a square skylight where the
classic box has its lamp; the front (+z) is open for the cameras. Red left wall, green right
wall, white floor, ceiling and back wall, a tall and a short block. Each wall is its own
closed slab (surfaces are one-sided) and its own object.
"""

from __future__ import annotations

import math

import numpy as np

from prtbench.scene import params as P
from prtbench.scene.model import Scene, SceneObject, TriangleMesh
from prtbench.scene.registry import register_scene
from scenes.common import assemble, check_variant, material
from scenes.primitives import box, merge, rotate_y, transformed, translate

SIZE = 1.0     # inner edge length
WALL = 0.04    # slab thickness


def tessellated_box(size, *, center=(0.0, 0.0, 0.0), subdivisions: int = 1) -> TriangleMesh:
    """:func:`~scenes.primitives.box` with each face split into a grid of quads of edge about
    ``SIZE / subdivisions`` (at least one quad per side), for per-vertex methods.

    ``subdivisions=1`` returns ``box`` itself (the existing Cornell geometry, bit for bit).
    """
    if subdivisions <= 1:
        return box(size, center=center)
    half = np.asarray(size, dtype=np.float64) / 2
    c = np.asarray(center, dtype=np.float64)
    cell = SIZE / subdivisions
    positions, normals, faces = [], [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            # The same (u, v, n) frame and counter-clockwise quads as box().
            n = np.zeros(3)
            n[axis] = sign
            u = np.zeros(3)
            u[(axis + 1) % 3] = 1.0
            v = np.cross(n, u)
            nu = max(1, math.ceil(2 * float(half @ np.abs(u)) / cell - 1e-9))
            nv = max(1, math.ceil(2 * float(half @ np.abs(v)) / cell - 1e-9))
            a, b = np.meshgrid(np.linspace(-1, 1, nu + 1), np.linspace(-1, 1, nv + 1),
                               indexing="ij")
            grid = c + half * (n + a[..., None] * u + b[..., None] * v)  # (nu+1, nv+1, 3)
            base = sum(len(p) for p in positions)
            idx = base + np.arange((nu + 1) * (nv + 1)).reshape(nu + 1, nv + 1)
            p00, p10 = idx[:-1, :-1], idx[1:, :-1]
            p11, p01 = idx[1:, 1:], idx[:-1, 1:]
            quads = np.stack([p00, p10, p11, p01], -1).reshape(-1, 4)
            faces.append(np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]]))
            positions.append(grid.reshape(-1, 3))
            normals.append(np.broadcast_to(n, (len(positions[-1]), 3)))
    return TriangleMesh(np.concatenate(positions), np.concatenate(faces),
                        np.concatenate(normals))


@register_scene("cornell", params={"skylight": P.real(low=0.0, high=0.9 * SIZE),
                                      "subdivisions": P.count(low=1, high=64)})
def build(*, variant: str = "diffuse", skylight: float = 0.3, subdivisions: int = 1) -> Scene:
    """The Cornell box (inner size 1, floor at y = 0, centred on x = z = 0).

    Parameters
    ----------
    variant : {"diffuse", "glossy"}
        Glossy: the tall block is glossy (ks 0.5, s 64) and the floor slightly (ks 0.15, s 32).
    skylight : float
        Side of the square opening in the ceiling (0 closes it).
    subdivisions : int
        Quads per box edge: every slab and block face is split into quads of edge about
        1/``subdivisions`` (1: the 2-triangle faces). Per-vertex methods (``vertex``,
        ``sloan-matrix``) need it to resolve shadows and interreflection on the walls.
    """
    check_variant(variant)
    k = int(subdivisions)

    def slab(size, center=(0.0, 0.0, 0.0)):
        return tessellated_box(size, center=center, subdivisions=k)

    h, t = SIZE / 2, WALL
    outer = SIZE + 2 * t
    white = (0.73, 0.71, 0.68)
    ceiling_y = SIZE + t / 2
    s = min(max(float(skylight), 0.0), 0.9 * SIZE) / 2
    if s > 0:
        # Four slabs framing the skylight.
        ceiling = merge([
            slab((outer, t, h + t - s), center=(0.0, ceiling_y, -(s + (h + t - s) / 2))),
            slab((outer, t, h - s), center=(0.0, ceiling_y, s + (h - s) / 2)),
            slab((h + t - s, t, 2 * s), center=(-(s + (h + t - s) / 2), ceiling_y, 0.0)),
            slab((h + t - s, t, 2 * s), center=(s + (h + t - s) / 2, ceiling_y, 0.0)),
        ])
    else:
        ceiling = slab((outer, t, SIZE + t), center=(0.0, ceiling_y, -t / 2))
    tall = transformed(slab((0.3, 0.6, 0.3)), translate(-0.17, 0.3, -0.15) @ rotate_y(17.0))
    short = transformed(slab((0.3, 0.3, 0.3)), translate(0.18, 0.15, 0.14) @ rotate_y(-17.0))
    objects = [
        SceneObject("floor", slab((outer, t, SIZE + t), center=(0.0, -t / 2, -t / 2)),
                    material(variant, "floor", white, ks=0.15, shininess=32.0)),
        SceneObject("ceiling", ceiling, material(variant, "ceiling", white)),
        SceneObject("back", slab((outer, SIZE, t), center=(0.0, h, -h - t / 2)),
                    material(variant, "back", white)),
        SceneObject("left", slab((t, SIZE, SIZE), center=(-h - t / 2, h, 0.0)),
                    material(variant, "left", (0.63, 0.065, 0.05))),
        SceneObject("right", slab((t, SIZE, SIZE), center=(h + t / 2, h, 0.0)),
                    material(variant, "right", (0.14, 0.45, 0.091))),
        SceneObject("tall_block", tall, material(variant, "tall_block", white, ks=0.5,
                                                 shininess=64.0)),
        SceneObject("short_block", short, material(variant, "short_block", white)),
    ]
    # The default leaves ``params`` as they were before the knob existed (stored rows).
    params = {"skylight": skylight, **({"subdivisions": k} if k != 1 else {})}
    return assemble("cornell", objects, variant=variant, params=params,
                    center=(0.0, h, 0.0), orbit_radius=2.6, orbit_height=0.05,
                    start_degrees=-15.0, arc_degrees=30.0, fov_y=35.0,
                    default_light="sky", exposure=3.5)
