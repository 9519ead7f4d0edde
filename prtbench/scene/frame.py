"""The canonical frame (DESIGN.md §22): scenes are rendered centred and at unit scale.

Distant-light PRT is invariant to a uniform scale and a translation of the whole scene, but
float arithmetic is not: float32 positions 10⁷ from the origin are spaced 1 apart, and Mitsuba
offsets every secondary ray by an absolute ``(1 + max|p|) · 8.9e-5``, larger than a scene
modelled in millimetres. So every scene is built in its *canonical frame*, and one similarity
``world_from_canonical`` (a uniform scale s > 0 and an offset o: p_world = s·p + o) records where
the user's world is. It is fitted and applied in float64, before positions are cast to float32,
so a scene modelled in millimetres or placed far from the origin renders the same image as the
same scene in metres at the origin; precompute, ray offsets, GL clip planes, masks and the
reference all see only the canonical scene.

Which canonical frame a scene gets:

- a scene from a file: centred (its bounds' centre at the origin) with a bounds diagonal of
  :data:`CANONICAL_DIAGONAL`, whatever its units (:func:`canonical_from_world`);
- a built-in scene: as built when it is already well conditioned (:func:`is_conditioned`: all
  of them at their default parameters), so their images, caches and golden metrics are
  bit-identical; otherwise (a builder parameter such as ``size=1e-5``) as a file's;
- a scene moved in world space as a whole (a stability case): the frame of the scene it was
  moved from (:func:`fit_bounds`), so the same shape is the same canonical scene.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

#: Bounds diagonal of a canonical scene (its bounding sphere has radius at most 1).
CANONICAL_DIAGONAL = 2.0
#: A scene is conditioned (left as built) when Mitsuba's absolute ray offset
#: ``(1 + max|p|) · RAY_EPSILON`` stays under this fraction of its bounds diagonal ...
CONDITIONED_OFFSET_FRACTION = 1e-3
#: ... and float32's spacing at ``max|p|`` (``max|p| · 2⁻²⁴``) under this fraction of it: far
#: below anything the metrics resolve (the canonical frame itself has 9e-5 and 3e-8).
CONDITIONED_SPACING_FRACTION = 1e-6
#: Mitsuba 3's float32 ``RayEpsilon`` (1500 · 2⁻²⁴): its secondary rays start
#: ``(1 + max|p|) · RAY_EPSILON`` from the surface, an absolute distance.
RAY_EPSILON = 1500 * 2.0 ** -24


@dataclass(frozen=True)
class Similarity:
    """A uniform scale then a translation: ``p ↦ scale · p + offset`` (float64).

    Attributes
    ----------
    scale : float
        Positive and finite (no mirroring: windings and normals are kept).
    offset : 3-tuple of float
    """

    scale: float = 1.0
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        scale = float(self.scale)
        offset = tuple(float(c) for c in np.asarray(self.offset, dtype=np.float64).reshape(3))
        if not (math.isfinite(scale) and scale > 0.0) or not all(map(math.isfinite, offset)):
            # Built from checked bounds only: a failure here is a harness bug, not user input.
            raise ValueError(f"similarity scale={scale!r} offset={offset!r}; accepted: a finite "
                             "scale > 0 and a finite offset")
        object.__setattr__(self, "scale", scale)
        object.__setattr__(self, "offset", offset)

    @property
    def is_identity(self) -> bool:
        return self.scale == 1.0 and not any(self.offset)

    def apply(self, points: Any) -> np.ndarray:
        """``points`` (..., 3) mapped, float64 (computed in float64 whatever their type)."""
        return np.asarray(points, dtype=np.float64) * self.scale + np.asarray(self.offset)

    def inverse(self) -> "Similarity":
        return Similarity(1.0 / self.scale, tuple(-np.asarray(self.offset) / self.scale))

    def after(self, first: "Similarity") -> "Similarity":
        """``self ∘ first``: ``first`` applied, then ``self``."""
        return Similarity(self.scale * first.scale,
                          tuple(self.scale * np.asarray(first.offset) + np.asarray(self.offset)))

    def matrix(self) -> np.ndarray:
        """(4, 4) float64 homogeneous matrix."""
        m = np.eye(4) * self.scale
        m[3, 3] = 1.0
        m[:3, 3] = self.offset
        return m

    def view(self, view: Any) -> Any:
        """A :class:`~prtbench.scene.model.View` mapped: eye and target moved; its up
        direction and field of view are unchanged by a similarity."""
        eye, target = self.apply(np.asarray([view.eye, view.target], dtype=np.float64))
        return dataclasses.replace(view, eye=tuple(float(c) for c in eye),
                                   target=tuple(float(c) for c in target))

    def to_json(self) -> dict[str, Any]:
        return {"scale": self.scale, "offset": list(self.offset)}


IDENTITY = Similarity()


def bounds_of(points: Sequence[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned bounds (lo, hi), each (3,) float64, of the (N_i, 3) arrays ``points``."""
    stacked = np.concatenate([np.asarray(p, dtype=np.float64).reshape(-1, 3) for p in points])
    return stacked.min(axis=0), stacked.max(axis=0)


