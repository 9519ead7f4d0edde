"""The data-driven method's dataset: direct vectors and indirect lightmaps of random lights.

For each of N lighting configurations of the chosen family (:func:`lights.sample_family`):

* the direct vector x_k is rendered by the runtime's own fake G-buffer pass (GL deferred
  shading with shadow maps), exactly as at run time (paper §4.1: "the runtime renderer for
  direct illumination");
* the indirect lightmap y_k is path traced in texture space by :func:`bake.bake_indirect`.

The dataset depends on fewer knobs than the artifact (not on the basis count, ridge λ, gamma or
layout), so it is cached separately and sweeps over those knobs bake once. Its original wall
time is stored with it (``bake_seconds``: the paper's "bake time").
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from tqdm import tqdm

from methods.data_driven.bake import bake_indirect, object_albedo
from methods.data_driven.families import sample_family
from methods.data_driven.lightmap import Lightmap, build_lightmap
from methods.data_driven.measurement import MeasurementPoints, measurement_points
from methods.data_driven.runtime import DirectLighting, FakeGBuffer
from prtbench.api.cache import cached_arrays, content_key
from prtbench.api.config import to_dict
from prtbench.render import gl
from prtbench.transport.lights import get_light
from prtbench.transport.parallel import map_chunks
from prtbench.transport.raytrace import Tracer

#: Bump when the dataset for the same knobs changes.
DATASET_VERSION = 4

#: Config fields the dataset depends on.
DATASET_KNOBS = ("light_family", "environment", "configurations", "measurement_points",
                 "placement", "supersample", "lightmap_resolution", "lightmap_padding",
                 "paths_per_texel", "env_samples", "bounces", "env_lights", "shadow_resolution",
                 "env_shadow_resolution", "light_region", "light_intensity", "seed")


@dataclass(frozen=True, eq=False)
class Dataset:
    """Direct vectors, indirect lightmaps and what produced them.

    Attributes
    ----------
    direct : ndarray, shape (N, P, 3), float32
    indirect : ndarray, shape (N, T, 3), float32
        Indirect outgoing radiance at the covered texels of ``lightmap``.
    points : MeasurementPoints
    lightmap : Lightmap
    lights : list
        The N lighting configurations.
    bake_seconds, direct_seconds, indirect_seconds : float
        Wall time of the original computation (also on cache hits).
    cache_hit : bool
    """

    direct: np.ndarray
    indirect: np.ndarray
    points: MeasurementPoints
    lightmap: Lightmap
    lights: list
    bake_seconds: float
    direct_seconds: float
    indirect_seconds: float
    cache_hit: bool


def family_environment(scene: Any, config: Any):
    """The environment map an ``env-rotations`` family rotates (None for other families)."""
    if config.light_family != "env-rotations":
        return None

    return get_light(config.environment or scene.default_light)


def family_lights(scene: Any, config: Any, count: int, *, seed_offset: int = 0) -> list:
    """``count`` configurations of the config's family (``seed_offset`` gives held-out sets).

    Lights placed ``inside`` the scene are anchored on the measurement points.
    """
    anchors = None
    if config.light_family in ("spot", "point"):
        points = scene_points(scene, config)
        anchors = (points.points[:, 0], points.normals[:, 0])
    return sample_family(scene, config.light_family, count, seed=config.seed + seed_offset,
                         environment=family_environment(scene, config),
                         region=config.light_region, intensity=config.light_intensity,
                         anchors=anchors)


def scene_points(scene: Any, config: Any) -> MeasurementPoints:
    return measurement_points(scene, config.measurement_points, placement=config.placement,
                              supersample=config.supersample, seed=config.seed)


class DirectRenderer:
    """The runtime's direct-light passes without a basis: measures x for any light."""

    def __init__(self, scene: Any, points: MeasurementPoints, config: Any):
        ctx = gl.create_context()
        positions, _, faces, _ = scene.merged()
        lo, hi = scene.bounds()
        self.lighting = DirectLighting(ctx, positions, faces, lo=lo, hi=hi,
                                       shadow_resolution=config.shadow_resolution,
                                       env_shadow_resolution=config.env_shadow_resolution,
                                       env_lights=config.env_lights)
        self.gbuffer = FakeGBuffer(ctx, points.points, points.normals, points.albedo)

    def __call__(self, light: Any) -> np.ndarray:
        self.lighting.set_light(light)
        self.lighting.render_shadows()
        self.gbuffer.run(self.lighting)
        return self.gbuffer.read()

    def release(self) -> None:
        self.lighting.release()
        self.gbuffer.release()


