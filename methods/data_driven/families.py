"""Random lighting configurations for the data-driven method's datasets (paper §4.1).

Families (the ``light_family`` knob): ``env-rotations`` (an environment map turned about +Y by
a random whole number of lat-long columns, an exact rotation), ``spot``, ``point`` and
``directional``. Point and spot lights go ``inside`` an enclosure (each anchored on a
measurement point it sees directly, kept clear of every surface) or ``above`` the view target
on a shell; their power is set so the lit point receives irradiance of about the ``intensity``
knob, times a random factor in [0.5, 1.5].
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from methods.data_driven.lights import DirectionalLight, EnvironmentRotations, PointLight, SpotLight
from prtbench.api.errors import InvalidInputError, UnknownNameError
from prtbench.scene.geometry import sample_surface
from prtbench.transport.raytrace import Tracer, offset_origins

FAMILIES = ("env-rotations", "spot", "point", "directional")
REGIONS = ("auto", "inside", "above")


def _is_enclosure(scene: Any, target: np.ndarray) -> bool:
    """True when rays from ``target`` along ±x, ±y, ±z hit geometry in at least 4 of 6."""

    tracer = Tracer.from_scene(scene)
    axes = np.concatenate([np.eye(3), -np.eye(3)])
    hits = tracer.first_hit(np.repeat(target[None], 6, axis=0), axes)
    return int(hits.hit.sum()) >= 4


def light_region(scene: Any, region: str = "auto") -> tuple[str, np.ndarray, float]:
    """Where a scene's random lights go: (kind, centre (3,), radius).

    ``inside``: uniformly inside the scene's bounding box shrunk by 10 % (an enclosure such as
    the Cornell box); ``above``: on a shell above the first view's target at a distance between
    0.5 and 1 of the camera distance. ``auto`` picks ``inside`` when the view target is enclosed
    (:func:`_is_enclosure`).
    """
    if region not in REGIONS:
        raise UnknownNameError("light region", region, REGIONS)
    view = scene.trajectory.views[0] if len(scene.trajectory) else None
    lo, hi = scene.bounds()
    target = np.asarray(view.target if view else (lo + hi) / 2, dtype=np.float64)
    distance = float(np.linalg.norm(np.asarray(view.eye) - target)) if view else scene.diagonal()
    if region == "auto":
        region = "inside" if _is_enclosure(scene, target) else "above"
    return region, target, distance


def _random_unit(rng: np.random.Generator, n: int) -> np.ndarray:
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


#: Directions probing a light position's distance to the nearest surface (cube corners/faces).
_CLEARANCE_DIRS = np.array([[x, y, z] for x in (-1, 0, 1) for y in (-1, 0, 1) for z in (-1, 0, 1)
                            if (x, y, z) != (0, 0, 0)], dtype=np.float64)
_CLEARANCE_DIRS /= np.linalg.norm(_CLEARANCE_DIRS, axis=1, keepdims=True)


def _anchored(scene: Any, rng: np.random.Generator, n: int, anchors: tuple[np.ndarray, np.ndarray],
              *, clearance: float = 0.06) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Light positions that directly see a random anchor point: (positions, aims, distances).

    Each light picks an anchor (a measurement point), a direction within about 70° of the
    anchor's normal and a distance in [0.25, 0.6] of the scene diagonal (shortened after failed
    tries) such that the light stays inside the scene's bounds, keeps ``clearance`` × diagonal
    from every surface and sees the anchor.
    """

    tracer = Tracer.from_scene(scene)
    lo, hi = scene.bounds()
    diag = scene.diagonal()
    points, normals = (np.asarray(a, dtype=np.float64) for a in anchors)
    positions, aims, dists = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros(n)
    for i in range(n):
        for attempt in range(64):
            k = int(rng.integers(len(points)))
            p, nrm = points[k], normals[k] / np.linalg.norm(normals[k])
            d = _random_unit(rng, 1)[0]
            d = d if d @ nrm > 0 else -d
            d = d + nrm * 1.5  # towards the normal: no grazing lights
            d /= np.linalg.norm(d)
            r = diag * (0.25 + 0.35 * rng.random()) * (0.8 ** (attempt // 8))
            q = p + d * r
            if np.any(q < lo) or np.any(q > hi):
                continue
            # Clearance: a delta light grazing a wall makes a tiny, extremely bright hot spot
            # that dominates the direct vector's norm but hardly any indirect light.
            near = tracer.first_hit(np.repeat(q[None], len(_CLEARANCE_DIRS), axis=0),
                                    _CLEARANCE_DIRS)
            if np.min(near.t) < clearance * diag:
                continue
            origin = offset_origins(p[None], nrm[None], diagonal=diag)
            if not tracer.occluded(origin, d[None], tfar=np.array([r]))[0]:
                break
        positions[i], aims[i], dists[i] = q, p, r
    return positions, aims, dists


def sample_family(scene: Any, family: str, count: int, *, seed: int, environment: Any = None,
                  region: str = "auto", intensity: float = 1.0,
                  anchors: tuple[np.ndarray, np.ndarray] | None = None) -> Sequence[Any]:
    """``count`` random lighting configurations of ``family`` for ``scene``.

    Parameters
    ----------
    scene : Scene
    family : {"env-rotations", "spot", "point", "directional"}
    count : int
    seed : int
    environment : EnvironmentLight
        The map rotated by ``env-rotations``.
    region : {"auto", "inside", "above"}
        Where point and spot lights go (:func:`light_region`): ``inside`` anchors each light on
        a random measurement point (``anchors``), which it sees directly and a spot aims at;
        ``above`` puts lights on a shell around the view target, aimed near it.
    intensity : float
        Scale of the lights' power, chosen so that the lit point (anchor or target) receives
        irradiance of about ``intensity`` (random factors in [0.5, 1.5] per configuration).
    anchors : (points (K, 3), normals (K, 3)), optional
        Surface points for ``inside`` (default: 256 area-uniform surface samples).

    Returns
    -------
    sequence
        EnvironmentLight (rotated) or analytic lights, one per configuration.
    """
    if family not in FAMILIES:
        raise UnknownNameError("light family", family, FAMILIES)
    if count < 0:
        raise InvalidInputError(f"configuration count {count}; accepted: >= 0")
    rng = np.random.default_rng([int(seed), 0x44445052])  # "DDPR"
    if family == "env-rotations":
        if environment is None:
            raise InvalidInputError("light family 'env-rotations' needs an environment map")
        return EnvironmentRotations(environment, rng.integers(0, environment.width, size=count))
    scale = rng.uniform(0.5, 1.5, size=count)
    if family == "directional":
        d = _random_unit(rng, count)
        d[:, 1] = np.abs(d[:, 1]) * 0.9 + 0.1
        return [DirectionalLight(tuple(d[i]), (intensity * scale[i],) * 3, name=f"directional{i}")
                for i in range(count)]
    kind, target, distance = light_region(scene, region)
    if kind == "inside":
        if anchors is None:

            samples = sample_surface(scene, 256, seed=int(seed) + 17)
            anchors = (samples.points, samples.normals)
        positions, aims, dists = _anchored(scene, rng, count, anchors)
    else:
        d = _random_unit(rng, count)
        d[:, 1] = np.abs(d[:, 1]) * 0.8 + 0.2  # upper hemisphere, not grazing
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        dists = distance * (0.5 + 0.5 * rng.random(count))
        positions = target + d * dists[:, None]
        aims = target + _random_unit(rng, count) * 0.15 * distance * rng.random((count, 1))
        dists = np.linalg.norm(aims - positions, axis=1)
    power = intensity * dists * dists * scale
    if family == "point":
        return [PointLight(tuple(positions[i]), (power[i],) * 3, name=f"point{i}")
                for i in range(count)]
    cutoff = rng.uniform(30.0, 60.0, size=count)
    return [SpotLight(tuple(positions[i]), tuple(aims[i] - positions[i]),
                      cutoff_deg=float(cutoff[i]), intensity=(power[i],) * 3, name=f"spot{i}")
            for i in range(count)]
