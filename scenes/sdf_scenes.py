"""Continuous (SDF) scenes standing in for the thesis's SDF results (Sirikonda 2023, §4.2.2).

The thesis renders four analytic SDFs — OLD-CAR and FISH from Takikawa et al.'s SDF dataset
(JCGT 2022), MIKE-MONSTER (Quilez, Shadertoy 2013) and RABBIT (Fizzler, Shadertoy 2018) — and
the neural SDF of the Stanford bunny from Davies et al. 2021 (tables 4.2, 4.3, figs. 4.1, 4.9,
4.10). Those shader sources are not redistributable assets here, so each scene is modelled
anew from primitives and smooth Booleans in the same spirit (``sdf-car``, ``sdf-monster``,
``sdf-fish``, ``sdf-rabbit``), and the neural bunny is our own small MLP fitted to the CGAL
bunny (``sdf-bunny-neural``, :mod:`prtbench.transport.neural_sdf`) in the two sizes of table 4.3.

Every scene stands on a ground plane that is part of its SDF (the half space y ≤ 0, bounded by
the scene's tracing box, which makes it a 4 × 4 square like the mesh scenes' grounds). The
scene's ``objects`` are the marching-cubes mesh of the whole SDF split by material id
(``objects[k]`` has ``sdf.materials[k]``), at ``mc_resolution`` cells along the box's longest
side: the Mitsuba reference, geometry masks and mesh methods use it, continuous methods
sphere-trace ``scene.sdf``.
"""

from __future__ import annotations

from typing import Any

from prtbench.api.errors import InvalidInputError
from prtbench.scene import params as P
from prtbench.scene.model import Material, Scene
from prtbench.scene.registry import register_scene
from prtbench.transport.neural_sdf import SIZES
from prtbench.transport.neural_sdf_fit import fit_neural_sdf
from prtbench.transport.sdf import (
    Box,
    Capsule,
    Cone,
    Cylinder,
    Ellipsoid,
    Mirror,
    Plane,
    RoundedBox,
    SdfNode,
    SdfSurface,
    Sphere,
    Torus,
    intersection,
    sdf_scene_objects,
    subtract,
    union,
)
from scenes.common import assemble, asset_mesh, check_variant, material

#: Default marching-cubes resolution (cells along the 4-unit side of the box: 1.6 cm cells).
MC_RESOLUTION = 256

#: The ground square's half size and the tracing box below the ground.
GROUND_HALF = 2.0
BELOW_GROUND = 0.05


def _ground_material(variant: str) -> Material:
    return material(variant, "ground", (0.5, 0.5, 0.5), ks=0.15, shininess=16.0)


def _as_int(value: Any, name: str, low: int, high: int) -> int:
    """``value`` as an int in [low, high]; numeric strings (``--scene-param k=v``) accepted."""
    try:
        number = int(value) if isinstance(value, str) else value
        ok = int(number) == number and low <= number <= high
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise InvalidInputError(f"{name}={value!r}; accepted: integers {low}..{high}")
    return int(number)


#: ``mc_resolution`` r: a float32 distance grid and a bool mask of at most r³ nodes, and a
#: marching-cubes mesh of ~8·r² triangles (a surface spanning the grid).
MC_PARAM = P.count(low=16, high=1024, triangles=lambda r: 8.0 * r * r,
                   extra_bytes=lambda r: 5.0 * r ** 3)


def _check_resolution(mc_resolution: Any) -> int:
    return _as_int(mc_resolution, "mc_resolution", 16, 1024)


def sdf_scene(name: str, shape: SdfNode, materials: list[Material], *, variant: str,
              height: float, mc_resolution: int, params: dict[str, Any], substitution: str,
              center_y: float, orbit_radius: float = 2.8, orbit_height: float = 1.2,
              exposure: float = 0.7) -> Scene:
    """A Scene of ``shape`` on the ground plane (material 0) with its marching-cubes objects.

    Parameters
    ----------
    shape : SdfNode
        The object(s), standing on y = 0, within |x|, |z| < 2 and below ``height``.
    materials : list of Material
        ``materials[k]`` for material id k (id 0 is the ground).
    """
    mc_resolution = _check_resolution(mc_resolution)
    root = union(Plane((0.0, 1.0, 0.0), 0.0, material=0), shape)
    bounds = ((-GROUND_HALF, -BELOW_GROUND, -GROUND_HALF), (GROUND_HALF, height, GROUND_HALF))
    surface = SdfSurface(root, bounds, tuple(materials), name=name)
    objects = sdf_scene_objects(surface, resolution=mc_resolution)
    scene = assemble(name, objects, variant=variant,
                     params={**params, "mc_resolution": mc_resolution},
                     center=(0.0, center_y, 0.0), orbit_radius=orbit_radius,
                     orbit_height=orbit_height, exposure=exposure, fov_y=40.0,
                     substitution=substitution)
    scene.sdf = surface
    return scene