def measure_direct(scene: Any, points: MeasurementPoints, config: Any, lights: list) -> np.ndarray:
    """(len(lights), P, 3) direct vectors from the runtime's fake G-buffer pass."""
    renderer = DirectRenderer(scene, points, config)
    try:
        return np.stack([renderer(light) for light in lights]) if lights else \
            np.zeros((0, len(points), 3), np.float32)
    finally:
        renderer.release()


def bake_lightmaps(scene: Any, lightmap: Lightmap, lights: list, *, bounces: int, paths: int,
                   env_samples: int, seed: int, progress: bool = False) -> np.ndarray:
    """(len(lights), T, 3) path-traced indirect lightmaps (covered texels)."""

    tracer = Tracer.from_scene(scene)
    albedo = object_albedo(scene, tracer)
    out = np.zeros((len(lights), len(lightmap), 3), np.float32)

    def bake(k: int) -> np.ndarray:
        return bake_indirect(tracer, albedo, lightmap.points, lightmap.normals, lightmap.albedo,
                             lights[k], bounces=bounces, paths=paths, env_samples=env_samples,
                             seed=seed * 100_003 + k)

    # Lights on the precompute threads (each light has its own seed: same bits on any count).
    with tqdm(total=len(lights), desc=f"ddprt bake {scene.name}", unit="light", leave=False,
              disable=not progress) as bar:
        for k, lightmap_k in enumerate(map_chunks(bake, range(len(lights)))):
            out[k] = lightmap_k
            bar.update(1)
    return out


def dataset_key(scene: Any, config: Any) -> str:
    knobs = {k: v for k, v in to_dict(config).items() if k in DATASET_KNOBS}
    env = family_environment(scene, config)
    return content_key("ddprt-dataset", DATASET_VERSION, scene.content_hash(), knobs,
                       env.content_hash() if env is not None else None)


def build_dataset(scene: Any, config: Any, *, progress: bool = False,
                  use_cache: bool = True) -> Dataset:
    """The (cached) dataset of ``config`` on ``scene``."""
    lightmap = build_lightmap(scene, resolution=config.lightmap_resolution,
                              padding=config.lightmap_padding)
    points = scene_points(scene, config)
    lights = family_lights(scene, config, config.configurations)
    computed = {}

    def compute() -> dict[str, np.ndarray]:
        start = time.perf_counter()
        direct = measure_direct(scene, points, config, lights)
        mid = time.perf_counter()
        indirect = bake_lightmaps(scene, lightmap, lights, bounces=config.bounces,
                                  paths=config.paths_per_texel, env_samples=config.env_samples,
                                  seed=config.seed, progress=progress)
        end = time.perf_counter()
        computed["yes"] = True
        return {"direct": direct.astype(np.float32), "indirect": indirect,
                "seconds": np.array([end - start, mid - start, end - mid])}

    arrays = cached_arrays("ddprt-dataset", dataset_key(scene, config), compute,
                           use_cache=use_cache)
    seconds = arrays["seconds"]
    return Dataset(arrays["direct"], arrays["indirect"], points, lightmap, lights,
                   float(seconds[0]), float(seconds[1]), float(seconds[2]), not computed)
