"""The rays ``compute_transfer`` traces, for the benchmarks that time it against raw embree.

Shared by ``test_transfer_throughput.py`` (one thread) and ``test_transfer_threads.py`` (all
cores) so that both compare against exactly the same rays (seeded pattern, origin offset).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from prtbench.api.errors import PrtbenchError
from prtbench.scene.model import Scene
from prtbench.scene.registry import get_scene
from prtbench.transport.ray_pattern import RayPattern
from prtbench.transport.raytrace import Tracer, offset_origins


def benchmark_scene() -> Scene:
    """``plants`` (a real asset) where its asset is fetched, else ``sphere-over-plane``."""
    try:
        return get_scene("plants")
    except (PrtbenchError, ImportError):
        return get_scene("sphere-over-plane")


@dataclass
class TransferRays:
    """``n_points`` surface points of ``scene`` and the rays transfer traces from them.

    points, normals : (P, 3) float64; origins, directions : (P · rays_per_point, 3) float32.
    """

    scene: Scene
    tracer: Tracer
    points: np.ndarray
    normals: np.ndarray
    origins: np.ndarray
    directions: np.ndarray

    @property
    def n_rays(self) -> int:
        return len(self.origins)

    def raw_occluded(self, origins: np.ndarray | None = None,
                     directions: np.ndarray | None = None):
        """One bare embreex ``OCCLUDED`` call (all rays, or the given slice of them)."""
        return self.tracer._scene.run(self.origins if origins is None else origins,
                                      self.directions if directions is None else directions,
                                      query="OCCLUDED")


def transfer_rays(*, n_points: int, rays_per_point: int, seed: int = 0) -> TransferRays:
    scene = benchmark_scene()
    positions, normals, _, _ = scene.merged()
    pick = np.random.default_rng(seed).choice(len(positions), size=min(n_points, len(positions)),
                                              replace=False)
    points = positions[pick].astype(np.float64)
    normals = normals[pick].astype(np.float64)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    tracer = Tracer.from_scene(scene)
    # Exactly the rays compute_transfer traces (same seeded pattern and origin offset).
    pattern = RayPattern(len(points), rays_per_point, 0)
    everything = slice(0, len(points))
    directions = pattern.world_directions(pattern.frames(normals, everything),
                                          everything).reshape(-1, 3)
    origins = np.repeat(offset_origins(points, normals, diagonal=tracer.diagonal)
                        .astype(np.float32), rays_per_point, axis=0)
    return TransferRays(scene=scene, tracer=tracer, points=points, normals=normals,
                        origins=origins, directions=directions)