# --- sdf-car -------------------------------------------------------------------------------------

def car_shape() -> SdfNode:
    """A 1930s roadster, 2.3 long along x (front +x), ~1.1 high; ids 1 paint, 2 tyres, 3 chrome,
    4 glass."""
    paint, tyre, chrome, glass = 1, 2, 3, 4
    z_axis = (1.0, 0.0, 0.0)  # rotating a +Y-axis primitive 90° about x points it along z
    # Wheels: tyres (tori about z) with chrome hubs; mirrored to both sides (z < 0 copies).
    wheel = union(
        Torus(0.21, 0.095, material=tyre).rotate(z_axis, 90.0),
        Cylinder(0.13, 0.06, material=chrome).rotate(z_axis, 90.0),
    )
    wheels = Mirror(union(wheel.translate(0.68, 0.3, 0.46), wheel.translate(-0.68, 0.3, 0.46)),
                    "z")
    # Fenders: half cylinders over the wheels, blended into the body.
    fender = intersection(
        Cylinder(0.37, 0.12, material=paint).rotate(z_axis, 90.0),
        Plane((0.0, -1.0, 0.0), -0.3, material=paint),
    )
    fenders = Mirror(union(fender.translate(0.68, 0.3, 0.45), fender.translate(-0.68, 0.3, 0.45),
                           Box((0.33, 0.02, 0.1), material=paint).translate(0.0, 0.32, 0.43)),
                     "z")
    chassis = RoundedBox((0.98, 0.15, 0.36), 0.08, material=paint).translate(0.0, 0.44, 0.0)
    hood = RoundedBox((0.38, 0.15, 0.28), 0.1, material=paint).translate(0.55, 0.64, 0.0)
    cabin = RoundedBox((0.42, 0.27, 0.36), 0.1, material=paint).translate(-0.25, 0.8, 0.0)
    roof = RoundedBox((0.48, 0.035, 0.39), 0.03, material=paint).translate(-0.25, 1.09, 0.0)
    trunk = RoundedBox((0.22, 0.2, 0.33), 0.12, material=paint).translate(-0.82, 0.6, 0.0)
    body = union(chassis, hood, cabin, roof, trunk, k=0.08)
    # Side and front windows: glass panels standing 5 mm proud of the cabin.
    windows = union(
        Mirror(union(RoundedBox((0.15, 0.12, 0.02), 0.015, material=glass).translate(
            -0.43, 0.86, 0.35), RoundedBox((0.15, 0.12, 0.02), 0.015, material=glass).translate(
            -0.07, 0.86, 0.35)), "z"),
        RoundedBox((0.02, 0.12, 0.3), 0.015, material=glass).translate(0.13, 0.86, 0.0),
    )
    lights = Mirror(union(Sphere(0.085, material=chrome).translate(0.97, 0.78, 0.24),
                          Cylinder(0.02, 0.06, material=chrome).translate(0.93, 0.68, 0.24)), "z")
    grille = RoundedBox((0.04, 0.14, 0.22), 0.02, material=chrome).translate(0.94, 0.63, 0.0)
    bumpers = union(
        Capsule((1.06, 0.33, -0.42), (1.06, 0.33, 0.42), 0.04, material=chrome),
        Capsule((-1.06, 0.33, -0.42), (-1.06, 0.33, 0.42), 0.04, material=chrome),
    )
    spare = union(Torus(0.2, 0.08, material=tyre), Cylinder(0.12, 0.05, material=chrome)).rotate(
        (0.0, 0.0, 1.0), 90.0).translate(-1.1, 0.66, 0.0)
    return union(union(body, fenders, k=0.05), wheels, windows, lights, grille, bumpers, spare)