def diagonal(lo: np.ndarray, hi: np.ndarray) -> float:
    """Length of the bounds (lo, hi)'s diagonal, without the underflow of a plain norm (whose
    squares vanish below 1e-154) or its overflow above 1e154."""
    with np.errstate(over="ignore", invalid="ignore"):
        extent = np.abs(np.asarray(hi, dtype=np.float64) - np.asarray(lo, dtype=np.float64))
    largest = float(np.max(extent))
    if not (math.isfinite(largest) and largest > 0.0):
        return largest
    return largest * float(np.linalg.norm(extent / largest))


def canonical_from_world(lo: np.ndarray, hi: np.ndarray, *,
                         diagonal: float = CANONICAL_DIAGONAL) -> Similarity:
    """The similarity that centres the bounds (lo, hi) at the origin and scales their diagonal
    to ``diagonal``; the bounds must be finite with a positive diagonal
    (:func:`prtbench.scene.params.check_extent`)."""
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    return fit_bounds(lo, hi, np.full(3, -0.5 * diagonal / math.sqrt(3.0)),
                      np.full(3, 0.5 * diagonal / math.sqrt(3.0)))


def fit_bounds(lo: np.ndarray, hi: np.ndarray, target_lo: np.ndarray,
               target_hi: np.ndarray) -> Similarity:
    """The similarity that maps the centre of (lo, hi) onto the centre of (target_lo,
    target_hi) and its diagonal onto the target's diagonal (float64)."""
    lo, hi, target_lo, target_hi = (np.asarray(b, dtype=np.float64)
                                    for b in (lo, hi, target_lo, target_hi))
    scale = diagonal(target_lo, target_hi) / diagonal(lo, hi)
    # Centre first (a difference of nearby large numbers is exact-ish in float64), then scale.
    return Similarity(scale, tuple(0.5 * (target_lo + target_hi) - scale * 0.5 * (lo + hi)))


def is_conditioned(lo: np.ndarray, hi: np.ndarray) -> bool:
    """Whether a scene with bounds (lo, hi) renders as well as built as it would canonically.

    True when Mitsuba's absolute ray offset stays under :data:`CONDITIONED_OFFSET_FRACTION`
    of the bounds diagonal and float32's spacing at the farthest coordinate under
    :data:`CONDITIONED_SPACING_FRACTION` of it: the built-in scenes at their default
    parameters (diagonals 1.8 to 11.4 near the origin) and, e.g., ``plane size=2000``.
    """
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    diag = diagonal(lo, hi)
    reach = float(np.max(np.abs(np.concatenate([lo, hi]))))
    return (diag > 0.0 and (1.0 + reach) * RAY_EPSILON <= CONDITIONED_OFFSET_FRACTION * diag
            and reach * 2.0 ** -24 <= CONDITIONED_SPACING_FRACTION * diag)


def moved_scene(scene: Any, canonical_from_current: Similarity) -> Any:
    """``scene`` (a :class:`~prtbench.scene.model.Scene`) with its geometry, views and SDF
    moved by ``canonical_from_current``, its ``world_from_canonical`` updated to match.

    Positions go through float64 and are cast to float32 once; normals, faces, UVs and
    materials are kept (a similarity changes no direction). An SDF's tree gains the same
    scale and translation nodes. ``params["world_from_canonical"]`` records the frame when it
    is not the identity.
    """

    if canonical_from_current.is_identity:
        return scene
    move = canonical_from_current
    objects = [dataclasses.replace(o, mesh=dataclasses.replace(
        o.mesh, positions=move.apply(o.mesh.positions))) for o in scene.objects]
    trajectory = dataclasses.replace(scene.trajectory,
                                     views=tuple(move.view(v) for v in scene.trajectory.views))
    sdf = scene.sdf
    if sdf is not None:
        # d'(p) = s·d(p/s) for a scale s, then d''(p) = d'(p − o): the surface moves with it.
        lo, hi = (move.apply(np.asarray(b, dtype=np.float64)) for b in sdf.bounds)
        sdf = dataclasses.replace(sdf, root=sdf.root.scale(move.scale).translate(*move.offset),
                                  bounds=(tuple(lo), tuple(hi)))
    world_from_canonical = scene.world_from_canonical.after(move.inverse())
    return dataclasses.replace(scene, objects=objects, trajectory=trajectory, sdf=sdf,
                               world_from_canonical=world_from_canonical,
                               params=with_frame(scene.params, world_from_canonical))


def with_frame(params: dict[str, Any], world_from_canonical: Similarity) -> dict[str, Any]:
    """``params`` with ``world_from_canonical`` recorded (dropped when it is the identity), so
    stored rows say where the user's world was."""
    out = {k: v for k, v in params.items() if k != "world_from_canonical"}
    if not world_from_canonical.is_identity:
        out["world_from_canonical"] = world_from_canonical.to_json()
    return out
