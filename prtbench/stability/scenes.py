"""A stability case's scene: the base scene with the case's material, transform and geometry.

The transformed scene keeps the base scene's name and records the case in ``params`` (which
the runner stores with every row and which enters no cache key: the content hash covers the
geometry and materials themselves). A scale or translation case moves the base scene in the
user's world, in float64, and puts it back in a canonical frame as any imported scene
(:mod:`prtbench.scene.frame`): the base scene's own, since it is the same shape. So its image
must match the moderate case's; only what is physically undefined (non-finite coordinates,
zero extent: :func:`prtbench.scene.params.check_extent`) is refused.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from prtbench.api.errors import InvalidInputError
from prtbench.scene.frame import bounds_of, fit_bounds, with_frame
from prtbench.scene.model import Material, Scene, SceneObject, Trajectory, TriangleMesh, View
from prtbench.scene.params import check_extent
from prtbench.stability.lights import LIGHTS
from prtbench.transport.sdf.nodes import SdfNode, glsl_float

#: Height of the grazing camera above the ground, as a fraction of the scene's diagonal.
GRAZING_HEIGHT = 1e-3
#: The direction of the translation case.
TRANSLATE_AXIS = np.ones(3) / math.sqrt(3.0)


def _material(material: Material, shininess: float | None) -> Material:
    if shininess is None or not material.is_glossy:
        return material
    return dataclasses.replace(material, shininess=shininess)  # validated: [0, 1e4]


def _moved(base: Scene, scale: float, translate: np.ndarray, shown: dict) -> Scene:
    """``base`` scaled about the world origin by ``scale`` and moved by ``translate``, then put
    back in the base's canonical frame.

    The moved world is computed in float64 from the canonical float32 positions (as a file's
    float64 vertices are read), and the frame is fitted to its float64 bounds before the cast:
    a float32 cast of the world itself would lose the geometry 10⁷ from the origin.
    """

    def world(points) -> np.ndarray:
        with np.errstate(over="ignore", invalid="ignore"):
            return scale * base.world_from_canonical.apply(points) + translate

    positions = [world(o.mesh.positions) for o in base.objects]
    lo, hi = bounds_of(positions)
    check_extent(base.name, lo, hi, shown)
    canonical = fit_bounds(lo, hi, *base.bounds())
    objects = [SceneObject(o.name, TriangleMesh(canonical.apply(p), o.mesh.faces, o.mesh.normals,
                                                o.mesh.uvs), o.material)
               for o, p in zip(base.objects, positions)]
    views = []
    for view in base.trajectory.views:
        eye, target = canonical.apply(world(np.asarray([view.eye, view.target])))
        views.append(dataclasses.replace(view, eye=tuple(map(float, eye)),
                                         target=tuple(map(float, target))))
    # An SDF keeps its tree: the frame is the base's, so its canonical surface is the base's
    # own (the canonical mesh above equals the base's up to float64 rounding).
    return dataclasses.replace(base, objects=objects, trajectory=Trajectory(tuple(views)),
                               world_from_canonical=canonical.inverse())


class DistanceScale(SdfNode):
    """``child``'s distance multiplied by ``factor`` < 1: d(p) = f·child(p).

    The zero set (the surface) and the sign are unchanged and the field stays 1-Lipschitz, so
    sphere tracing stays safe, but |∇d| = f: every step is f times the exact one.
    """

    def __init__(self, child: SdfNode, factor: float):
        if not 0.0 < float(factor) <= 1.0:
            raise InvalidInputError(f"distance factor {factor!r}; accepted: 0 < factor <= 1")
        self.child, self.factor = child, float(factor)

    @property
    def children(self):
        return (self.child,)

    def _eval(self, p, need_material):
        d, m = self.child._eval(p, need_material)
        return d * self.factor, m

    def _emit(self, cg, p):
        d, m = self.child._emit(cg, p)
        return cg.let("float", "d", f"{d} * {glsl_float(self.factor)}"), m

    def _spec(self):
        return {"factor": self.factor}


def _solid_block(scene: Scene) -> SceneObject:
    """A closed box standing on the ground under the scene's centre: half the ground's width
    and depth, a third of the scene's height (outward faces, flat normals)."""
    import trimesh

    lo, hi = (np.asarray(b, dtype=np.float64) for b in scene.bounds())
    names = [o.name for o in scene.objects]
    floor = (float(scene.objects[names.index("ground")].mesh.positions[:, 1].max())
             if "ground" in names else float(lo[1]))
    extent = np.array([0.5 * (hi[0] - lo[0]), (hi[1] - floor) / 3.0, 0.5 * (hi[2] - lo[2])])
    centre = np.array([0.5 * (lo[0] + hi[0]), floor + 0.5 * extent[1], 0.5 * (lo[2] + hi[2])])
    box = trimesh.creation.box(extents=extent)
    box.apply_translation(centre)
    box.unmerge_vertices()  # one vertex per face corner: flat normals at the box's edges
    material = next((o.material for o in scene.objects if o.name == "ground"),
                    scene.objects[0].material)
    return SceneObject("solid-block", TriangleMesh(box.vertices, box.faces), material)


