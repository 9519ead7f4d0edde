"""FOUR-ANIMALS: the stand-in for Raghavan et al. 2023's "Four Animals" scene.

Four CGAL demo meshes (Debian ``libcgal-demo``, the ``cgal-meshes`` asset) on a glossy ground
around a glossy metallic ring: the armadillo, the bunny (``bunny00``), the lion head and the
Chinese dragon statue (``ChineseDragon-10kv``, a guardian-dragon figure: the package's only
dragon, standing in for the paper's). The ring is an upright torus with a gold Phong lobe
(high ks, high s) whose reflections on the animals and whose glossy indirect light on the
ground change with the view, as the paper's ring does.

Views: two trajectories (the ``trajectory`` parameter; the geometry and so every method's
precompute is the same for both, since :meth:`Scene.content_hash` ignores cameras):

* ``near`` (default): the training orbit, 30 views on a circle of radius 2.3 at a 0.9 height
  above the look-at point; the paper's spherical training trajectories.
* ``far``: a held-out helix, 30 views at radius 3.3 rising from 0.4 to 1.9 above the look-at
  point over one turn, its azimuths offset by half a step from ``near``'s, so no view repeats
  a training view; the paper's "far views" (novel trajectories) of its Table 1.
"""

from __future__ import annotations

import math

from prtbench.api.errors import InvalidInputError
from prtbench.scene import params as P
from prtbench.scene.geometry import grid_plane
from prtbench.scene.model import Material, Scene, SceneObject, Trajectory, View
from prtbench.scene.registry import register_scene
from scenes.common import asset_mesh, check_variant, material
from scenes.lion import lion_mesh
from scenes.primitives import rotate_y, torus, transformed, translate

SUBSTITUTION = ("CGAL armadillo, bunny00, lion-head and ChineseDragon statue (libcgal-demo) "
                "stand in for the paper's Four Animals; our ring is a gold Phong torus")
TRAJECTORIES = ("near", "far")
#: Look-at point of both trajectories: the middle of the animals' height.
CENTER = (0.0, 0.35, 0.0)
N_VIEWS = 30
RING_MAJOR, RING_MINOR = 0.3, 0.04


def _ring(variant: str) -> Material:
    """Gold: a strong, sharp coloured lobe over a dark diffuse base (kd + ks ≤ 1 per channel).
    The diffuse variant keeps a gold-coloured diffuse ring."""
    check_variant(variant)
    if variant == "diffuse":
        return Material(kd=(0.75, 0.6, 0.3), name="ring")
    return Material(kd=(0.05, 0.04, 0.02), ks=(0.9, 0.72, 0.4), shininess=400.0, name="ring")


def trajectory_views(name: str) -> Trajectory:
    """The ``near`` (training orbit) or ``far`` (held-out helix) views, 30 each."""
    if name == "near":
        return Trajectory.orbit(center=CENTER, radius=2.3, height=0.9, n_views=N_VIEWS,
                                fov_y=45.0, start_degrees=0.0)
    if name != "far":
        raise InvalidInputError(f"four-animals trajectory '{name}'; accepted: "
                                f"{', '.join(TRAJECTORIES)}")
    views = []
    step = 360.0 / N_VIEWS
    for i in range(N_VIEWS):
        a = math.radians(step / 2 + step * i)
        height = 0.4 + 1.5 * i / (N_VIEWS - 1)
        eye = (CENTER[0] + 3.3 * math.sin(a), CENTER[1] + height, CENTER[2] + 3.3 * math.cos(a))
        views.append(View(eye=eye, target=CENTER, fov_y=40.0))
    return Trajectory(tuple(views))


@register_scene("four-animals", params={"trajectory": P.choice(*TRAJECTORIES),
                                        "ground_subdivisions": P.grid_subdivisions()})
def build(*, variant: str = "diffuse", trajectory: str = "near", ground_subdivisions: int = 1,
          ) -> Scene:
    """Armadillo, bunny, lion head and dragon statue around a gold ring on a glossy ground.

    Parameters
    ----------
    variant : {"diffuse", "glossy"}
        Glossy: glossy ground (ks 0.25, s 48), lacquered animals (ks 0.35–0.45, s 64–128) and
        the gold ring (ks (0.9, 0.72, 0.4), s 400).
    trajectory : {"near", "far"}
        The training orbit or the held-out helix (module docstring).
    ground_subdivisions : int
        Ground quads per side k (2·k² triangles).
    """
    check_variant(variant)
    views = trajectory_views(trajectory)
    # Files: the armadillo is y-up facing −z, the bunny faces −x, the lion (mounted upright by
    # lion_mesh) and the dragon statue face +z; each is turned to face the ring at the centre.
    armadillo = asset_mesh("cgal-meshes", "armadillo.off", height=0.75, rotate_y_degrees=135.0,
                           position=(-0.7, 0.0, -0.6))
    bunny = asset_mesh("cgal-meshes", "bunny00.off", height=0.55, rotate_y_degrees=90.0 - 35.0,
                       position=(0.7, 0.0, -0.6))
    lion = lion_mesh(height=0.55, rotate_y_degrees=45.0, position=(-0.7, 0.0, 0.6))
    dragon = asset_mesh("cgal-meshes", "ChineseDragon-10kv.off", height=0.6,
                        rotate_y_degrees=-45.0, position=(0.7, 0.0, 0.6))
    # Upright in the xy-plane, turned 30° about +Y, sunk 1 cm so it stands on the ground
    # rather than touching it at one tangent point.
    ring = transformed(torus(major=RING_MAJOR, minor=RING_MINOR, segments=96, sides=24),
                       translate(0.0, RING_MAJOR + RING_MINOR - 0.01, 0.0) @ rotate_y(30.0))
    objects = [
        SceneObject("ground", grid_plane(5.0, ground_subdivisions),
                    material(variant, "ground", (0.5, 0.5, 0.5), ks=0.25, shininess=48.0)),
        SceneObject("armadillo", armadillo, material(variant, "armadillo", (0.55, 0.4, 0.25),
                                                     ks=0.4, shininess=96.0)),
        SceneObject("bunny", bunny, material(variant, "bunny", (0.75, 0.72, 0.66), ks=0.35,
                                             shininess=128.0)),
        SceneObject("lion", lion, material(variant, "lion", (0.7, 0.5, 0.3), ks=0.45,
                                           shininess=64.0)),
        SceneObject("dragon", dragon, material(variant, "dragon", (0.3, 0.55, 0.35), ks=0.4,
                                               shininess=96.0)),
        SceneObject("ring", ring, _ring(variant)),
    ]
    return Scene("four-animals", objects, variant=variant, default_light="sky", trajectory=views,
                 exposure=0.7, substitution=SUBSTITUTION,
                 params={"trajectory": trajectory, "ground_subdivisions": ground_subdivisions})
