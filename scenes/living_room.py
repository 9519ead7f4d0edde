"""LIVING-ROOM (thesis §4.3.1, figs. 4.12, 4.14, 4.15): a large scene for sub-scene networks.

The thesis's living room (a sofa, the floor and three shelves) is not public. This procedural
one spreads the same parts over a 7 m × 5 m floor: a sofa against the back wall, a tall
bookcase on the right ("right shelves"), a low sideboard on the left and two floating shelves
above the sofa ("front and top shelves"), with books and vases casting detailed shadows on
boards that are far apart — the case where one small network per sub-scene beats one big one.

Object names encode the thesis's semantic groups (fig. 4.14b) as the prefix before '.':
``floor``, ``wall``, ``sofa.*``, ``right_shelves.*``, ``front_top_shelves.*``.
"""

from __future__ import annotations

import numpy as np

from prtbench.scene import params as P
from prtbench.scene.geometry import grid_plane
from prtbench.scene.model import Scene, SceneObject
from prtbench.scene.registry import register_scene
from scenes.common import assemble, check_variant, material
from scenes.primitives import box, lathe, merge, rotate_y, transformed, translate

FLOOR = (7.0, 5.0)
WALL_Z = -2.5
WALL_HEIGHT = 2.6


def _sofa() -> tuple[list, list]:
    """Frame (base, back, arms, feet) and cushions of a three-seat sofa against the back wall."""
    z0 = WALL_Z + 0.15  # the back stands just off the wall
    frame = [box((2.4, 0.3, 0.95), center=(0.0, 0.25, z0 + 0.475)),
             box((2.4, 0.55, 0.22), center=(0.0, 0.675, z0 + 0.11)),
             box((0.22, 0.35, 0.95), center=(-1.09, 0.575, z0 + 0.475)),
             box((0.22, 0.35, 0.95), center=(1.09, 0.575, z0 + 0.475))]
    for sx in (-1, 1):
        for dz in (0.08, 0.87):
            frame.append(box((0.08, 0.1, 0.08), center=(sx * 1.1, 0.05, z0 + dz)))
    cushions = [box((0.64, 0.16, 0.7), center=(x, 0.48, z0 + 0.56)) for x in (-0.66, 0.0, 0.66)]
    cushions += [box((0.6, 0.42, 0.14), center=(x, 0.75, z0 + 0.3)) for x in (-0.66, 0.0, 0.66)]
    return frame, cushions


def _books(rng: np.random.Generator, *, x0: float, x1: float, y: float, z: float,
           depth: float) -> list:
    """A row of upright books from x0 to x1 standing on a board at height ``y``."""
    books, x = [], x0
    while x < x1:
        w, h = rng.uniform(0.025, 0.06), rng.uniform(0.2, 0.34)
        if x + w > x1:
            break
        if rng.random() < 0.12:  # a gap, so light reaches the back panel between books
            x += rng.uniform(0.05, 0.12)
            continue
        books.append(box((w, h, depth * rng.uniform(0.75, 0.95)), center=(x + w / 2, y + h / 2, z)))
        x += w + rng.uniform(0.0, 0.006)
    return books


def _bookcase(rng: np.random.Generator) -> tuple[list, list]:
    """A tall open bookcase, built facing +z at the origin (placed by the caller)."""
    width, height, depth = 1.0, 2.0, 0.35
    frame = [box((0.04, height, depth), center=(sx * (width / 2 - 0.02), height / 2, 0.0))
             for sx in (-1, 1)]
    frame.append(box((width, height, 0.02), center=(0.0, height / 2, -depth / 2 + 0.01)))
    books = []
    for level, y in enumerate(np.linspace(0.04, height - 0.02, 5)):
        frame.append(box((width - 0.08, 0.03, depth - 0.02), center=(0.0, y, 0.01)))
        if level < 4:
            books += _books(rng, x0=-width / 2 + 0.05, x1=width / 2 - 0.05, y=y + 0.015,
                            z=0.02, depth=depth - 0.06)
    return frame, books


def _vase(x: float, y: float, z: float, *, height: float) -> object:
    r = 0.35 * height
    profile = [(0, 0), (0.6 * r, 0), (0.6 * r, 0), (r, 0.35 * height), (0.55 * r, 0.8 * height),
               (0.6 * r, height), (0.6 * r, height), (0, height)]
    return transformed(lathe(profile, segments=32), translate(x, y, z))


