"""Mitsuba path references under the data-driven method's lights (total, direct or indirect).

:func:`prtbench.render.reference.render_reference` renders environment maps only. This module builds
the same Mitsuba scene with :func:`prtbench.render.reference.mitsuba_scene_dict` and swaps the emitter
for Mitsuba's ``point``, ``spot`` or ``directional`` (or keeps the ``envmap``), so the method and
the reference see identical geometry, materials and cameras.

Components: ``total`` is the ``path`` integrator with ``max_depth = bounces + 2``; ``direct`` is
``max_depth = 2``; ``indirect`` is total − direct rendered with the *same seeds*, so both
images draw identical samples up to the first bounce and the direct light cancels exactly (no
negative pixels). Each image averages two halves with different seeds, and RMS(A − B) of the
halves estimates the image's own Monte-Carlo error (``noise_rmse``, linear radiance). Cached as
EXRs under ``$PRTBENCH_CACHE/ddprt-references``.
"""

from __future__ import annotations

import hashlib
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from methods.data_driven.lights import analytic_lights, is_environment, light_spec
from prtbench.api.cache import cache_root, content_key
from prtbench.api.errors import InvalidInputError
from prtbench.io.imageio import read_exr, read_exr_metadata, write_exr
from prtbench.render.mitsuba_variant import select_variant
from prtbench.render.reference import mitsuba_scene_dict

#: Bump when a change here changes pixels.
VERSION = 1
COMPONENTS = ("total", "direct", "indirect")
LANES_PER_PASS = 1 << 21


@dataclass
class LightReference:
    """A cached Mitsuba render: (H, W, 3) float32 linear image, spp and its own noise."""

    image: np.ndarray
    spp: int
    noise_rmse: float
    component: str
    bounces: int
    path: Path
    seconds: float
    cache_hit: bool = False


class _Black:
    """A placeholder environment for ``mitsuba_scene_dict`` (its emitter is replaced)."""

    name = "none"
    image = np.zeros((4, 8, 3), np.float32)


def scene_dict(scene: Any, light: Any, view: Any, *, width: int, height: int,
               max_depth: int) -> dict[str, Any]:
    """``mi.load_dict`` description of ``scene`` under ``light`` (variant must be set)."""

    env = light if is_environment(light) else _Black()
    out = mitsuba_scene_dict(scene, env, view, width=width, height=height, bounces=0)
    out["integrator"] = {"type": "path", "max_depth": int(max_depth),
                         "rr_depth": int(max_depth) + 1, "hide_emitters": True}
    if not is_environment(light):
        del out["light"]
        for k, item in enumerate(analytic_lights(light, env_lights=1)):
            out[f"light_{k:03d}"] = item.mitsuba_dict()
    return out


def _seed(seed: int, half: int, index: int) -> int:
    digest = hashlib.sha256(f"ddprt-reference:{seed}:{half}:{index}".encode()).digest()
    return int.from_bytes(digest[:4], "little")


def _render(scenes: list, *, width: int, height: int, spp: int, seed: int, half: int,
            ) -> list[np.ndarray]:
    import mitsuba as mi

    per_pass = max(1, LANES_PER_PASS // (width * height))
    acc = [np.zeros((height, width, 4)) for _ in scenes]
    done, index = 0, 0
    while done < spp:
        count = min(per_pass, spp - done)
        s = _seed(seed, half, index)
        for a, sc in zip(acc, scenes):  # the same seed in every scene: shared first segments
            a += np.asarray(mi.render(sc, spp=count, seed=s), np.float64).reshape(height, width, 4) * count
        done += count
        index += 1
    return [a / spp for a in acc]


def render_light_reference(scene: Any, light: Any, view: Any, *, width: int, height: int,
                           spp: int, bounces: int = 1, component: str = "total", seed: int = 0,
                           use_cache: bool = True) -> LightReference:
    """Mitsuba render of ``scene`` lit by ``light`` (cached).

    Parameters
    ----------
    scene : Scene
    light : EnvironmentLight, analytic light, LightSet or list of analytic lights
    view : View
    width, height, spp : int
        Resolution and samples per pixel (≥ 2: two halves estimate the noise).
    bounces : int
        Indirect bounces of ``total`` / ``indirect`` (``max_depth = bounces + 2``).
    component : {"total", "direct", "indirect"}
    seed : int
    """

    if component not in COMPONENTS:
        raise InvalidInputError(f"reference component '{component}'; accepted: {', '.join(COMPONENTS)}")
    if spp < 2 or bounces < 0 or (component == "indirect" and bounces < 1):
        raise InvalidInputError(f"reference spp={spp}, bounces={bounces} for '{component}'; "
                                "accepted: spp >= 2, bounces >= 0 (>= 1 for indirect)")
    select_variant()
    import mitsuba as mi

    key = content_key("ddprt-reference", VERSION, scene.content_hash(), light_spec(light), view,
                      width, height, spp, bounces, component, seed, mi.__version__)
    path = cache_root() / "ddprt-references" / f"{key}.exr"
    if use_cache and path.is_file():
        try:
            meta = read_exr_metadata(path)
            image = read_exr(path)
            if image.shape == (height, width, 3) and np.all(np.isfinite(image)):
                return LightReference(image, int(meta["spp"]), float(meta["noise_rmse"]),
                                      component, bounces, path, float(meta["seconds"]), True)
        except Exception:  # noqa: BLE001 - a corrupt cache entry is re-rendered
            pass
        path.unlink(missing_ok=True)
    start = time.perf_counter()
    depths = {"total": [bounces + 2], "direct": [2], "indirect": [bounces + 2, 2]}[component]
    scenes = [mi.load_dict(scene_dict(scene, light, view, width=width, height=height,
                                      max_depth=d)) for d in depths]
    spp_a = spp // 2
    spp_b = spp - spp_a
    halves = []
    for half, count in ((0, spp_a), (1, spp_b)):
        images = _render(scenes, width=width, height=height, spp=count, seed=seed, half=half)
        rgb = images[0][..., :3] - (images[1][..., :3] if len(images) > 1 else 0.0)
        halves.append((rgb, images[0][..., 3]))
    image = (halves[0][0] * spp_a + halves[1][0] * spp_b) / spp
    mask = (halves[0][1] + halves[1][1]) > 0
    diff = (halves[0][0] - halves[1][0])[mask]
    noise = float(np.sqrt(np.mean(diff * diff)) * math.sqrt(spp_a * spp_b) / spp) if mask.any() else 0.0
    seconds = time.perf_counter() - start
    image = image.astype(np.float32)
    if use_cache:
        write_exr(path, image, metadata={"spp": str(spp), "noise_rmse": repr(noise),
                                         "seconds": repr(seconds), "component": component,
                                         "bounces": str(bounces), "scene": scene.name})
    return LightReference(image, spp, noise, component, bounces, path, seconds)