def _ground_index(scene: Scene) -> int:
    names = [o.name for o in scene.objects]
    if "ground" not in names:
        raise InvalidInputError(f"scene '{scene.name}' has no object named 'ground'; the "
                                "geometry cases need one")
    return names.index("ground")


def _degenerate(mesh: TriangleMesh) -> TriangleMesh:
    """``mesh`` plus a zero-area copy of every face and one sliver per face (1e-6 tall)."""
    faces = mesh.faces
    zero = np.stack([faces[:, 0], faces[:, 1], faces[:, 0]], axis=1)  # two equal corners
    p = mesh.positions.astype(np.float64)
    mid = 0.5 * (p[faces[:, 0]] + p[faces[:, 1]])
    mid[:, 1] += 1e-6 * float(np.linalg.norm(p.max(0) - p.min(0)))
    base = len(p)
    sliver = np.stack([faces[:, 0], faces[:, 1], base + np.arange(len(faces))], axis=1)
    positions = np.concatenate([p, mid])
    normals = np.concatenate([mesh.normals, mesh.normals[faces[:, 0]]])
    uvs = None if mesh.uvs is None else np.concatenate([mesh.uvs, mesh.uvs[faces[:, 0]]])
    return TriangleMesh(positions, np.concatenate([faces, zero, sliver]), normals, uvs)


def _t_junction(mesh: TriangleMesh) -> TriangleMesh:
    """``mesh`` with its first triangle split at the midpoint of its edge (0, 2) only.

    The neighbour across that edge keeps the whole edge, so the new vertex is a T-junction:
    per-vertex data interpolates differently on the two sides.
    """
    f = mesh.faces
    a, b, c = (int(i) for i in f[0])
    p = mesh.positions.astype(np.float64)
    m = len(p)
    positions = np.concatenate([p, 0.5 * (p[[a]] + p[[c]])])
    normals = np.concatenate([mesh.normals, mesh.normals[[a]]])
    uvs = None if mesh.uvs is None else np.concatenate([mesh.uvs, 0.5 * (mesh.uvs[[a]] + mesh.uvs[[c]])])
    faces = np.concatenate([[[a, b, m], [m, b, c]], f[1:]])
    return TriangleMesh(positions, faces, normals, uvs)


def _single_triangle(mesh: TriangleMesh) -> TriangleMesh:
    """One triangle covering ``mesh``'s horizontal extent (a ground as a single triangle)."""
    p = mesh.positions.astype(np.float64)
    lo, hi = p.min(0), p.max(0)
    y = float(hi[1])
    w = hi - lo
    # Counter-clockwise seen from +Y, and containing the whole [lo, hi] rectangle.
    positions = np.array([[lo[0] - w[0], y, hi[2] + w[2]], [hi[0] + 2 * w[0], y, hi[2] + w[2]],
                          [lo[0] - w[0], y, lo[2] - 2 * w[2]]])
    normals = np.tile(mesh.normals[:1], (3, 1))
    return TriangleMesh(positions, [[0, 1, 2]], normals)