@register_scene("sdf-car", params={"mc_resolution": MC_PARAM})
def build_car(*, variant: str = "diffuse", mc_resolution: int = MC_RESOLUTION) -> Scene:
    """SDF vintage car on the ground (stands in for the thesis's OLD-CAR).

    Parameters
    ----------
    variant : {"diffuse", "glossy"}
        Glossy: lacquered paint (ks 0.35, s 128), chrome (ks 0.6, s 256), glass (ks 0.5, s 512).
    mc_resolution : int
        Marching-cubes cells along the 4-unit side of the scene box.
    """
    check_variant(variant)
    materials = [
        _ground_material(variant),
        material(variant, "paint", (0.55, 0.07, 0.05), ks=0.35, shininess=128.0),
        material(variant, "tyres", (0.06, 0.06, 0.06), ks=0.05, shininess=16.0),
        material(variant, "chrome", (0.65, 0.65, 0.62), ks=0.6, shininess=256.0),
        material(variant, "glass", (0.08, 0.1, 0.12), ks=0.5, shininess=512.0),
    ]
    return sdf_scene("sdf-car", car_shape(), materials, variant=variant, height=1.3,
                     mc_resolution=mc_resolution, params={}, center_y=0.5,
                     substitution="OLD-CAR (an SDF from Takikawa et al.'s dataset) replaced by "
                                  "our own SDF vintage car (24 primitives, pairs mirrored)")


# --- sdf-monster ---------------------------------------------------------------------------------

def monster_shape() -> SdfNode:
    """A one-eyed round green monster, ~1.65 high, facing +z; ids 1 skin, 2 eye white, 3 iris,
    4 pupil, 5 horn."""
    skin, white, iris, pupil, horn = 1, 2, 3, 4, 5
    body = Ellipsoid((0.55, 0.58, 0.5), material=skin).translate(0.0, 0.98, 0.0)
    legs = Mirror(union(
        Capsule((0.22, 0.6, 0.0), (0.26, 0.12, 0.02), 0.08, material=skin),
        Ellipsoid((0.13, 0.07, 0.2), material=skin).translate(0.27, 0.07, 0.08),
        k=0.08), "x")
    arms = Mirror(union(
        Capsule((0.45, 1.0, 0.0), (0.78, 0.72, 0.12), 0.06, material=skin),
        Sphere(0.09, material=skin).translate(0.8, 0.68, 0.14),
        k=0.06), "x")
    horns = Mirror(Cone(0.09, 0.065, 0.012, material=horn).rotate((0.0, 0.0, 1.0), -20.0)
                   .translate(0.24, 1.55, 0.0), "x")
    figure = union(body, legs, arms, k=0.1)
    figure = union(figure, horns, k=0.03)
    mouth = Ellipsoid((0.3, 0.07, 0.2), material=skin).translate(0.0, 0.75, 0.47)
    figure = subtract(figure, mouth, k=0.04)
    eye = union(
        Sphere(0.25, material=white).translate(0.0, 1.12, 0.33),
        Sphere(0.12, material=iris).translate(0.0, 1.12, 0.5),
        Sphere(0.06, material=pupil).translate(0.0, 1.12, 0.575),
    )
    return union(figure, eye)


@register_scene("sdf-monster", params={"mc_resolution": MC_PARAM})
def build_monster(*, variant: str = "diffuse", mc_resolution: int = MC_RESOLUTION) -> Scene:
    """SDF one-eyed monster on the ground (stands in for the thesis's MIKE-MONSTER).

    Parameters
    ----------
    variant : {"diffuse", "glossy"}
        Glossy: satin skin (ks 0.2, s 32), wet eye (ks 0.5, s 512), glossy horns.
    mc_resolution : int
    """
    check_variant(variant)
    materials = [
        _ground_material(variant),
        material(variant, "skin", (0.3, 0.62, 0.1), ks=0.2, shininess=32.0),
        material(variant, "eye-white", (0.88, 0.88, 0.85), ks=0.5, shininess=512.0),
        material(variant, "iris", (0.15, 0.5, 0.35), ks=0.5, shininess=512.0),
        material(variant, "pupil", (0.03, 0.03, 0.03), ks=0.5, shininess=512.0),
        material(variant, "horn", (0.8, 0.74, 0.6), ks=0.3, shininess=64.0),
    ]
    return sdf_scene("sdf-monster", monster_shape(), materials, variant=variant, height=1.8,
                     mc_resolution=mc_resolution, params={}, center_y=0.8,
                     substitution="MIKE-MONSTER (Quilez, Shadertoy) replaced by our own SDF "
                                  "one-eyed monster")


# --- sdf-fish ------------------------------------------------------------------------------------

