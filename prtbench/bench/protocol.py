"""The protocol's facts about one run (docs/PROTOCOL.md): which reference and panel its rows
belong to, whether the method saw the light or the views it is scored on, and what a new light
costs it before its first frame."""

from __future__ import annotations

import hashlib
import json
import math
import statistics
import time
from dataclasses import asdict
from typing import Any

import numpy as np

from prtbench.api.method import Method
from prtbench.bench.job import Job

#: The most interreflection bounces a path reference may model.
MAX_REFERENCE_BOUNCES = 16


def reference_bounces(job: Job, config: Any) -> int:
    """The bounces of ``job``'s path reference: the job's ``reference_bounces`` (one per panel),
    else the method's own ``bounces`` knob (0 where it has none)."""
    if job.reference_bounces is not None:
        return int(job.reference_bounces)
    return int(getattr(config, "bounces", 0))


def panel_of(prepared: Any, *, ref_spp: int | None, bounces: int) -> str:
    """Which rows may share a ranking (docs/PROTOCOL.md): the same scene, variant, light,
    resolution and view set, scored against the same reference (kind, bounces, spp)."""
    views = [asdict(v) for v in prepared.scene.trajectory.views]
    view_set = hashlib.sha256(json.dumps(views, sort_keys=True, default=str).encode())
    reference = (f"path/b{bounces}/{ref_spp}spp" if prepared.reference_method is None
                 else prepared.job.reference)
    return (f"{prepared.scene.name}/{prepared.scene.variant} {prepared.light.name} "
            f"{prepared.width}x{prepared.height} views={len(views)}:"
            f"{view_set.hexdigest()[:8]} ref={reference}")


#: An evaluated view "is" a training camera when its eye lies within this fraction of the
#: scene's diagonal of the camera's and their directions differ by less than
#: :data:`SAME_VIEW_DEGREES`.
SAME_VIEW_DISTANCE = 1e-3
SAME_VIEW_DEGREES = 0.5


def same_camera(a: Any, b: Any, *, diagonal: float) -> bool:
    """Whether views ``a`` and ``b`` see the scene from the same place in the same direction."""
    eye_a, eye_b = np.asarray(a.eye, float), np.asarray(b.eye, float)
    if np.linalg.norm(eye_a - eye_b) > SAME_VIEW_DISTANCE * diagonal:
        return False
    da, db = np.asarray(a.target, float) - eye_a, np.asarray(b.target, float) - eye_b
    cos = float(da @ db / max(np.linalg.norm(da) * np.linalg.norm(db), 1e-300))
    return cos >= math.cos(math.radians(SAME_VIEW_DEGREES))


def split_of(method_cls: type[Method], config: Any, light: Any, *, scene: Any = None) -> str:
    """``trained`` where the method trained or fitted on this light or on one of the scene's
    evaluated views, ``in-family`` where it fits a family of lights built around the light,
    else ``held-out``."""
    if getattr(light, "name", light) in set(method_cls.training_lights(config)):
        return "trained"
    if scene is not None:
        cameras = method_cls.training_cameras(scene, config)
        diagonal = float(scene.diagonal())
        if any(same_camera(view, camera, diagonal=diagonal)
               for view in scene.trajectory.views for camera in cameras):
            return "trained"
    return "in-family" if method_cls.light_class_of(config) == "family" else "held-out"


def time_light_change(renderer: Any, view: Any, light: Any, *, repeats: int = 3
                      ) -> float | None:
    """Milliseconds a new light costs before its first frame (``light_change_ms``).

    The renderer's own :meth:`~prtbench.api.method.Renderer.light_change` when it has one;
    otherwise a ``render`` of a light nothing has seen (the same image as
    :meth:`~prtbench.transport.lights.EnvironmentLight.as_new_light`: no memoised or cached
    projection, no per-light state in the renderer) minus a ``render`` of the known light:
    the SH projection, TPFL matrix, probe products, cubemap resampling or median cut a light
    change pays, measured the same way for every method. Medians over ``repeats``. None for a
    renderer that :attr:`~prtbench.api.method.Renderer.bakes_its_light`."""
    if renderer.bakes_its_light:  # it refuses any other light: a change is a new precompute
        return None

    def timed(call) -> float:
        start = time.perf_counter()
        call()
        return (time.perf_counter() - start) * 1e3

    if renderer.light_change(light.as_new_light()):  # the method times its own hook
        return float(statistics.median(
            timed(lambda: renderer.light_change(light.as_new_light())) for _ in range(repeats)))
    known = statistics.median(timed(lambda: renderer.render(view, light)) for _ in range(repeats))
    new = statistics.median(timed(lambda: renderer.render(view, light.as_new_light()))
                            for _ in range(repeats))
    return max(0.0, float(new - known))
