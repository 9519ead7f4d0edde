"""Scenes: geometry, materials, cameras and the scene registry.

Conventions (DESIGN.md §3): right-handed, +Y up, cameras look down their -Z (OpenGL). Objects
are stored in the scene's canonical frame (:mod:`prtbench.scene.frame`; builders apply their
``world_from_object`` transforms when building, and ``Scene.world_from_canonical`` says where
the user's world is), which is what every method and the reference render.
Surfaces are one-sided: the front side is the side the vertex normals point to, and a surface
seen from behind is black in every renderer and in the reference, so thin parts (leaves, cloth)
are modelled as closed or two-layer geometry.

The background is not drawn (``hide_emitters``): pixels that see no geometry are 0 in every
method and in the reference, and masked metrics ignore them.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Union

import numpy as np

from prtbench.api.cache import content_key
from prtbench.api.errors import InvalidInputError
from prtbench.scene.frame import IDENTITY, Similarity

Color = tuple[float, float, float]


@dataclass(frozen=True, eq=False)
class Texture:
    """A linear float texture sampled with an object's UVs (bilinear, repeat).

    Attributes
    ----------
    image : ndarray, shape (H, W, C), float32
        Row 0 is v = 0 (the bottom of UV space, as OpenGL samples it).
    name : str
        What the texture shows, for reports.
    """

    image: np.ndarray
    name: str = "texture"

    def __post_init__(self) -> None:
        img = np.asarray(self.image, dtype=np.float32)
        if img.ndim == 2:
            img = img[..., None]
        if img.ndim != 3 or not np.all(np.isfinite(img)):
            raise InvalidInputError(f"texture '{self.name}' must be a finite (H, W, C) array")
        object.__setattr__(self, "image", img)

    def sample(self, uv: np.ndarray) -> np.ndarray:
        """Bilinear sample at ``uv`` (N, 2) with repeat wrapping; returns (N, C)."""
        h, w, _ = self.image.shape
        x = np.mod(uv[:, 0], 1.0) * w - 0.5
        y = np.mod(uv[:, 1], 1.0) * h - 0.5
        x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
        fx, fy = (x - x0)[:, None], (y - y0)[:, None]
        img = self.image

        def at(yy: np.ndarray, xx: np.ndarray) -> np.ndarray:
            return img[np.mod(yy, h), np.mod(xx, w)]

        return ((1 - fx) * (1 - fy) * at(y0, x0) + fx * (1 - fy) * at(y0, x0 + 1)
                + (1 - fx) * fy * at(y0 + 1, x0) + fx * fy * at(y0 + 1, x0 + 1))


@dataclass(frozen=True, eq=False)
class Material:
    """The one BRDF of DESIGN.md §4: f = kd/π + ks·(s+1)/(2π)·max(ωi·r, 0)^s.

    Attributes
    ----------
    kd : RGB tuple or Texture
        Diffuse albedo in [0, 1].
    ks : RGB tuple or Texture
        Specular albedo; (0, 0, 0) makes the material purely diffuse.
    shininess : float or Texture
        Phong exponent s >= 0 of the normalized lobe.
    normal_map : Texture or None
        Tangent-space normal map (RGB in [0, 1]), used by methods that support it.
    name : str
        Material name.
    """

    kd: Union[Color, Texture] = (0.5, 0.5, 0.5)
    ks: Union[Color, Texture] = (0.0, 0.0, 0.0)
    shininess: Union[float, Texture] = 1.0
    normal_map: Texture | None = None
    name: str = "material"

    def __post_init__(self) -> None:
        for attr in ("kd", "ks"):
            value = getattr(self, attr)
            if not isinstance(value, Texture):
                rgb = tuple(float(c) for c in value)
                if len(rgb) != 3 or not all(0.0 <= c <= 1.0 for c in rgb):
                    raise InvalidInputError(
                        f"material '{self.name}': {attr}={value!r}; accepted: 3 values in [0, 1]")
                object.__setattr__(self, attr, rgb)
        if not isinstance(self.shininess, Texture):
            s = float(self.shininess)
            if not (0.0 <= s <= 1e4):
                raise InvalidInputError(
                    f"material '{self.name}': shininess={s}; accepted: [0, 10000]")
            object.__setattr__(self, "shininess", s)

    @property
    def is_glossy(self) -> bool:
        return isinstance(self.ks, Texture) or any(c > 0 for c in self.ks)

    @property
    def is_textured(self) -> bool:
        return any(isinstance(v, Texture) for v in (self.kd, self.ks, self.shininess))

    def spec(self) -> dict[str, Any]:
        """JSON-able description (textures by content hash) for cache keys and reports."""
        def enc(v: Any) -> Any:
            return {"texture": v.name, "hash": content_key(v.image)} if isinstance(v, Texture) else v
        return {"kd": enc(self.kd), "ks": enc(self.ks), "shininess": enc(self.shininess),
                "normal_map": enc(self.normal_map) if self.normal_map else None,
                "name": self.name}


@dataclass(eq=False)
class TriangleMesh:
    """An indexed triangle mesh in world space.

    Attributes
    ----------
    positions : ndarray, shape (V, 3), float32
    faces : ndarray, shape (F, 3), int32
        Counter-clockwise seen from the front (the side the normals point to).
    normals : ndarray, shape (V, 3), float32
        Unit shading normals; area-weighted face normals when not given.
    uvs : ndarray, shape (V, 2), float32, or None
        Texture coordinates for textured materials (not the transfer-texture atlas).
    """

    positions: np.ndarray
    faces: np.ndarray
    normals: np.ndarray | None = None
    uvs: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.positions = np.ascontiguousarray(self.positions, dtype=np.float32).reshape(-1, 3)
        self.faces = np.ascontiguousarray(self.faces, dtype=np.int32).reshape(-1, 3)
        if len(self.faces) and (self.faces.min() < 0 or self.faces.max() >= len(self.positions)):
            raise InvalidInputError("mesh faces index outside its positions")
        if not np.all(np.isfinite(self.positions)):
            raise InvalidInputError("mesh positions contain NaN/Inf")
        if self.normals is None:
            self.normals = vertex_normals(self.positions, self.faces)
        self.normals = np.ascontiguousarray(self.normals, dtype=np.float32).reshape(-1, 3)
        if self.uvs is not None:
            self.uvs = np.ascontiguousarray(self.uvs, dtype=np.float32).reshape(-1, 2)

    @property
    def n_vertices(self) -> int:
        return len(self.positions)

    @property
    def n_triangles(self) -> int:
        return len(self.faces)

    def triangle_areas(self) -> np.ndarray:
        """(F,) float64 triangle areas."""
        p = self.positions.astype(np.float64)
        a, b, c = p[self.faces[:, 0]], p[self.faces[:, 1]], p[self.faces[:, 2]]
        return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)


def vertex_normals(positions: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals, (V, 3) float32; isolated vertices get +Y."""
    p = positions.astype(np.float64)
    fn = np.cross(p[faces[:, 1]] - p[faces[:, 0]], p[faces[:, 2]] - p[faces[:, 0]])
    vn = np.zeros_like(p)
    for k in range(3):
        np.add.at(vn, faces[:, k], fn)
    length = np.linalg.norm(vn, axis=1, keepdims=True)
    vn = np.where(length > 0, vn / np.maximum(length, 1e-300), np.array([0.0, 1.0, 0.0]))
    return vn.astype(np.float32)