def fish_shape() -> SdfNode:
    """A clownfish sculpture on a stand, head +x; ids 1 stand, 2 orange, 3 white, 4 fins,
    5 pupils."""
    stand, orange, white, fin, pupil = 1, 2, 3, 4, 5
    base = union(
        Cylinder(0.32, 0.04, material=stand).translate(0.0, 0.04, 0.0),
        Cylinder(0.03, 0.2, material=stand).translate(0.0, 0.28, 0.0),
        k=0.04)
    cy = 0.78  # body centre height
    body = union(
        Ellipsoid((0.55, 0.28, 0.15), material=orange).translate(0.0, cy, 0.0),
        Capsule((-0.35, cy, 0.0), (-0.6, cy, 0.0), 0.06, material=orange),
        k=0.08)
    tail = Mirror(RoundedBox((0.17, 0.05, 0.02), 0.015, material=fin)
                  .rotate((0.0, 0.0, 1.0), -35.0).translate(-0.72, 0.1, 0.0), "y")
    tail = tail.translate(0.0, cy, 0.0)
    dorsal = RoundedBox((0.24, 0.09, 0.015), 0.012, material=fin).rotate(
        (0.0, 0.0, 1.0), -12.0).translate(-0.08, cy + 0.25, 0.0)
    belly = RoundedBox((0.1, 0.06, 0.015), 0.012, material=fin).rotate(
        (0.0, 0.0, 1.0), 20.0).translate(-0.25, cy - 0.24, 0.0)
    pectoral = Mirror(RoundedBox((0.1, 0.015, 0.07), 0.012, material=fin).rotate(
        (1.0, 0.0, 0.0), 30.0).translate(0.18, cy - 0.1, 0.17), "z")
    fish = union(body, tail, dorsal, belly, pectoral, k=0.05)
    # White bands: shells of a slightly larger body, cut to slabs across x.
    shell = Ellipsoid((0.56, 0.29, 0.16), material=white).translate(0.0, cy, 0.0)
    bands = union(*(intersection(shell, Box((0.035, 1.0, 1.0), material=white).translate(x, 0, 0))
                    for x in (0.25, -0.12)))
    mouth = Sphere(0.05, material=orange).translate(0.57, cy - 0.04, 0.0)
    eyes = Mirror(union(Sphere(0.06, material=white).translate(0.36, cy + 0.06, 0.1),
                        Sphere(0.032, material=pupil).translate(0.39, cy + 0.07, 0.14)), "z")
    fish = subtract(union(fish, bands, eyes), mouth, k=0.02)
    return union(base, fish, k=0.05)


@register_scene("sdf-fish", params={"mc_resolution": MC_PARAM})
def build_fish(*, variant: str = "diffuse", mc_resolution: int = MC_RESOLUTION) -> Scene:
    """SDF clownfish sculpture on a stand on the ground (stands in for the thesis's FISH).

    Parameters
    ----------
    variant : {"diffuse", "glossy"}
        Glossy: glazed ceramic fish (ks 0.35, s 128), bronze stand (ks 0.4, s 64).
    mc_resolution : int
    """
    check_variant(variant)
    materials = [
        _ground_material(variant),
        material(variant, "stand", (0.25, 0.16, 0.08), ks=0.4, shininess=64.0),
        material(variant, "orange", (0.85, 0.32, 0.04), ks=0.35, shininess=128.0),
        material(variant, "white", (0.9, 0.9, 0.88), ks=0.35, shininess=128.0),
        material(variant, "fins", (0.7, 0.22, 0.03), ks=0.35, shininess=128.0),
        material(variant, "pupils", (0.03, 0.03, 0.03), ks=0.5, shininess=512.0),
    ]
    return sdf_scene("sdf-fish", fish_shape(), materials, variant=variant, height=1.2,
                     mc_resolution=mc_resolution, params={}, center_y=0.55,
                     orbit_radius=2.6, orbit_height=1.0,
                     substitution="FISH (an SDF from Takikawa et al.'s dataset) replaced by our "
                                  "own SDF clownfish sculpture")


# --- sdf-rabbit ----------------------------------------------------------------------------------

def rabbit_shape() -> SdfNode:
    """A sitting rabbit facing +z, ~1.55 high; ids 1 fur, 2 pink, 3 eyes, 4 tail."""
    fur, pink, eye, tail = 1, 2, 3, 4
    body = Ellipsoid((0.36, 0.42, 0.48), material=fur).translate(0.0, 0.42, -0.05)
    haunches = Mirror(Ellipsoid((0.14, 0.22, 0.3), material=fur).translate(0.24, 0.22, -0.08),
                      "x")
    paws = Mirror(Ellipsoid((0.07, 0.06, 0.14), material=fur).translate(0.13, 0.05, 0.36), "x")
    head = Sphere(0.25, material=fur).translate(0.0, 0.9, 0.22)
    muzzle = Mirror(Sphere(0.1, material=fur).translate(0.065, 0.82, 0.4), "x")
    ear = Ellipsoid((0.075, 0.28, 0.04), material=fur)
    inner = Ellipsoid((0.045, 0.21, 0.02), material=pink).translate(0.0, 0.01, 0.03)
    ears = Mirror(union(ear, inner).rotate((1.0, 0.0, 0.0), -12.0).rotate((0.0, 0.0, 1.0), -14.0)
                  .translate(0.12, 1.32, 0.14), "x")
    figure = union(body, haunches, paws, head, muzzle, k=0.08)
    figure = union(figure, ears, k=0.06)
    figure = union(figure, Sphere(0.1, material=tail).translate(0.0, 0.3, -0.55), k=0.04)
    nose = Sphere(0.035, material=pink).translate(0.0, 0.87, 0.49)
    eyes = Mirror(Sphere(0.045, material=eye).translate(0.14, 0.96, 0.4), "x")
    return union(figure, nose, eyes)