def _edge_on(scene: Scene) -> Trajectory:
    """A camera exactly in the ground's plane, looking at the scene's centre above it."""
    lo, hi = scene.bounds()
    ground_y = float(scene.objects[_ground_index(scene)].mesh.positions[:, 1].max())
    centre = 0.5 * (lo + hi)
    view = scene.trajectory.views[0]
    eye = np.asarray(view.eye, dtype=np.float64)
    eye[1] = ground_y
    return Trajectory((View(eye=tuple(float(c) for c in eye),
                            target=(float(centre[0]), float(centre[1]), float(centre[2])),
                            fov_y=view.fov_y),))


def _grazing(scene: Scene) -> Trajectory:
    lo, hi = scene.bounds()
    ground = scene.objects[_ground_index(scene)].mesh.positions
    height = float(ground[:, 1].max()) + GRAZING_HEIGHT * scene.diagonal()
    centre = 0.5 * (lo + hi)
    eye = (float(lo[0]), height, float(centre[2]))
    target = (float(hi[0]), height, float(centre[2]))
    return Trajectory((View(eye=eye, target=target, fov_y=45.0),))


def case_scene(base: Scene, case) -> Scene:
    """The scene ``case`` is measured on (``base`` is not changed).

    Raises
    ------
    InvalidInputError
        A Phong exponent outside the material's range, or a scale or translation that leaves
        non-finite coordinates or zero extent (:func:`prtbench.scene.params.check_extent`).
    """

    scale = float(case.scale)
    world_from_canonical = base.world_from_canonical
    if scale != 1.0 or case.translate:
        shown = {k: v for k, v in base.params.items()
                 if k not in ("stability_case", "world_from_canonical")}
        base = _moved(base, scale, TRANSLATE_AXIS * float(case.translate),
                      {**shown, "scale": scale, "translate": case.translate})
        world_from_canonical = base.world_from_canonical
    objects = [SceneObject(o.name, o.mesh, _material(o.material, case.shininess))
               for o in base.objects]
    sdf = base.sdf
    if sdf is not None and case.distance_factor != 1.0:
        sdf = dataclasses.replace(sdf, root=DistanceScale(sdf.root, case.distance_factor))
    elif case.distance_factor != 1.0:
        raise InvalidInputError(f"stability case '{case.name}' scales a distance field; scene "
                                f"'{base.name}' has none (accepted: SDF scenes)")
    if sdf is not None and case.shininess is not None:
        sdf = dataclasses.replace(sdf, materials=tuple(_material(m, case.shininess)
                                                       for m in sdf.materials))
    trajectory = base.trajectory
    if case.geometry in ("flipped-normals", "solid-block"):
        names = [o.name for o in objects]
        g = names.index("ground") if "ground" in names else -1  # a file may have no ground
        if case.geometry == "solid-block":
            objects.append(_solid_block(dataclasses.replace(base, objects=objects)))
        else:
            objects = [o if i == g else SceneObject(
                o.name, TriangleMesh(o.mesh.positions, o.mesh.faces, -o.mesh.normals, o.mesh.uvs),
                o.material) for i, o in enumerate(objects)]
    elif case.geometry:
        g = _ground_index(base)
        ground = objects[g]
        if case.geometry == "degenerate":
            objects[g] = SceneObject(ground.name, _degenerate(ground.mesh), ground.material)
        elif case.geometry == "coincident":
            objects.append(SceneObject("ground-copy", ground.mesh, ground.material))
        elif case.geometry == "t-junction":
            objects[g] = SceneObject(ground.name, _t_junction(ground.mesh), ground.material)
        elif case.geometry == "edge-on":
            objects[g] = SceneObject(ground.name, _single_triangle(ground.mesh), ground.material)
        elif case.geometry != "grazing":
            raise InvalidInputError(f"stability geometry '{case.geometry}'; accepted: grazing, "
                                    "edge-on, flipped-normals, degenerate, t-junction, "
                                    "coincident, solid-block")
    exposure = base.exposure * (LIGHTS[case.light].exposure_factor if case.light else 1.0)
    params = with_frame({**base.params, "stability_case": case.name}, world_from_canonical)
    scene = dataclasses.replace(base, objects=objects, sdf=sdf, trajectory=trajectory,
                                exposure=exposure, params=params)
    if case.geometry in ("grazing", "edge-on"):
        views = _grazing(scene) if case.geometry == "grazing" else _edge_on(scene)
        scene = dataclasses.replace(scene, trajectory=views)
    return scene
