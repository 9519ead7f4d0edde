"""SDF expression trees, defined once and evaluated both in NumPy (float64) and in GLSL.

A tree is built from primitives (centred at the origin; round ones have their axis along +Y),
rigid transforms with uniform scale, and hard or smooth (polynomial ``smin``) Boolean
combinations. Every node answers

* :meth:`SdfNode.evaluate` — signed distance of (N, 3) points, negative inside, float64;
* :meth:`SdfNode.material_at` — the integer material id of the primitive a point is nearest to;
* :meth:`SdfNode.glsl` — GLSL source of ``float scene_sdf(vec3 p)``, ``int scene_material(vec3
  p)`` and ``float scene_sdf_material(vec3 p, out int material)``, generated from the tree at
  run time (it calls the primitives of ``prtbench/render/shaders/sdf_primitives.glsl``, which mirror
  the NumPy formulas below line by line);
* :meth:`SdfNode.spec` — a JSON-able description (cache keys, reports).

Sphere tracing needs every node to be 1-Lipschitz (|d(x) − d(y)| ≤ |x − y|), so that |d| never
exceeds the distance to the surface. Primitives are exact distances except the ellipsoid, which
is the bound (|p/r| − 1)·min(r); rotations, translations and uniform scales keep exactness;
``min``/``max`` and the polynomial smooth min (a convex combination of its arguments'
gradients) keep the Lipschitz bound. Smooth unions stay within k/4 below the hard union.

Material ids: every primitive carries one (default 0). A union takes the id of its nearer
operand, an intersection that of its farther one, a subtraction always keeps its first
operand's id (the carved surface is painted like the solid it is carved from).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from prtbench.api.errors import InvalidInputError

#: Points per NumPy evaluation block (bounds temporaries to a few tens of MB).
EVAL_CHUNK = 1 << 17

#: Default central-difference step of :meth:`SdfNode.normal` for bare nodes (scene units).
NORMAL_STEP = 1e-5


# --- small helpers ------------------------------------------------------------------------------

def _vec3(value: Any, name: str) -> np.ndarray:
    v = np.asarray(value, dtype=np.float64).reshape(-1)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise InvalidInputError(f"{name}={value!r}; accepted: 3 finite numbers")
    return v


def _positive(value: Any, name: str, *, allow_zero: bool = False) -> float:
    v = float(value)
    if not math.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        raise InvalidInputError(f"{name}={value!r}; accepted: {'>= 0' if allow_zero else '> 0'}")
    return v


def _norm(p: np.ndarray) -> np.ndarray:
    return np.sqrt(np.einsum("ij,ij->i", p, p))


#: Points as three contiguous coordinate arrays (x, y, z): NumPy is ~10× faster on them than
#: on the columns of an (N, 3) array (axis reductions and small matmuls are slow).
Points = tuple[np.ndarray, np.ndarray, np.ndarray]


def _length(x: np.ndarray, y: np.ndarray, z: np.ndarray | None = None) -> np.ndarray:
    return np.sqrt(x * x + y * y if z is None else x * x + y * y + z * z)


def glsl_float(x: float) -> str:
    """A GLSL float literal of ``x`` with 9 significant digits (float32 round-trips)."""
    text = format(float(x), ".9g")
    if "e" in text or "E" in text:
        mantissa, exponent = text.lower().split("e")
        if "." not in mantissa:
            mantissa += ".0"
        return f"{mantissa}e{int(exponent)}"
    return text if "." in text or "n" in text else text + ".0"


def glsl_vec3(v: Sequence[float]) -> str:
    return "vec3(" + ", ".join(glsl_float(c) for c in v) + ")"


class Codegen:
    """Collects the GLSL statements (SSA style) and top-level functions of a tree."""

    def __init__(self) -> None:
        self.lines: list[str] = []
        self.functions: dict[str, str] = {}
        self._count = 0

    def name(self, prefix: str) -> str:
        self._count += 1
        return f"{prefix}{self._count}"

    def let(self, glsl_type: str, prefix: str, expression: str) -> str:
        var = self.name(prefix)
        self.lines.append(f"    {glsl_type} {var} = {expression};")
        return var

    def function(self, key: str, source: str) -> None:
        """Add a top-level declaration once (e.g. a neural network's evaluation function)."""
        self.functions.setdefault(key, source)


# --- the node base ------------------------------------------------------------------------------

class SdfNode:
    """A signed distance function R³ → R (negative inside), composable and GLSL-emittable."""

    #: Child nodes (empty for primitives).
    children: tuple["SdfNode", ...] = ()

    # Subclasses implement these three.
    def _eval(self, p: Points, need_material: bool) -> tuple[np.ndarray, np.ndarray | None]:
        """(distance (N,), material (N,) int32 or None) at points ``p`` = (x, y, z), float64."""
        raise NotImplementedError

    def _emit(self, cg: Codegen, p: str) -> tuple[str, str]:
        """Emit statements for the point variable ``p``; return (distance var, material var)."""
        raise NotImplementedError

    def _spec(self) -> dict[str, Any]:
        raise NotImplementedError

    # --- public API ----------------------------------------------------------------------------

    def evaluate(self, points: np.ndarray) -> np.ndarray:
        """Signed distance at ``points``.

        Parameters
        ----------
        points : ndarray, shape (N, 3)

        Returns
        -------
        ndarray, shape (N,), float64
            Negative inside, zero on the surface.
        """
        p = _points(points)
        out = np.empty(len(p))
        for s in range(0, len(p), EVAL_CHUNK):
            out[s:s + EVAL_CHUNK] = self._eval(_soa(p[s:s + EVAL_CHUNK]), False)[0]
        return out

    def evaluate_with_material(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Signed distance (N,) float64 and material id (N,) int32 at ``points`` (N, 3)."""
        p = _points(points)
        d, m = np.empty(len(p)), np.empty(len(p), dtype=np.int32)
        for s in range(0, len(p), EVAL_CHUNK):
            d[s:s + EVAL_CHUNK], m[s:s + EVAL_CHUNK] = self._eval(_soa(p[s:s + EVAL_CHUNK]),
                                                                  True)
        return d, m

    def material_at(self, points: np.ndarray) -> np.ndarray:
        """Material id (N,) int32 of the primitive each point (N, 3) belongs to."""
        return self.evaluate_with_material(points)[1]

    def gradient(self, points: np.ndarray, *, step: float = NORMAL_STEP) -> np.ndarray:
        """Central-difference gradient (N, 3) float64 with step ``step`` (scene units)."""
        p = _points(points)
        h = _positive(step, "normal step")
        offsets = np.concatenate([np.eye(3) * h, -np.eye(3) * h])
        values = self.evaluate((p[:, None, :] + offsets[None]).reshape(-1, 3)).reshape(-1, 6)
        return (values[:, :3] - values[:, 3:]) / (2.0 * h)

    def normal(self, points: np.ndarray, *, step: float = NORMAL_STEP) -> np.ndarray:
        """Unit outward normals (N, 3) float64: the normalised gradient (+Y where it vanishes)."""
        g = self.gradient(points, step=step)
        length = _norm(g)[:, None]
        return np.where(length > 1e-12, g / np.maximum(length, 1e-300), [0.0, 1.0, 0.0])

    def glsl(self) -> str:
        """GLSL source defining ``scene_sdf``, ``scene_material`` and ``scene_sdf_material``.

        It ``#include``\\ s ``sdf_primitives.glsl`` (``prtbench/render/shaders``) and is meant to be
        given to :func:`prtbench.render.gl.load_program` as the virtual file ``scene_sdf.glsl``.
        """
        cg = Codegen()
        d, m = self._emit(cg, "p")
        body = "\n".join(cg.lines)
        functions = "\n\n".join(cg.functions.values())
        return "\n".join([
            "// Generated at run time by prtbench.transport.sdf from an SDF tree; not a committed file.",
            "#ifndef PRTBENCH_SCENE_SDF_GLSL",
            "#define PRTBENCH_SCENE_SDF_GLSL",
            '#include "sdf_primitives.glsl"',
            "",
            functions,
            "",
            "float scene_sdf_material(vec3 p, out int material) {",
            body,
            f"    material = {m};",
            f"    return {d};",
            "}",
            "",
            "float scene_sdf(vec3 p) {",
            "    int material;",
            "    return scene_sdf_material(p, material);",
            "}",
            "",
            "int scene_material(vec3 p) {",
            "    int material;",
            "    scene_sdf_material(p, material);",
            "    return material;",
            "}",
            "#endif",
            "",
        ])

    def spec(self) -> dict[str, Any]:
        """JSON-able description of the whole tree (types, parameters, material ids)."""
        out = {"type": type(self).__name__, **self._spec()}
        if self.children:
            out["children"] = [c.spec() for c in self.children]
        return out

    def material_ids(self) -> set[int]:
        """All material ids used by the tree's primitives."""
        ids: set[int] = set()
        for c in self.children:
            ids |= c.material_ids()
        return ids

    # --- builder sugar -------------------------------------------------------------------------

    def translate(self, x: float, y: float, z: float) -> "Translate":
        return Translate(self, (x, y, z))

    def rotate(self, axis: Sequence[float], degrees: float) -> "Rotate":
        return Rotate.about(self, axis, degrees)

    def scale(self, factor: float) -> "Scale":
        return Scale(self, factor)


def _soa(p: np.ndarray) -> Points:
    return (np.ascontiguousarray(p[:, 0]), np.ascontiguousarray(p[:, 1]),
            np.ascontiguousarray(p[:, 2]))


def _points(points: np.ndarray) -> np.ndarray:
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        raise InvalidInputError(f"SDF points shape {p.shape}; accepted: (N, 3)")
    return p


# --- primitives ---------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class Primitive(SdfNode):
    """Base of the primitives: a material id and the shared plumbing."""

    material: int = field(default=0, kw_only=True)

    def __post_init__(self) -> None:
        if int(self.material) != self.material or self.material < 0:
            raise InvalidInputError(f"material id {self.material!r}; accepted: integers >= 0")
        object.__setattr__(self, "material", int(self.material))

    def _distance(self, p: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def _call(self) -> str:
        """GLSL call with the point variable as ``{p}``."""
        raise NotImplementedError

    def _eval(self, p, need_material):
        d = self._distance(p)
        return d, (np.full(len(p[0]), self.material, dtype=np.int32) if need_material else None)

    def _emit(self, cg, p):
        d = cg.let("float", "d", self._call().format(p=p))
        return d, str(self.material)

    def material_ids(self) -> set[int]:
        return {self.material}


@dataclass(frozen=True, eq=False)
class Sphere(Primitive):
    """Sphere of ``radius`` at the origin (exact)."""

    radius: float = 1.0

    def __post_init__(self):
        super().__post_init__()
        object.__setattr__(self, "radius", _positive(self.radius, "sphere radius"))

    def _distance(self, p):
        return _length(*p) - self.radius

    def _call(self):
        return f"sdf_sphere({{p}}, {glsl_float(self.radius)})"

    def _spec(self):
        return {"radius": self.radius, "material": self.material}


def _box_distance(p: Points, half: Sequence[float]) -> np.ndarray:
    qx, qy, qz = (np.abs(c) - h for c, h in zip(p, half))
    outside = _length(np.maximum(qx, 0.0), np.maximum(qy, 0.0), np.maximum(qz, 0.0))
    inside = np.minimum(np.maximum(qx, np.maximum(qy, qz)), 0.0)
    return outside + inside


@dataclass(frozen=True, eq=False)
class Box(Primitive):
    """Axis-aligned box with half extents ``half_size`` at the origin (exact)."""

    half_size: tuple[float, float, float] = (1.0, 1.0, 1.0)

    def __post_init__(self):
        super().__post_init__()
        h = _vec3(self.half_size, "box half_size")
        if np.any(h <= 0):
            raise InvalidInputError(f"box half_size={self.half_size!r}; accepted: 3 values > 0")
        object.__setattr__(self, "half_size", tuple(float(c) for c in h))

    def _distance(self, p):
        return _box_distance(p, self.half_size)

    def _call(self):
        return f"sdf_box({{p}}, {glsl_vec3(self.half_size)})"

    def _spec(self):
        return {"half_size": list(self.half_size), "material": self.material}


@dataclass(frozen=True, eq=False)
class RoundedBox(Primitive):
    """Box with half extents ``half_size`` whose edges are rounded by ``radius`` (exact)."""

    half_size: tuple[float, float, float] = (1.0, 1.0, 1.0)
    radius: float = 0.1

    def __post_init__(self):
        super().__post_init__()
        h = _vec3(self.half_size, "rounded box half_size")
        r = _positive(self.radius, "rounded box radius", allow_zero=True)
        if np.any(h <= r):
            raise InvalidInputError(f"rounded box half_size={self.half_size!r} radius={r}; "
                                    "accepted: every half size > radius")
        object.__setattr__(self, "half_size", tuple(float(c) for c in h))
        object.__setattr__(self, "radius", r)

    def _distance(self, p):
        return _box_distance(p, [h - self.radius for h in self.half_size]) - self.radius

    def _call(self):
        return f"sdf_round_box({{p}}, {glsl_vec3(self.half_size)}, {glsl_float(self.radius)})"

    def _spec(self):
        return {"half_size": list(self.half_size), "radius": self.radius,
                "material": self.material}


@dataclass(frozen=True, eq=False)
class Capsule(Primitive):
    """Segment ``a``–``b`` thickened by ``radius`` (exact)."""

    a: tuple[float, float, float] = (0.0, 0.0, 0.0)
    b: tuple[float, float, float] = (0.0, 1.0, 0.0)
    radius: float = 0.1

    def __post_init__(self):
        super().__post_init__()
        object.__setattr__(self, "a", tuple(float(c) for c in _vec3(self.a, "capsule a")))
        object.__setattr__(self, "b", tuple(float(c) for c in _vec3(self.b, "capsule b")))
        object.__setattr__(self, "radius", _positive(self.radius, "capsule radius"))

    def _distance(self, p):
        pa = [c - a for c, a in zip(p, self.a)]
        ba = [b - a for a, b in zip(self.a, self.b)]
        denom = sum(c * c for c in ba)
        if denom > 0:
            h = np.clip((pa[0] * ba[0] + pa[1] * ba[1] + pa[2] * ba[2]) / denom, 0.0, 1.0)
        else:
            h = np.zeros_like(pa[0])
        return _length(*(c - h * e for c, e in zip(pa, ba))) - self.radius

    def _call(self):
        return (f"sdf_capsule({{p}}, {glsl_vec3(self.a)}, {glsl_vec3(self.b)}, "
                f"{glsl_float(self.radius)})")

    def _spec(self):
        return {"a": list(self.a), "b": list(self.b), "radius": self.radius,
                "material": self.material}


@dataclass(frozen=True, eq=False)
class Torus(Primitive):
    """Ring of tube radius ``minor`` around the +Y axis at distance ``major`` (exact)."""

    major: float = 1.0
    minor: float = 0.25

    def __post_init__(self):
        super().__post_init__()
        object.__setattr__(self, "major", _positive(self.major, "torus major radius"))
        object.__setattr__(self, "minor", _positive(self.minor, "torus minor radius"))

    def _distance(self, p):
        rho = _length(p[0], p[2]) - self.major
        return _length(rho, p[1]) - self.minor

    def _call(self):
        return f"sdf_torus({{p}}, {glsl_float(self.major)}, {glsl_float(self.minor)})"

    def _spec(self):
        return {"major": self.major, "minor": self.minor, "material": self.material}


@dataclass(frozen=True, eq=False)
class Cylinder(Primitive):
    """Capped cylinder of ``radius`` along +Y, y in [−``half_height``, ``half_height``] (exact)."""

    radius: float = 0.5
    half_height: float = 0.5

    def __post_init__(self):
        super().__post_init__()
        object.__setattr__(self, "radius", _positive(self.radius, "cylinder radius"))
        object.__setattr__(self, "half_height", _positive(self.half_height, "cylinder half_height"))

    def _distance(self, p):
        dx = _length(p[0], p[2]) - self.radius
        dy = np.abs(p[1]) - self.half_height
        return np.minimum(np.maximum(dx, dy), 0.0) + _length(np.maximum(dx, 0), np.maximum(dy, 0))

    def _call(self):
        return f"sdf_cylinder({{p}}, {glsl_float(self.radius)}, {glsl_float(self.half_height)})"

    def _spec(self):
        return {"radius": self.radius, "half_height": self.half_height, "material": self.material}


@dataclass(frozen=True, eq=False)
class Cone(Primitive):
    """Capped cone along +Y: radius ``bottom_radius`` at y = −h, ``top_radius`` at y = +h (exact).

    In the (ρ, y) half plane the solid is a trapezoid; the distance is the smaller of the
    distances to its two caps and its slanted side, negative inside.
    """

    half_height: float = 0.5
    bottom_radius: float = 0.5
    top_radius: float = 0.0

    def __post_init__(self):
        super().__post_init__()
        object.__setattr__(self, "half_height", _positive(self.half_height, "cone half_height"))
        r1 = _positive(self.bottom_radius, "cone bottom_radius", allow_zero=True)
        r2 = _positive(self.top_radius, "cone top_radius", allow_zero=True)
        if r1 == 0 and r2 == 0:
            raise InvalidInputError("cone radii 0 and 0; accepted: at least one radius > 0")
        object.__setattr__(self, "bottom_radius", r1)
        object.__setattr__(self, "top_radius", r2)

    def _distance(self, p):
        h, r1, r2 = self.half_height, self.bottom_radius, self.top_radius
        rho, y = _length(p[0], p[2]), p[1]
        bottom = _length(np.maximum(rho - r1, 0.0), y + h)
        top = _length(np.maximum(rho - r2, 0.0), y - h)
        # Slanted side: the segment (r1, −h) → (r2, h).
        ex, ey = r2 - r1, 2.0 * h
        t = np.clip(((rho - r1) * ex + (y + h) * ey) / (ex * ex + ey * ey), 0.0, 1.0)
        side = _length(rho - r1 - t * ex, y + h - t * ey)
        unsigned = np.minimum(np.minimum(bottom, top), side)
        inside = (np.abs(y) <= h) & (rho <= r1 + (r2 - r1) * (y + h) / (2.0 * h))
        return np.where(inside, -unsigned, unsigned)

    def _call(self):
        return (f"sdf_cone({{p}}, {glsl_float(self.half_height)}, "
                f"{glsl_float(self.bottom_radius)}, {glsl_float(self.top_radius)})")

    def _spec(self):
        return {"half_height": self.half_height, "bottom_radius": self.bottom_radius,
                "top_radius": self.top_radius, "material": self.material}


@dataclass(frozen=True, eq=False)
class Ellipsoid(Primitive):
    """Axis-aligned ellipsoid with semi-axes ``radii``: the 1-Lipschitz bound (|p/r| − 1)·min r.

    Exact on the surface and for spheres; elsewhere it underestimates |distance| (safe for
    sphere tracing): the gradient of |p/r| has norm ≤ 1/min r.
    """

    radii: tuple[float, float, float] = (1.0, 0.5, 0.5)

    def __post_init__(self):
        super().__post_init__()
        r = _vec3(self.radii, "ellipsoid radii")
        if np.any(r <= 0):
            raise InvalidInputError(f"ellipsoid radii={self.radii!r}; accepted: 3 values > 0")
        object.__setattr__(self, "radii", tuple(float(c) for c in r))

    def _distance(self, p):
        r = self.radii
        return (_length(p[0] / r[0], p[1] / r[1], p[2] / r[2]) - 1.0) * min(r)

    def _call(self):
        return f"sdf_ellipsoid({{p}}, {glsl_vec3(self.radii)})"

    def _spec(self):
        return {"radii": list(self.radii), "material": self.material}


@dataclass(frozen=True, eq=False)
class Plane(Primitive):
    """Half space n·p ≤ ``height`` with unit outward ``normal`` (exact, unbounded).

    Scenes bound it by their tracing box (:class:`prtbench.transport.sdf.SdfSurface.bounds`).
    """

    normal: tuple[float, float, float] = (0.0, 1.0, 0.0)
    height: float = 0.0

    def __post_init__(self):
        super().__post_init__()
        n = _vec3(self.normal, "plane normal")
        length = float(np.linalg.norm(n))
        if length < 1e-12:
            raise InvalidInputError("plane normal (0, 0, 0); accepted: a non-zero vector")
        object.__setattr__(self, "normal", tuple(float(c) for c in n / length))
        object.__setattr__(self, "height", float(self.height))

    def _distance(self, p):
        n = self.normal
        return p[0] * n[0] + p[1] * n[1] + p[2] * n[2] - self.height

    def _call(self):
        return f"sdf_plane({{p}}, {glsl_vec3(self.normal)}, {glsl_float(self.height)})"

    def _spec(self):
        return {"normal": list(self.normal), "height": self.height, "material": self.material}


# --- transforms ---------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class Translate(SdfNode):
    """``child`` moved by ``offset``: d(p) = child(p − offset)."""

    child: SdfNode
    offset: tuple[float, float, float]

    def __post_init__(self):
        _check_node(self.child)
        object.__setattr__(self, "offset", tuple(float(c) for c in _vec3(self.offset, "offset")))

    @property
    def children(self):
        return (self.child,)

    def _eval(self, p, need_material):
        return self.child._eval(tuple(c - o for c, o in zip(p, self.offset)), need_material)

    def _emit(self, cg, p):
        q = cg.let("vec3", "p", f"{p} - {glsl_vec3(self.offset)}")
        return self.child._emit(cg, q)

    def _spec(self):
        return {"offset": list(self.offset)}


@dataclass(frozen=True, eq=False)
class Rotate(SdfNode):
    """``child`` rotated by the proper rotation ``rotation`` (3, 3): d(p) = child(Rᵀ p)."""

    child: SdfNode
    rotation: tuple[tuple[float, float, float], ...]

    def __post_init__(self):
        _check_node(self.child)
        r = np.asarray(self.rotation, dtype=np.float64)
        if r.shape != (3, 3) or not np.allclose(r @ r.T, np.eye(3), atol=1e-9) \
                or np.linalg.det(r) < 0:
            raise InvalidInputError("rotation matrix is not a proper rotation; accepted: an "
                                    "orthonormal (3, 3) matrix with determinant +1")
        object.__setattr__(self, "rotation", tuple(tuple(float(c) for c in row) for row in r))

    @classmethod
    def about(cls, child: SdfNode, axis: Sequence[float], degrees: float) -> "Rotate":
        """Rotation by ``degrees`` about ``axis`` (right-handed, Rodrigues)."""
        return cls(child, rotation_matrix(axis, degrees))

    @property
    def children(self):
        return (self.child,)

    def _eval(self, p, need_material):
        # q = Rᵀ p: q_k = Σ_j R[j][k] p_j.
        r = self.rotation
        q = tuple(r[0][k] * p[0] + r[1][k] * p[1] + r[2][k] * p[2] for k in range(3))
        return self.child._eval(q, need_material)

    def _emit(self, cg, p):
        # GLSL matrices are column-major: listing R row by row builds the matrix Rᵀ.
        entries = ", ".join(glsl_float(c) for row in self.rotation for c in row)
        q = cg.let("vec3", "p", f"mat3({entries}) * {p}")
        return self.child._emit(cg, q)

    def _spec(self):
        return {"rotation": [list(r) for r in self.rotation]}


def rotation_matrix(axis: Sequence[float], degrees: float) -> np.ndarray:
    """(3, 3) right-handed rotation by ``degrees`` about ``axis``."""
    a = _vec3(axis, "rotation axis")
    length = float(np.linalg.norm(a))
    if length < 1e-12:
        raise InvalidInputError("rotation axis (0, 0, 0); accepted: a non-zero vector")
    x, y, z = a / length
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    k = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
    return np.eye(3) + s * k + (1 - c) * (k @ k)


@dataclass(frozen=True, eq=False)
class Scale(SdfNode):
    """``child`` scaled uniformly by ``factor`` about the origin: d(p) = s·child(p / s) (exact)."""

    child: SdfNode
    factor: float

    def __post_init__(self):
        _check_node(self.child)
        object.__setattr__(self, "factor", _positive(self.factor, "scale factor"))

    @property
    def children(self):
        return (self.child,)

    def _eval(self, p, need_material):
        d, m = self.child._eval(tuple(c / self.factor for c in p), need_material)
        return d * self.factor, m

    def _emit(self, cg, p):
        q = cg.let("vec3", "p", f"{p} / {glsl_float(self.factor)}")
        d, m = self.child._emit(cg, q)
        return cg.let("float", "d", f"{d} * {glsl_float(self.factor)}"), m

    def _spec(self):
        return {"factor": self.factor}


_AXES = {"x": 0, "y": 1, "z": 2}


@dataclass(frozen=True, eq=False)
class Mirror(SdfNode):
    """``child`` plus its mirror image across the plane ``axis`` = 0: d(p) = child(..|p_axis|..).

    Exact when ``child`` lies on the positive side (then the nearer copy is always the one on
    the query point's side); used for pairs (eyes, ears, wheels).
    """

    child: SdfNode
    axis: str = "x"

    def __post_init__(self):
        _check_node(self.child)
        if self.axis not in _AXES:
            raise InvalidInputError(f"mirror axis '{self.axis}'; accepted: x, y, z")

    @property
    def children(self):
        return (self.child,)

    def _eval(self, p, need_material):
        q = list(p)
        q[_AXES[self.axis]] = np.abs(q[_AXES[self.axis]])
        return self.child._eval(tuple(q), need_material)

    def _emit(self, cg, p):
        parts = [f"{p}.x", f"{p}.y", f"{p}.z"]
        parts[_AXES[self.axis]] = f"abs({parts[_AXES[self.axis]]})"
        q = cg.let("vec3", "p", f"vec3({', '.join(parts)})")
        return self.child._emit(cg, q)

    def _spec(self):
        return {"axis": self.axis}


@dataclass(frozen=True, eq=False)
class Round(SdfNode):
    """``child`` inflated by ``radius``: d(p) = child(p) − r (rounds edges, keeps the bound)."""

    child: SdfNode
    radius: float

    def __post_init__(self):
        _check_node(self.child)
        object.__setattr__(self, "radius", _positive(self.radius, "round radius", allow_zero=True))

    @property
    def children(self):
        return (self.child,)

    def _eval(self, p, need_material):
        d, m = self.child._eval(p, need_material)
        return d - self.radius, m

    def _emit(self, cg, p):
        d, m = self.child._emit(cg, p)
        return cg.let("float", "d", f"{d} - {glsl_float(self.radius)}"), m

    def _spec(self):
        return {"radius": self.radius}


# --- Boolean combinations -----------------------------------------------------------------------

def _check_node(node: Any) -> None:
    if not isinstance(node, SdfNode):
        raise InvalidInputError(f"SDF operand of type {type(node).__name__}; accepted: SdfNode")


def _blend(a: np.ndarray, b: np.ndarray, k: float) -> np.ndarray:
    """The polynomial smin correction h²k/4 with h = max(k − |a − b|, 0)/k (0 where k = 0)."""
    if k <= 0:
        return np.zeros_like(a)
    h = np.maximum(k - np.abs(a - b), 0.0) / k
    return h * h * k * 0.25


@dataclass(frozen=True, eq=False)
class SmoothUnion(SdfNode):
    """min(a, b) − h²k/4 (hard union for k = 0); in [min − k/4, min]. Id of the nearer operand."""

    a: SdfNode
    b: SdfNode
    k: float = 0.0

    def __post_init__(self):
        _check_node(self.a)
        _check_node(self.b)
        object.__setattr__(self, "k", _positive(self.k, "smooth union k", allow_zero=True))

    @property
    def children(self):
        return (self.a, self.b)

    def _eval(self, p, need_material):
        da, ma = self.a._eval(p, need_material)
        db, mb = self.b._eval(p, need_material)
        d = np.minimum(da, db) - _blend(da, db, self.k)
        return d, (np.where(da <= db, ma, mb) if need_material else None)

    def _emit(self, cg, p):
        da, ma = self.a._emit(cg, p)
        db, mb = self.b._emit(cg, p)
        d = cg.let("float", "d", f"sdf_smin({da}, {db}, {glsl_float(self.k)})")
        m = cg.let("int", "m", f"{da} <= {db} ? {ma} : {mb}")
        return d, m

    def _spec(self):
        return {"k": self.k}


@dataclass(frozen=True, eq=False)
class SmoothIntersection(SdfNode):
    """max(a, b) + h²k/4 (hard for k = 0). Id of the farther operand (the active one)."""

    a: SdfNode
    b: SdfNode
    k: float = 0.0

    def __post_init__(self):
        _check_node(self.a)
        _check_node(self.b)
        object.__setattr__(self, "k", _positive(self.k, "smooth intersection k", allow_zero=True))

    @property
    def children(self):
        return (self.a, self.b)

    def _eval(self, p, need_material):
        da, ma = self.a._eval(p, need_material)
        db, mb = self.b._eval(p, need_material)
        d = np.maximum(da, db) + _blend(da, db, self.k)
        return d, (np.where(da >= db, ma, mb) if need_material else None)

    def _emit(self, cg, p):
        da, ma = self.a._emit(cg, p)
        db, mb = self.b._emit(cg, p)
        d = cg.let("float", "d", f"sdf_smax({da}, {db}, {glsl_float(self.k)})")
        m = cg.let("int", "m", f"{da} >= {db} ? {ma} : {mb}")
        return d, m

    def _spec(self):
        return {"k": self.k}


@dataclass(frozen=True, eq=False)
class SmoothSubtraction(SdfNode):
    """``a`` with ``b`` carved out: smax(a, −b, k). Always ``a``'s material id."""

    a: SdfNode
    b: SdfNode
    k: float = 0.0

    def __post_init__(self):
        _check_node(self.a)
        _check_node(self.b)
        object.__setattr__(self, "k", _positive(self.k, "smooth subtraction k", allow_zero=True))

    @property
    def children(self):
        return (self.a, self.b)

    def _eval(self, p, need_material):
        da, ma = self.a._eval(p, need_material)
        db, _ = self.b._eval(p, False)
        return np.maximum(da, -db) + _blend(da, -db, self.k), ma

    def _emit(self, cg, p):
        da, ma = self.a._emit(cg, p)
        db, _ = self.b._emit(cg, p)
        d = cg.let("float", "d", f"sdf_smax({da}, -{db}, {glsl_float(self.k)})")
        return d, ma

    def material_ids(self) -> set[int]:
        return self.a.material_ids()

    def _spec(self):
        return {"k": self.k}


def union(*nodes: SdfNode, k: float = 0.0) -> SdfNode:
    """Union of ``nodes`` (left fold of :class:`SmoothUnion` with blend width ``k``)."""
    if not nodes:
        raise InvalidInputError("union of no shapes; accepted: one or more SdfNode")
    out = nodes[0]
    _check_node(out)
    for node in nodes[1:]:
        out = SmoothUnion(out, node, k)
    return out


def intersection(*nodes: SdfNode, k: float = 0.0) -> SdfNode:
    """Intersection of ``nodes`` (left fold of :class:`SmoothIntersection`)."""
    if not nodes:
        raise InvalidInputError("intersection of no shapes; accepted: one or more SdfNode")
    out = nodes[0]
    _check_node(out)
    for node in nodes[1:]:
        out = SmoothIntersection(out, node, k)
    return out


def subtract(a: SdfNode, *cutters: SdfNode, k: float = 0.0) -> SdfNode:
    """``a`` minus each of ``cutters`` (:class:`SmoothSubtraction` with blend width ``k``)."""
    out = a
    _check_node(out)
    for node in cutters:
        out = SmoothSubtraction(out, node, k)
    return out