def _front_top_shelves(rng: np.random.Generator) -> tuple[list, list]:
    """A low sideboard with cubbies (left) and two floating shelves above the sofa."""
    boards, items = [], []
    # Sideboard: 1.4 m long, 0.7 m high, 0.45 m deep, three cubbies, against the back wall.
    cx, cz, w, h, d = -2.5, WALL_Z + 0.25, 1.4, 0.7, 0.45
    boards += [box((w, 0.03, d), center=(cx, y, cz)) for y in (0.08, 0.38, h)]
    boards += [box((0.03, h, d), center=(cx + dx, h / 2, cz))
               for dx in (-w / 2, -w / 6, w / 6, w / 2)]
    boards.append(box((w, h, 0.02), center=(cx, h / 2, cz - d / 2 + 0.01)))
    items += _books(rng, x0=cx - w / 2 + 0.03, x1=cx - w / 6 - 0.02, y=0.395, z=cz + 0.02,
                    depth=0.3)
    items += [_vase(cx + 0.45, h + 0.015, cz, height=0.35), _vase(cx - 0.3, h + 0.015, cz + 0.05,
                                                                 height=0.22)]
    # Floating shelves above the sofa.
    for y, x_left, x_right in ((1.45, -1.1, 0.2), (1.85, -0.3, 1.1)):
        boards.append(box((x_right - x_left, 0.035, 0.25), center=((x_left + x_right) / 2, y,
                                                                   WALL_Z + 0.125)))
        items += _books(rng, x0=x_left + 0.05, x1=(x_left + x_right) / 2, y=y + 0.0175,
                        z=WALL_Z + 0.13, depth=0.2)
        items.append(_vase(x_right - 0.2, y + 0.0175, WALL_Z + 0.125, height=0.25))
    return boards, items


@register_scene("living-room", params={"floor_subdivisions": P.grid_subdivisions(),
                                          "seed": P.seed()})
def build(*, variant: str = "diffuse", floor_subdivisions: int = 1, seed: int = 5) -> Scene:
    """A large living room: sofa, bookcase, sideboard and wall shelves on a 7 m × 5 m floor.

    Parameters
    ----------
    variant : {"diffuse", "glossy"}
        Glossy: all shelves varnished (ks 0.3, s 64), floor and sofa stay diffuse, as in the
        thesis's fig. 4.12 (right).
    floor_subdivisions : int
        Floor quads per side k (2·k² floor triangles).
    seed : int
        Seed of the book sizes.
    """
    check_variant(variant)
    rng = np.random.default_rng(seed)
    sofa_frame, cushions = _sofa()
    case_frame, case_books = _bookcase(rng)
    right = translate(2.9, 0.0, -1.3) @ rotate_y(-90.0)  # faces −x, towards the sofa
    case_frame = [transformed(m, right) for m in case_frame]
    case_books = [transformed(m, right) for m in case_books]
    boards, items = _front_top_shelves(rng)
    wood = dict(ks=0.3, shininess=64.0)
    objects = [
        SceneObject("floor", grid_plane(FLOOR, floor_subdivisions),
                    material(variant, "floor", (0.6, 0.55, 0.48))),
        SceneObject("wall", box((FLOOR[0], WALL_HEIGHT, 0.1),
                                center=(0.0, WALL_HEIGHT / 2, WALL_Z - 0.05)),
                    material(variant, "wall", (0.75, 0.73, 0.7))),
        SceneObject("sofa.frame", merge(sofa_frame), material(variant, "sofa", (0.3, 0.36, 0.45))),
        SceneObject("sofa.cushions", merge(cushions),
                    material(variant, "cushions", (0.45, 0.5, 0.58))),
        SceneObject("right_shelves.frame", merge(case_frame),
                    material(variant, "bookcase", (0.5, 0.34, 0.2), **wood)),
        SceneObject("right_shelves.books", merge(case_books),
                    material(variant, "books", (0.55, 0.25, 0.2))),
        SceneObject("front_top_shelves.boards", merge(boards),
                    material(variant, "shelves", (0.62, 0.5, 0.36), **wood)),
        SceneObject("front_top_shelves.items", merge(items),
                    material(variant, "shelf-items", (0.3, 0.45, 0.52), **wood)),
    ]
    return assemble("living-room", objects, variant=variant,
                    params={"floor_subdivisions": floor_subdivisions, "seed": seed},
                    center=(0.0, 0.8, -1.0), orbit_radius=4.3, orbit_height=1.3,
                    default_light="sky", exposure=0.9, start_degrees=-60.0, arc_degrees=120.0,
                    substitution="a procedural living room (sofa, bookcase, sideboard, wall "
                                 "shelves) stands in for the thesis's LIVING-ROOM")
