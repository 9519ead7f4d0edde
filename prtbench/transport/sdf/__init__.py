"""Continuous (SDF) surfaces: expression trees, sphere tracing, meshes, GL programs.

An SDF scene is a normal :class:`prtbench.scene.model.Scene` whose ``objects`` hold a fine
marching-cubes mesh of its SDF (one object per material id, used by the Mitsuba reference, by
masks and by mesh-based methods) and whose ``sdf`` is an :class:`SdfSurface` (the tree, its
bounds and its materials), which continuous methods sphere-trace in NumPy or GLSL.

Modules: :mod:`.nodes` (the tree, NumPy evaluation, GLSL generation), :mod:`.surface`
(:class:`SdfSurface`), :mod:`.trace` (NumPy sphere tracing, SDF transfer), :mod:`.mesh`
(marching cubes, surface samples), :mod:`prtbench.render.sdf_gl` holds their GL programs, G-buffer and GPU occlusion.
"""

from prtbench.transport.sdf.mesh import (
    marching_cubes_mesh,
    sample_sdf_surface,
    sdf_grid,
    sdf_scene_objects,
    split_by_material,
)
from prtbench.transport.sdf.nodes import (
    Box,
    Capsule,
    Cone,
    Cylinder,
    Ellipsoid,
    Mirror,
    Plane,
    Rotate,
    Round,
    RoundedBox,
    Scale,
    SdfNode,
    SmoothIntersection,
    SmoothSubtraction,
    SmoothUnion,
    Sphere,
    Torus,
    Translate,
    intersection,
    rotation_matrix,
    subtract,
    union,
)
from prtbench.transport.sdf.surface import SdfSurface, as_surface
from prtbench.transport.sdf.trace import (
    CLEARANCE,
    MarchResult,
    SdfHits,
    SdfTracer,
    compute_sdf_transfer,
    first_hit,
    march,
    occluded,
    surface_origins,
)

__all__ = [
    "Box", "Capsule", "Cone", "Cylinder", "Ellipsoid", "Mirror", "Plane", "Rotate", "Round",
    "RoundedBox", "Scale", "SdfNode", "SmoothIntersection", "SmoothSubtraction", "SmoothUnion",
    "Sphere", "Torus", "Translate", "intersection", "rotation_matrix", "subtract", "union",
    "SdfSurface", "as_surface", "MarchResult", "SdfHits", "SdfTracer", "compute_sdf_transfer",
    "first_hit", "march", "occluded", "surface_origins", "CLEARANCE", "marching_cubes_mesh", "sample_sdf_surface", "sdf_grid",
    "sdf_scene_objects", "split_by_material"]
