"""ROOM: the PRTT teaser (Fig. 1): a minimally tessellated floor, walls, a table and a rug.

The paper's room (21K vertices, spatially varying colour) is not public. This procedural room
keeps what the teaser is about: large flat surfaces with two triangles each (floor, two walls,
rug, table top) that receive detailed shadows from a table, chairs, a lamp, a shelf and objects
on the table, about 20k triangles in all. Materials are constant per object.

``normal_mapped_floor`` gives the floor a procedural tangent-space normal map (bevelled tiles)
for normal-map experiments (PRTT Fig. 6). The floor's tangent frame: T = +x (u), B = −z (v),
N = +y; the map stores (n_T, n_B, n_N)·0.5 + 0.5.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from prtbench.scene import params as P
from prtbench.scene.geometry import grid_plane
from prtbench.scene.model import Scene, SceneObject, Texture
from prtbench.scene.registry import register_scene
from scenes.common import assemble, check_variant, material
from scenes.primitives import box, lathe, merge, tube, uv_sphere

FLOOR_SIZE = 5.0
WALL_HEIGHT = 2.6


def tile_normal_map(*, resolution: int = 512, tiles: int = 8, bevel: float = 0.08,
                    depth: float = 0.6) -> Texture:
    """A tangent-space normal map of ``tiles``² bevelled tiles with grooves between them.

    Parameters
    ----------
    resolution : int
        Texture side in texels.
    tiles : int
        Tiles per texture side.
    bevel : float
        Bevel width as a fraction of a tile.
    depth : float
        Slope of the bevels (tangent-space normal x/y magnitude before normalisation).

    Returns
    -------
    Texture
        (resolution, resolution, 3) RGB in [0, 1]; row 0 is v = 0.
    """
    t = (np.arange(resolution) + 0.5) / resolution * tiles
    f = t - np.floor(t)  # position inside a tile, [0, 1)
    # Slope of a trapezoidal height profile: rising over the first bevel, falling over the last.
    slope = np.where(f < bevel, depth, np.where(f > 1 - bevel, -depth, 0.0))
    du = slope[None, :]  # varies with u (columns)
    dv = slope[:, None]  # varies with v (rows)
    n = np.stack([-np.broadcast_to(du, (resolution, resolution)),
                  -np.broadcast_to(dv, (resolution, resolution)),
                  np.ones((resolution, resolution))], -1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return Texture(n * 0.5 + 0.5, name="floor-tiles-normal")


def _table(top_y: float) -> list:
    parts = [box((1.5, 0.05, 0.9), center=(0.0, top_y - 0.025, 0.0))]
    for sx in (-1, 1):
        for sz in (-1, 1):
            x, z = sx * 0.66, sz * 0.37
            parts.append(tube((x, 0.0, z), (x, top_y - 0.05, z), radius=0.03, end_radius=0.04,
                              segments=16))
    return parts


def _chair(x: float, z: float, facing: float) -> list:
    """A chair at (x, z) whose back is on the ``facing`` side (+1: +z, −1: −z)."""
    seat_y = 0.45
    parts = [box((0.45, 0.04, 0.45), center=(x, seat_y, z)),
             box((0.45, 0.5, 0.04), center=(x, seat_y + 0.27, z + facing * 0.205))]
    for sx in (-1, 1):
        for sz in (-1, 1):
            px, pz = x + sx * 0.19, z + sz * 0.19
            parts.append(tube((px, 0.0, pz), (px, seat_y - 0.02, pz), radius=0.02, segments=12))
    return parts


def _vase(x: float, z: float, y: float) -> object:
    profile = [(0, 0), (0.06, 0), (0.06, 0), (0.09, 0.08), (0.1, 0.14), (0.07, 0.24),
               (0.045, 0.3), (0.05, 0.34), (0.05, 0.34), (0.04, 0.34), (0.04, 0.34),
               (0.04, 0.2), (0.04, 0.2), (0, 0.2)]
    vase = lathe(profile, segments=96)
    vase.positions[:] += (x, y, z)
    return vase


def _bowl(x: float, z: float, y: float) -> object:
    # A closed bowl: outer wall up, rim, inner wall down (the solid is the wall itself).
    profile = [(0, 0), (0.07, 0), (0.07, 0), (0.16, 0.07), (0.19, 0.11), (0.19, 0.11),
               (0.18, 0.11), (0.18, 0.11), (0.15, 0.07), (0.06, 0.02), (0, 0.02)]
    bowl = lathe(profile, segments=96)
    bowl.positions[:] += (x, y, z)
    return bowl


def _lamp(x: float, z: float) -> list:
    shade = [(0.0, 1.45), (0.25, 1.45), (0.25, 1.45), (0.17, 1.7), (0.17, 1.7), (0.0, 1.7)]
    base = [(0, 0), (0.18, 0), (0.18, 0), (0.18, 0.03), (0.18, 0.03), (0, 0.04)]
    parts = [lathe(shade, segments=48), lathe(base, segments=48),
             tube((0, 0.03, 0), (0, 1.46, 0), radius=0.015, segments=12)]
    for p in parts:
        p.positions[:] += (x, 0.0, z)
    return parts


def _shelf(x: float, z: float, rng: np.random.Generator) -> tuple[list, list]:
    frame = [box((0.04, 1.6, 0.3), center=(x - 0.48, 0.8, z)),
             box((0.04, 1.6, 0.3), center=(x + 0.48, 0.8, z))]
    books = []
    for level, y in enumerate((0.02, 0.55, 1.1, 1.58)):
        frame.append(box((1.0, 0.03, 0.3), center=(x, y, z)))
        if level == 3:
            continue
        bx = x - 0.44
        while bx < x + 0.4:
            w, h = rng.uniform(0.025, 0.06), rng.uniform(0.25, 0.42)
            books.append(box((w, h, rng.uniform(0.18, 0.24)),
                             center=(bx + w / 2, y + 0.015 + h / 2, z)))
            bx += w + rng.uniform(0.0, 0.01)
    return frame, books


@register_scene("room", params={"floor_subdivisions": P.grid_subdivisions(),
                                   "normal_mapped_floor": P.flag()})
def build(*, variant: str = "diffuse", floor_subdivisions: int = 1,
          normal_mapped_floor: bool = False) -> Scene:
    """A corner of a room: floor, two walls, rug, table with objects, chairs, lamp, shelf.

    Parameters
    ----------
    variant : {"diffuse", "glossy"}
        Glossy: polished floor (ks 0.25, s 64), varnished table (ks 0.3, s 96), glazed vase
        (ks 0.5, s 128), shiny fruit (ks 0.3, s 64).
    floor_subdivisions : int
        Floor quads per side k (2·k² triangles; 1 is the teaser's minimal floor).
    normal_mapped_floor : bool
        Add a procedural tiles normal map to the floor (UVs are always present).
    """
    check_variant(variant)
    rng = np.random.default_rng(11)
    half = FLOOR_SIZE / 2
    floor_material = material(variant, "floor", (0.55, 0.38, 0.22), ks=0.25, shininess=64.0)
    if normal_mapped_floor:
        floor_material = replace(floor_material, normal_map=tile_normal_map())
    wall = material(variant, "wall", (0.78, 0.76, 0.70))
    table_y, table_at = 0.75, np.array([0.0, 0.0, -0.4])
    table = _table(table_y)
    for part in table:
        part.positions[:] += table_at
    chairs = (_chair(table_at[0], table_at[2] + 0.65, +1)
              + _chair(table_at[0], table_at[2] - 0.65, -1))
    fruit = [uv_sphere(radius=0.045, segments=48, center=(table_at[0] + dx, table_y + 0.075,
                                                          table_at[2] + dz))
             for dx, dz in ((0.33, 0.05), (0.38, -0.03), (0.28, -0.04), (0.35, 0.1), (0.42, 0.06),
                            (0.31, 0.0), (0.4, 0.0))]
    frame, books = _shelf(-1.4, -half + 0.2, rng)
    objects = [
        SceneObject("floor", grid_plane(FLOOR_SIZE, floor_subdivisions), floor_material),
        SceneObject("wall_back", box((FLOOR_SIZE, WALL_HEIGHT, 0.1),
                                     center=(0.0, WALL_HEIGHT / 2, -half - 0.05)), wall),
        SceneObject("wall_left", box((0.1, WALL_HEIGHT, FLOOR_SIZE),
                                     center=(-half - 0.05, WALL_HEIGHT / 2, 0.0)), wall),
        SceneObject("rug", box((2.6, 0.012, 1.8), center=(table_at[0], 0.006, table_at[2])),
                    material(variant, "rug", (0.55, 0.14, 0.12))),
        SceneObject("table", merge(table), material(variant, "table", (0.45, 0.28, 0.15),
                                                    ks=0.3, shininess=96.0)),
        SceneObject("chairs", merge(chairs), material(variant, "chairs", (0.30, 0.22, 0.16),
                                                      ks=0.2, shininess=48.0)),
        SceneObject("vase", _vase(table_at[0] - 0.35, table_at[2] - 0.1, table_y),
                    material(variant, "vase", (0.12, 0.25, 0.6), ks=0.5, shininess=128.0)),
        SceneObject("bowl", _bowl(table_at[0] + 0.35, table_at[2] + 0.03, table_y),
                    material(variant, "bowl", (0.85, 0.83, 0.78), ks=0.3, shininess=96.0)),
        SceneObject("fruit", merge(fruit), material(variant, "fruit", (0.75, 0.35, 0.05),
                                                    ks=0.3, shininess=64.0)),
        SceneObject("lamp", merge(_lamp(-1.8, 0.6)), material(variant, "lamp", (0.85, 0.8, 0.65))),
        SceneObject("shelf", merge(frame), material(variant, "shelf", (0.6, 0.55, 0.48))),
        SceneObject("books", merge(books), material(variant, "books", (0.25, 0.35, 0.45))),
    ]
    params = {"floor_subdivisions": floor_subdivisions, "normal_mapped_floor": normal_mapped_floor}
    return assemble("room", objects, variant=variant, params=params, center=(-0.4, 0.6, -0.7),
                    orbit_radius=3.3, orbit_height=1.3, start_degrees=-15.0, arc_degrees=105.0,
                    default_light="sky", exposure=1.2,
                    substitution="procedural room corner stands in for the PRTT teaser room")
