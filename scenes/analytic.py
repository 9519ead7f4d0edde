"""Analytic scenes: a ground plane, and a sphere over a plane (DESIGN.md §13).

Their transfer has closed forms, so tests check methods and the reference against them:

* ``plane``: nothing occludes an up-facing point, so T_0 = √π/2 (n = +Y) everywhere.
* ``sphere-over-plane``: a sphere of radius r whose centre is at height h above the ground
  hides the cosine-weighted fraction (r/h)² of the hemisphere of the ground point directly below
  it, so its unoccluded fraction is 1 − (r/h)².

The sphere is a latitude-longitude polyhedron scaled radially so that its surface area equals
4πr² (see :func:`scenes.primitives.uv_sphere`): by Cauchy's formula its mean silhouette then
equals the sphere's, instead of the smaller shadow of an inscribed polyhedron. Measured by ray
casting (Malley's method) below the sphere with the default 64 segments and h = 2r: occluded
fraction 0.24993 against (r/h)² = 0.25, a relative bias of −0.03 % (the inscribed polyhedron:
−0.23 %; 32 segments: −0.09 %). ``tests/scenes/test_scenes.py`` checks it to 0.2 %.
"""

from __future__ import annotations

import dataclasses

from prtbench.api.errors import InvalidInputError
from prtbench.scene import params as P
from prtbench.scene.geometry import grid_plane
from prtbench.scene.model import Material, Scene, SceneObject, Trajectory
from prtbench.scene.registry import register_scene
from scenes.primitives import uv_sphere

GROUND = {
    "diffuse": Material(kd=(0.5, 0.5, 0.5), name="ground"),
    "glossy": Material(kd=(0.35, 0.35, 0.35), ks=(0.3, 0.3, 0.3), shininess=32.0, name="ground"),
}
SPHERE = {
    "diffuse": Material(kd=(0.7, 0.45, 0.3), name="sphere"),
    "glossy": Material(kd=(0.45, 0.25, 0.15), ks=(0.45, 0.45, 0.45), shininess=128.0,
                       name="sphere"),
}


def _check_variant(variant: str) -> None:
    if variant not in GROUND:
        raise InvalidInputError(f"unknown variant '{variant}'; known: {', '.join(GROUND)}")


@register_scene("plane", params={"size": P.length(), "subdivisions": P.grid_subdivisions()})
def plane(*, variant: str = "diffuse", size: float = 4.0, subdivisions: int = 1) -> Scene:
    """A square ground plane on y = 0 centred at the origin, normals +Y.

    Parameters
    ----------
    variant : {"diffuse", "glossy"}
    size : float
        Edge length.
    subdivisions : int
        Quads per side k; the plane has 2·k² triangles.
    """
    _check_variant(variant)
    if not size > 0:
        raise InvalidInputError(f"plane size={size}; accepted: > 0")
    ground = SceneObject("ground", grid_plane(size, subdivisions), GROUND[variant])
    views = Trajectory.orbit(center=(0.0, 0.0, 0.0), radius=0.9 * size, height=0.6 * size,
                             n_views=30)
    return Scene("plane", [ground], variant=variant, default_light="sky", trajectory=views,
                 exposure=0.7, params={"size": size, "subdivisions": subdivisions})


@register_scene("sphere-over-plane", params={
    "radius": P.length(), "height": P.length(),
    "sphere_segments": P.count(low=8, triangles=lambda s: float(s) * s),
    "plane_size": P.length(), "plane_subdivisions": P.grid_subdivisions(),
    "sphere_shininess": P.real(low=0.0, high=1e6)})
def sphere_over_plane(*, variant: str = "diffuse", radius: float = 0.5, height: float = 1.0,
                      sphere_segments: int = 64, plane_size: float = 8.0,
                      plane_subdivisions: int = 1, sphere_shininess: float = 128.0) -> Scene:
    """A sphere of ``radius`` centred at (0, ``height``, 0) over the y = 0 ground plane.

    Parameters
    ----------
    variant : {"diffuse", "glossy"}
    radius : float
        Sphere radius r > 0.
    height : float
        Distance h > r from the plane to the sphere centre; the ground point directly below has
        cosine-weighted unoccluded fraction 1 − (r/h)².
    sphere_segments : int
        Longitude segments (latitude rings are half as many); 2·s·(s/2 − 1) triangles.
    plane_size : float
        Ground edge length.
    plane_subdivisions : int
        Ground quads per side k (2·k² triangles).
    sphere_shininess : float
        Phong exponent s of the glossy sphere (the gloss sweep of table factored-gloss).
        Ignored by the diffuse variant.
    """
    _check_variant(variant)
    if not (radius > 0 and height > radius):
        raise InvalidInputError(f"sphere radius={radius}, height={height}; accepted: "
                                "0 < radius < height")
    if sphere_segments < 8:
        raise InvalidInputError(f"sphere_segments={sphere_segments}; accepted: >= 8")
    if not plane_size > 2 * radius:
        raise InvalidInputError(f"plane_size={plane_size}; accepted: > 2 * radius")
    ball = uv_sphere(radius=radius, segments=sphere_segments, center=(0.0, height, 0.0),
                     match_area=True)
    sphere = SPHERE[variant]
    if variant == "glossy" and sphere_shininess != sphere.shininess:
        sphere = dataclasses.replace(sphere, shininess=float(sphere_shininess))
    objects = [SceneObject("ground", grid_plane(plane_size, plane_subdivisions), GROUND[variant]),
               SceneObject("sphere", ball, sphere)]
    extent = height + radius
    views = Trajectory.orbit(center=(0.0, 0.5 * extent, 0.0), radius=3.0 * extent,
                             height=1.2 * extent, n_views=30)
    params = {"radius": radius, "height": height, "sphere_segments": sphere_segments,
              "plane_size": plane_size, "plane_subdivisions": plane_subdivisions,
              "sphere_shininess": float(sphere_shininess)}
    return Scene("sphere-over-plane", objects, variant=variant, default_light="sky",
                 trajectory=views, exposure=0.7, params=params)
