"""An SDF scene surface: the SDF tree, the box it lives in, and the materials of its ids."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from prtbench.api.errors import InvalidInputError
from prtbench.scene.model import Material
from prtbench.transport.sdf.nodes import SdfNode, glsl_float, glsl_vec3

#: Hit threshold of sphere tracing, as a fraction of the bounds diagonal. A quarter of the ray
#: origin offset of prtbench.transport.raytrace (1e-4·diagonal), so a ray leaving a surface point is not
#: taken to hit the surface it starts on.
HIT_EPS_SCALE = 2.5e-5

#: Central-difference step of normals in NumPy (float64), fraction of the diagonal.
NORMAL_STEP_SCALE = 1e-5

#: Tetrahedral-stencil step of the Newton projection, fraction of the diagonal. The stencil's
#: gradient is only first-order accurate (its third moment is not zero): error ≈ h·curvature,
#: so the step is small; float64 rounding of d then costs ~1e-15/h ≈ 1e-8 relative.
PROJECTION_STEP_SCALE = 1e-7

#: Normal step in GLSL (float32 needs a larger step: rounding of d is ~1e-7 of the coordinates).
GLSL_NORMAL_STEP_SCALE = 2e-4

#: Sphere-tracing iterations before a ray is given up (counted as a miss).
MAX_STEPS = 512

#: Over-relaxation factor ω of sphere tracing (Keinert et al. 2014): steps are ω·d, undone to
#: the safe step d when the two unbounding spheres do not overlap or the ray lands inside.
RELAXATION = 1.4


#: Tetrahedral stencil (sums to 0; Σ k kᵀ = 4 I).
_TETRAHEDRON = np.array([[1.0, -1.0, -1.0], [-1.0, -1.0, 1.0], [-1.0, 1.0, -1.0], [1.0, 1.0, 1.0]])


@dataclass(frozen=True, eq=False)
class SdfSurface:
    """The continuous surface of an SDF scene (``Scene.sdf``).

    Attributes
    ----------
    root : SdfNode
        The signed distance tree (negative inside).
    bounds : ((3,), (3,)) tuple of float
        Axis-aligned box (lo, hi) holding the surface: rays are traced inside it only and the
        marching-cubes mesh spans exactly it (an unbounded ground plane ends at its sides).
    materials : tuple of Material
        ``materials[k]`` is the material of id k; every id the tree uses must have one.
    name : str
    """

    root: SdfNode
    bounds: tuple[tuple[float, float, float], tuple[float, float, float]]
    materials: tuple[Material, ...]
    name: str = "sdf"

    def __post_init__(self) -> None:
        if not isinstance(self.root, SdfNode):
            raise InvalidInputError(f"SDF root of type {type(self.root).__name__}; "
                                    "accepted: SdfNode")
        lo, hi = (np.asarray(b, dtype=np.float64).reshape(-1) for b in self.bounds)
        if lo.shape != (3,) or hi.shape != (3,) or not np.all(hi > lo) \
                or not np.all(np.isfinite(lo)) or not np.all(np.isfinite(hi)):
            raise InvalidInputError(f"SDF bounds {self.bounds!r}; accepted: (lo, hi) with lo < hi")
        object.__setattr__(self, "bounds", (tuple(float(c) for c in lo),
                                            tuple(float(c) for c in hi)))
        materials = tuple(self.materials)
        for m in materials:
            if not isinstance(m, Material):
                raise InvalidInputError(f"SDF material of type {type(m).__name__}; "
                                        "accepted: prtbench.scene.model.Material")
        missing = sorted(i for i in self.root.material_ids() if i >= len(materials))
        if missing:
            raise InvalidInputError(f"SDF material ids {missing} have no material; accepted: "
                                    f"ids 0..{len(materials) - 1}")
        object.__setattr__(self, "materials", materials)

    # --- geometry ------------------------------------------------------------------------------

    @property
    def lo(self) -> np.ndarray:
        return np.asarray(self.bounds[0])

    @property
    def hi(self) -> np.ndarray:
        return np.asarray(self.bounds[1])

    @property
    def diagonal(self) -> float:
        """Length of the bounds diagonal (scale of every tolerance)."""
        return float(np.linalg.norm(self.hi - self.lo))

    @property
    def hit_eps(self) -> float:
        return HIT_EPS_SCALE * self.diagonal

    def evaluate(self, points: np.ndarray) -> np.ndarray:
        """Signed distance (N,) float64 at ``points`` (N, 3)."""
        return self.root.evaluate(points)

    def evaluate_with_material(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Signed distance (N,) float64 and material id (N,) int32 at ``points`` (N, 3)."""
        return self.root.evaluate_with_material(points)

    def material_at(self, points: np.ndarray) -> np.ndarray:
        """Material id (N,) int32 at ``points`` (N, 3)."""
        return self.root.material_at(points)

    def gradient(self, points: np.ndarray, *, step: float | None = None) -> np.ndarray:
        """Central-difference gradient (N, 3) float64."""
        return self.root.gradient(points, step=step or NORMAL_STEP_SCALE * self.diagonal)

    def normal(self, points: np.ndarray, *, step: float | None = None) -> np.ndarray:
        """Unit outward normals (N, 3) float64 from the SDF gradient."""
        return self.root.normal(points, step=step or NORMAL_STEP_SCALE * self.diagonal)

    def project(self, points: np.ndarray, *, iterations: int = 3, step: float | None = None,
                with_normals: bool = False) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
        """Newton steps p ← p − d·∇d/|∇d|² onto the zero level set.

        Each step evaluates the SDF at the 4 corners of a tetrahedron of size ``step`` around p:
        their mean is d(p) + O(h²) and their weighted sum the gradient + O(h).

        Returns
        -------
        ndarray, shape (N, 3), float64
            Projected points; with ``with_normals`` also the unit gradients (N, 3) of the last
            step (taken ≲ 1e-6·diagonal away from the returned points).
        """
        h = step or PROJECTION_STEP_SCALE * self.diagonal
        p = np.array(points, dtype=np.float64, copy=True).reshape(-1, 3)
        g = np.tile([0.0, 1.0, 0.0], (len(p), 1))
        for _ in range(int(iterations)):
            values = self.evaluate((p[:, None, :] + h * _TETRAHEDRON[None]).reshape(-1, 3))
            values = values.reshape(-1, 4)
            d = values.mean(axis=1)
            g = values @ _TETRAHEDRON / (4.0 * h)
            g2 = np.maximum(np.einsum("ij,ij->i", g, g), 1e-12)
            p -= (d / g2)[:, None] * g
        if not with_normals:
            return p
        length = np.linalg.norm(g, axis=1, keepdims=True)
        normals = np.where(length > 1e-12, g / np.maximum(length, 1e-300), [0.0, 1.0, 0.0])
        return p, normals

    # --- GLSL ----------------------------------------------------------------------------------

    def glsl(self) -> str:
        """The tree's GLSL (:meth:`SdfNode.glsl`) plus the tracing constants of this surface.

        Defines ``SDF_BOUNDS_LO``, ``SDF_BOUNDS_HI`` (vec3), ``SDF_HIT_EPS`` and
        ``SDF_NORMAL_STEP`` (float) used by ``sdf_trace.glsl``.
        """
        header = "\n".join([
            f"#define SDF_BOUNDS_LO {glsl_vec3(self.bounds[0])}",
            f"#define SDF_BOUNDS_HI {glsl_vec3(self.bounds[1])}",
            f"#define SDF_HIT_EPS {glsl_float(self.hit_eps)}",
            f"#define SDF_NORMAL_STEP {glsl_float(GLSL_NORMAL_STEP_SCALE * self.diagonal)}",
        ])
        return header + "\n" + self.root.glsl()

    def glsl_sources(self) -> dict[str, str]:
        """``{"scene_sdf.glsl": source}``, the virtual include for ``prtbench.render.gl.load_program``."""
        return {"scene_sdf.glsl": self.glsl()}

    def spec(self) -> dict[str, Any]:
        """JSON-able description: tree, bounds, materials (part of ``Scene.content_hash``)."""
        return {"name": self.name, "root": self.root.spec(),
                "bounds": [list(self.bounds[0]), list(self.bounds[1])],
                "materials": [m.spec() for m in self.materials]}


def as_surface(scene_or_sdf: Any) -> SdfSurface:
    """The :class:`SdfSurface` of a Scene with ``sdf``, or the surface itself."""
    if isinstance(scene_or_sdf, SdfSurface):
        return scene_or_sdf
    sdf = getattr(scene_or_sdf, "sdf", None)
    if isinstance(sdf, SdfSurface):
        return sdf
    name = getattr(scene_or_sdf, "name", type(scene_or_sdf).__name__)
    raise InvalidInputError(f"'{name}' is not an SDF scene; accepted: a Scene whose sdf is an "
                            "SdfSurface (scenes sdf-car, sdf-monster, ...) or an SdfSurface")
