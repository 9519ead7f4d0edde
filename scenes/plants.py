"""PLANTS: procedural potted plants on a minimally tessellated ground (PRTT Fig. 4, thesis 4.8).

The papers' Plants scene (18K vertices) is not public; this stands in for it with five potted
plants of three kinds (a rosette of long blades, a branching bush, a tall plant with a trunk),
about 20k triangles, whose leaves cast high-frequency shadows on a ground plane of only two
triangles by default. ``ground_subdivisions`` k gives the ground 2·k² triangles (the
tessellation study uses k = 1, 8, 64, 512).
"""

from __future__ import annotations

import math

import numpy as np

from prtbench.api.errors import InvalidInputError
from prtbench.scene import params as P
from prtbench.scene.geometry import grid_plane
from prtbench.scene.model import Scene, SceneObject, TriangleMesh
from prtbench.scene.registry import register_scene
from scenes.common import assemble, check_variant, material
from scenes.primitives import (
    lathe,
    leaf,
    merge,
    rotate_x,
    rotate_y,
    rotate_z,
    scale,
    transformed,
    translate,
    tube,
)

LEAF_GREENS = [(0.16, 0.42, 0.10), (0.22, 0.50, 0.14), (0.12, 0.34, 0.12)]


def _pot(radius: float, height: float, at: np.ndarray) -> tuple[TriangleMesh, TriangleMesh]:
    """A tapered pot with a rim (closed solid) and its soil disc, standing at ``at``."""
    r0, r1, rim = 0.72 * radius, radius, 0.03 * radius / 0.15
    profile = [(0, 0), (r0, 0), (r0, 0), (r1, height - rim), (r1, height - rim),
               (r1 + rim * 0.5, height - rim), (r1 + rim * 0.5, height - rim),
               (r1 + rim * 0.5, height), (r1 + rim * 0.5, height),
               (r1 - rim * 0.6, height), (r1 - rim * 0.6, height),
               (r1 - rim * 0.6, height - 0.6 * rim), (r1 - rim * 0.6, height - 0.6 * rim),
               (0, height - 0.6 * rim)]
    pot = transformed(lathe(profile, segments=32), translate(*at))
    soil_r = r1 - rim * 0.6
    soil_profile = [(0, 0), (soil_r, 0), (soil_r, 0), (soil_r, 0.02), (soil_r, 0.02), (0, 0.025)]
    soil = transformed(lathe(soil_profile, segments=32),
                       translate(at[0], at[1] + height - 0.6 * rim - 0.01, at[2]))
    return pot, soil


def _placed_leaf(base: np.ndarray, *, yaw: float, pitch: float, roll: float, length: float,
                 width: float, bend: float) -> TriangleMesh:
    blade = leaf(length=1.0, width=width / length, thickness=0.02, bend=bend)
    world_from_leaf = (translate(*base) @ rotate_y(yaw) @ rotate_x(-pitch) @ rotate_z(roll)
                       @ scale(length))
    return transformed(blade, world_from_leaf)


def _rosette(rng: np.random.Generator, top: np.ndarray, n_leaves: int, size: float,
             ) -> tuple[list[TriangleMesh], list[TriangleMesh]]:
    """Long arching blades growing straight from the soil (spider-plant like)."""
    leaves = []
    for i in range(n_leaves):
        yaw = 360.0 * i / n_leaves + rng.uniform(-12, 12)
        pitch = rng.uniform(35, 70)
        leaves.append(_placed_leaf(top + rng.normal(0, 0.01, 3) * [1, 0, 1], yaw=yaw,
                                   pitch=pitch, roll=rng.uniform(-15, 15),
                                   length=size * rng.uniform(0.75, 1.1),
                                   width=size * rng.uniform(0.09, 0.13),
                                   bend=rng.uniform(0.5, 0.9)))
    return leaves, []


def _bush(rng: np.random.Generator, top: np.ndarray, n_branches: int, leaves_per_branch: int,
          size: float) -> tuple[list[TriangleMesh], list[TriangleMesh]]:
    """Branching stems with leaves along them."""
    leaves, stems = [], []
    for b in range(n_branches):
        yaw = math.radians(360.0 * b / n_branches + rng.uniform(-20, 20))
        tilt = rng.uniform(0.35, 0.8)
        direction = np.array([math.sin(yaw) * tilt, 1.0, math.cos(yaw) * tilt])
        direction /= np.linalg.norm(direction)
        end = top + direction * size * rng.uniform(0.8, 1.1)
        stems.append(tube(top, end, radius=0.008 * size / 0.4, end_radius=0.004 * size / 0.4))
        for k in range(leaves_per_branch):
            t = 0.35 + 0.65 * (k + 1) / leaves_per_branch
            base = top + (end - top) * t
            side = 1 if k % 2 else -1
            leaves.append(_placed_leaf(base, yaw=math.degrees(yaw) + side * rng.uniform(40, 80),
                                       pitch=rng.uniform(-5, 30), roll=side * rng.uniform(5, 25),
                                       length=size * rng.uniform(0.28, 0.38),
                                       width=size * rng.uniform(0.14, 0.19),
                                       bend=rng.uniform(0.15, 0.35)))
    return leaves, stems