@dataclass(eq=False)
class SceneObject:
    """A named mesh with its material."""

    name: str
    mesh: TriangleMesh
    material: Material


@dataclass(frozen=True)
class View:
    """A pinhole camera (OpenGL convention: looks down its -Z, +Y up).

    Attributes
    ----------
    eye, target, up : 3-tuples
        Camera position, look-at point and up hint, world space.
    fov_y : float
        Vertical field of view in degrees.
    """

    eye: tuple[float, float, float]
    target: tuple[float, float, float]
    up: tuple[float, float, float] = (0.0, 1.0, 0.0)
    fov_y: float = 45.0

    def world_from_camera(self) -> np.ndarray:
        """(4, 4) float64 camera-to-world transform."""
        eye, target, up = (np.asarray(v, dtype=np.float64) for v in (self.eye, self.target, self.up))
        back = eye - target
        back /= np.linalg.norm(back)
        right = np.cross(up, back)
        right /= np.linalg.norm(right)
        true_up = np.cross(back, right)
        m = np.eye(4)
        m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, true_up, back, eye
        return m

    def camera_from_world(self) -> np.ndarray:
        """(4, 4) float64 view matrix."""
        return np.linalg.inv(self.world_from_camera())

    def clip_from_camera(self, aspect: float, near: float, far: float) -> np.ndarray:
        """(4, 4) float64 OpenGL perspective projection."""
        f = 1.0 / math.tan(math.radians(self.fov_y) / 2)
        m = np.zeros((4, 4))
        m[0, 0], m[1, 1] = f / aspect, f
        m[2, 2], m[2, 3] = (far + near) / (near - far), 2 * far * near / (near - far)
        m[3, 2] = -1.0
        return m

    def primary_rays(self, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
        """Rays through pixel centres, row 0 at the top of the image.

        Returns
        -------
        origins, directions : ndarray, shape (height, width, 3), float64
        """
        f = math.tan(math.radians(self.fov_y) / 2)
        aspect = width / height
        xs = ((np.arange(width) + 0.5) / width * 2 - 1) * f * aspect
        ys = (1 - (np.arange(height) + 0.5) / height * 2) * f
        x, y = np.meshgrid(xs, ys)
        d_cam = np.stack([x, y, -np.ones_like(x)], axis=-1)
        m = self.world_from_camera()
        d = d_cam @ m[:3, :3].T
        d /= np.linalg.norm(d, axis=-1, keepdims=True)
        return np.broadcast_to(m[:3, 3], d.shape).copy(), d


@dataclass(frozen=True)
class Trajectory:
    """An ordered set of views (table 4.1 averages over 30)."""

    views: tuple[View, ...]

    def __len__(self) -> int:
        return len(self.views)

    @classmethod
    def orbit(cls, *, center: Sequence[float], radius: float, height: float, n_views: int = 30,
              fov_y: float = 45.0, arc_degrees: float = 360.0, start_degrees: float = 0.0,
              ) -> "Trajectory":
        """``n_views`` cameras on a horizontal circle around ``center``, looking at it."""
        views = []
        for i in range(n_views):
            a = math.radians(start_degrees + arc_degrees * i / n_views)
            eye = (center[0] + radius * math.sin(a), center[1] + height,
                   center[2] + radius * math.cos(a))
            views.append(View(eye=eye, target=tuple(float(c) for c in center), fov_y=fov_y))
        return cls(tuple(views))


def objects_bounds(objects: Sequence[SceneObject]) -> tuple[np.ndarray, np.ndarray]:
    """World-space axis-aligned bounds (lo, hi), each (3,) float64, of ``objects``.

    :meth:`Scene.bounds`, for objects not yet in a scene (a file import checks its extent
    before it builds the scene's views).
    """
    pts = np.concatenate([o.mesh.positions for o in objects]).astype(np.float64)
    return pts.min(axis=0), pts.max(axis=0)


@dataclass(eq=False)
class Scene:
    """Everything a method and the reference need to render the same picture.

    Attributes
    ----------
    name : str
        Registry name.
    objects : list of SceneObject
        World-space geometry with materials.
    variant : str
        ``"diffuse"`` or ``"glossy"`` material variant.
    default_light : str
        Name in the light registry.
    trajectory : Trajectory
        Default views (30 unless stated).
    exposure : float
        Fixed display exposure (linear multiplier before sRGB).
    params : dict
        Builder parameters (for cache keys and reports).
    substitution : str
        What this scene stands in for when the paper's assets are not public ("" if none).
    sdf : object or None
        For continuous (SDF) scenes: the signed distance function the scene is defined by
        (see :mod:`prtbench.transport.sdf`); ``objects`` then hold its fine marching-cubes mesh, which
        the reference, masks and mesh-based methods use.
    world_from_canonical : Similarity
        Maps the canonical frame the objects, views and SDF are stored in to the user's world
        (:mod:`prtbench.scene.frame`); the identity for a scene left as built.
    """

    name: str
    objects: list[SceneObject]
    variant: str = "diffuse"
    default_light: str = "sky"
    trajectory: Trajectory = field(default_factory=lambda: Trajectory(()))
    exposure: float = 1.0
    params: dict[str, Any] = field(default_factory=dict)
    substitution: str = ""
    sdf: Any = None
    world_from_canonical: Similarity = IDENTITY

    @property
    def n_triangles(self) -> int:
        return sum(o.mesh.n_triangles for o in self.objects)

    @property
    def n_vertices(self) -> int:
        return sum(o.mesh.n_vertices for o in self.objects)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """World-space axis-aligned bounds (lo, hi), each (3,) float64."""
        return objects_bounds(self.objects)

    def diagonal(self) -> float:
        lo, hi = self.bounds()
        return float(np.linalg.norm(hi - lo))

    def world_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The bounds (lo, hi) in the user's world (:attr:`world_from_canonical`), (3,) float64."""
        return tuple(self.world_from_canonical.apply(b) for b in self.bounds())

    def merged(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """All objects in one mesh.

        Returns
        -------
        positions (V, 3) float32, normals (V, 3) float32, faces (F, 3) int32,
        object_of_face (F,) int32 index into ``objects``.
        """
        pos, nrm, fcs, obj = [], [], [], []
        offset = 0
        for i, o in enumerate(self.objects):
            pos.append(o.mesh.positions)
            nrm.append(o.mesh.normals)
            fcs.append(o.mesh.faces + offset)
            obj.append(np.full(o.mesh.n_triangles, i, dtype=np.int32))
            offset += o.mesh.n_vertices
        return (np.concatenate(pos), np.concatenate(nrm), np.concatenate(fcs).astype(np.int32),
                np.concatenate(obj))

    def content_hash(self) -> str:
        """SHA-256 of geometry, normals, UVs and materials: the scene part of cache keys."""
        parts = [self.name, self.variant, self.sdf.spec() if self.sdf is not None else None]
        for o in self.objects:
            parts.append([o.name, o.mesh.positions, o.mesh.faces, o.mesh.normals,
                          o.mesh.uvs if o.mesh.uvs is not None else None, o.material.spec()])
        return content_key(parts)

    def with_views(self, n_views: int) -> "Scene":
        """A shallow copy keeping the first ``n_views`` trajectory views (evenly spread)."""
        views = self.trajectory.views
        if n_views < 1 or n_views > len(views):
            raise InvalidInputError(
                f"--views {n_views}; accepted: 1..{len(views)} for scene '{self.name}'")
        idx = np.linspace(0, len(views), n_views, endpoint=False).astype(int)
        return dataclasses.replace(self, trajectory=Trajectory(tuple(views[i] for i in idx)))


VARIANTS = ("diffuse", "glossy")