@register_scene("sdf-rabbit", params={"mc_resolution": MC_PARAM})
def build_rabbit(*, variant: str = "diffuse", mc_resolution: int = MC_RESOLUTION) -> Scene:
    """SDF sitting rabbit on the ground (stands in for the thesis's RABBIT).

    Parameters
    ----------
    variant : {"diffuse", "glossy"}
        Glossy: porcelain-like glaze on the fur (ks 0.3, s 64), glossy eyes.
    mc_resolution : int
    """
    check_variant(variant)
    materials = [
        _ground_material(variant),
        material(variant, "fur", (0.72, 0.58, 0.42), ks=0.3, shininess=64.0),
        material(variant, "pink", (0.88, 0.5, 0.55), ks=0.3, shininess=64.0),
        material(variant, "eyes", (0.02, 0.02, 0.02), ks=0.5, shininess=512.0),
        material(variant, "tail", (0.92, 0.92, 0.9), ks=0.3, shininess=64.0),
    ]
    return sdf_scene("sdf-rabbit", rabbit_shape(), materials, variant=variant, height=1.7,
                     mc_resolution=mc_resolution, params={}, center_y=0.7,
                     substitution="RABBIT (Fizzler, Shadertoy) replaced by our own SDF sitting "
                                  "rabbit")


# --- sdf-bunny-neural ----------------------------------------------------------------------------

#: Height of the bunny (the neural SDF is fitted to the CGAL bunny scaled to it).
BUNNY_HEIGHT = 1.2


@register_scene("sdf-bunny-neural", params={"size": P.choice("small", "large"),
                                               "mc_resolution": MC_PARAM,
                                               "seed": P.seed(high=2**31 - 1)})
def build_bunny_neural(*, variant: str = "diffuse", size: str = "small",
                       mc_resolution: int = MC_RESOLUTION, seed: int = 0) -> Scene:
    """The Stanford bunny as a neural SDF on the ground (thesis STANFORD-BUNNY, table 4.3).

    The CGAL bunny (Debian ``libcgal-demo``, needs ``prtbench assets fetch cgal-meshes``) is
    fitted by a small sine MLP (:func:`prtbench.transport.neural_sdf_fit.fit_neural_sdf`: ~0.5–1 min on two
    CPU cores the first time, then cached); the scene's SDF is that network united with the
    ground plane, and its objects the marching-cubes mesh of the network.

    Parameters
    ----------
    variant : {"diffuse", "glossy"}
        Glossy: porcelain (ks 0.35, s 128).
    size : {"small", "large"}
        Network size of table 4.3: small k = 32, l = 2; large k = 64, l = 2.
    mc_resolution : int
    seed : int
        Seed of the network's initialisation and training batches.
    """

    check_variant(variant)
    if size not in SIZES:
        raise InvalidInputError(f"neural SDF size '{size}'; accepted: {', '.join(SIZES)}")
    seed = _as_int(seed, "seed", 0, 2**31 - 1)
    mesh = asset_mesh("cgal-meshes", "bunny00.off", height=BUNNY_HEIGHT,
                      rotate_y_degrees=90.0)  # the file's bunny faces −x; turn it to face +z
    network = fit_neural_sdf(mesh, size=size, seed=seed, material=1, progress=True)
    materials = [
        _ground_material(variant),
        material(variant, "bunny", (0.75, 0.72, 0.66), ks=0.35, shininess=128.0),
    ]
    k, layers = SIZES[size]
    return sdf_scene("sdf-bunny-neural", network, materials, variant=variant,
                     height=BUNNY_HEIGHT + 0.1, mc_resolution=mc_resolution,
                     params={"size": size, "seed": seed}, center_y=0.5,
                     substitution=f"STANFORD-BUNNY neural SDF of Davies et al. 2021 replaced by "
                                  f"our {size} sine MLP (k={k}, l={layers}) fitted to the CGAL "
                                  "bunny")