def _tall(rng: np.random.Generator, top: np.ndarray, n_leaves: int, height: float,
          ) -> tuple[list[TriangleMesh], list[TriangleMesh]]:
    """A trunk with big leaves on short petioles in a spiral (fiddle-leaf-fig like)."""
    stems = [tube(top, top + [0, height, 0], radius=0.014, end_radius=0.008, segments=8)]
    leaves = []
    for i in range(n_leaves):
        t = 0.3 + 0.7 * i / max(n_leaves - 1, 1)
        yaw = 137.5 * i  # golden-angle phyllotaxis spreads the leaves evenly
        node = top + [0, height * t, 0]
        out = np.array([math.sin(math.radians(yaw)), 0.5, math.cos(math.radians(yaw))])
        petiole_end = node + 0.05 * out
        stems.append(tube(node, petiole_end, radius=0.004, segments=5))
        leaves.append(_placed_leaf(petiole_end, yaw=yaw, pitch=rng.uniform(5, 30),
                                   roll=rng.uniform(-20, 20), length=rng.uniform(0.22, 0.3),
                                   width=rng.uniform(0.12, 0.16), bend=rng.uniform(0.2, 0.4)))
    return leaves, stems


@register_scene("plants", params={"ground_subdivisions": P.grid_subdivisions(),
                                     "ground_size": P.length(low=2.5), "seed": P.seed()})
def build(*, variant: str = "diffuse", ground_subdivisions: int = 1, ground_size: float = 3.0,
          seed: int = 3) -> Scene:
    """Five potted plants on a ground of 2·k² triangles.

    Parameters
    ----------
    variant : {"diffuse", "glossy"}
        Glossy: waxy leaves (ks 0.2, s 64) and glazed pots (ks 0.35, s 128).
    ground_subdivisions : int
        Ground quads per side k (k = 1 is the papers' two-triangle ground).
    ground_size : float
        Ground edge length (the pots span about 2 units).
    seed : int
        Seed of the leaf placement jitter.
    """
    check_variant(variant)
    if ground_size < 2.5:
        raise InvalidInputError(f"plants ground_size={ground_size}; accepted: >= 2.5")
    rng = np.random.default_rng(seed)
    # (kind, pot centre x/z, pot radius, pot height, size)
    layout = [("tall", (0.05, -0.25), 0.16, 0.30, 0.95),
              ("bush", (-0.62, 0.22), 0.15, 0.24, 0.42),
              ("rosette", (0.62, 0.28), 0.14, 0.22, 0.48),
              ("bush", (0.0, 0.62), 0.11, 0.18, 0.32),
              ("rosette", (-0.55, -0.62), 0.12, 0.20, 0.40)]
    pots, soils, stems, leaves = [], [], [], []
    for kind, (x, z), radius, height, size in layout:
        pot, soil = _pot(radius, height, np.array([x, 0.0, z]))
        pots.append(pot)
        soils.append(soil)
        top = np.array([x, height - 0.01, z])
        if kind == "rosette":
            new_leaves, new_stems = _rosette(rng, top, 22, size)
        elif kind == "bush":
            new_leaves, new_stems = _bush(rng, top, 7, 7, size)
        else:
            new_leaves, new_stems = _tall(rng, top, 26, size)
        leaves += new_leaves
        stems += new_stems
    # Three leaf colours, one object each: variation without textures.
    leaf_groups = [merge(leaves[i::3]) for i in range(3)]
    objects = [SceneObject("ground", grid_plane(ground_size, ground_subdivisions),
                           material(variant, "ground", (0.55, 0.52, 0.47)))]
    objects += [SceneObject(f"leaves{i}", mesh, material(variant, f"leaves{i}", LEAF_GREENS[i],
                                                         ks=0.2, shininess=64.0))
                for i, mesh in enumerate(leaf_groups)]
    objects += [SceneObject("stems", merge(stems), material(variant, "stems", (0.25, 0.35, 0.12))),
                SceneObject("pots", merge(pots), material(variant, "pots", (0.62, 0.30, 0.18),
                                                          ks=0.35, shininess=128.0)),
                SceneObject("soil", merge(soils), material(variant, "soil", (0.16, 0.11, 0.07)))]
    params = {"ground_subdivisions": ground_subdivisions, "ground_size": ground_size,
              "seed": seed}
    return assemble("plants", objects, variant=variant, params=params, center=(0.0, 0.35, 0.0),
                    orbit_radius=2.4, orbit_height=1.3, default_light="sky", exposure=0.75,
                    substitution="procedural potted plants stand in for the papers' Plants scene")
