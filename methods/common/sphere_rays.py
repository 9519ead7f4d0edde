"""Uniform sphere rays from points: visibility SH, back-face fractions and hit distances.

Shared by the probe volume (probes in space) and the lightmap (texels on surfaces). The
estimator is the irradiance volume's (:mod:`methods.irradiance_volume.method`): M area-uniform
directions from a Cranley–Patterson shifted Fibonacci lattice, turned by one uniformly random
rotation per point, so the SH are evaluated once in the pattern's frame and each point's sum is
rotated to the world frame (:class:`prtbench.transport.ray_pattern.ShRotation`)::

    V_i(p) = ∫ Y_i(ω) V(p, ω) dω ≈ √(4π)·δ_i0 − 4π/M Σ_j Y_i(ω_j) (1 − V(p, ω_j))

(the SH of the constant 1 exactly, less the occluded rays' projection: an unoccluded point's
visibility is exact, and only occlusion carries the lattice's quadrature error)

Surface points (``normals`` given) start their rays off the surface
(:func:`prtbench.transport.raytrace.offset_origins`) and count the directions below their
tangent plane as unoccluded without tracing them (see :func:`trace_sphere`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from tqdm import tqdm

from prtbench.transport.parallel import map_chunks, parallel_chunks
from prtbench.transport.ray_pattern import ShRotation, fibonacci_square
from prtbench.transport.raytrace import offset_origins
from prtbench.transport.sh import eval_sh

#: Rays per embree call while tracing (bounds the temporary arrays to ~100 MB).
RAYS_PER_CHUNK = 1 << 19

#: ``per_ray(sl, directions, distances, backface) -> {name: (k, ...) array}`` (see trace_sphere).
PerRay = Callable[[slice, np.ndarray, np.ndarray, np.ndarray], dict]


def sphere_pattern(rays: int, rng: np.random.Generator) -> np.ndarray:
    """``rays`` area-uniform stratified unit directions (M, 3): a shifted Fibonacci lattice."""
    u = fibonacci_square(rays, shift=rng.random(2))
    z = 1.0 - 2.0 * u[:, 0]
    r = np.sqrt(np.maximum(1.0 - z * z, 0.0))
    phi = 2.0 * np.pi * u[:, 1]
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def random_rotations(count: int, rng: np.random.Generator) -> np.ndarray:
    """``count`` uniformly distributed rotation matrices (count, 3, 3) (unit quaternions from
    normalised 4D Gaussians)."""
    q = rng.standard_normal((count, 4))
    w, x, y, z = (q / np.linalg.norm(q, axis=1, keepdims=True)).T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], axis=1)


@dataclass(frozen=True, eq=False)
class SphereRays:
    """What the rays of every point found.

    Attributes
    ----------
    visibility : ndarray, shape (P, n²), float64
        SH of the binary visibility over the sphere.
    backface_fraction : ndarray, shape (P,), float64
        Fraction of a point's rays whose first hit is the back of a triangle (0 for surface
        points traced for occlusion only).
    reduced : dict of str to ndarray, shape (P, ...)
        What ``per_ray`` returned for every point (empty without it).
    """

    visibility: np.ndarray
    backface_fraction: np.ndarray
    reduced: dict = field(default_factory=dict)


def trace_sphere(tracer, positions: np.ndarray, *, bands: int, rays: int, seed: int,
                 stream: int, normals: np.ndarray | None = None, occlusion: bool = True,
                 per_ray: PerRay | None = None, progress: bool = False,
                 desc: str = "sphere rays") -> SphereRays:
    """Trace ``rays`` uniform sphere directions from every point.

    Parameters
    ----------
    tracer : prtbench.transport.raytrace.Tracer
    positions : ndarray, shape (P, 3)
    bands : int
        SH bands of the visibility.
    rays : int
    seed, stream : int
        The pattern's shift and the per-point rotations come from ``default_rng([seed, stream])``:
        each caller names its own stream.
    normals : ndarray, shape (P, 3), optional
        Surface points: rays start off the surface along the normal, and directions below the
        tangent plane count as unoccluded without being traced. The cosine of any receiver
        oriented near the normal removes them again, so they only extend the light beyond the
        horizon smoothly instead of cutting it there (a cut would ring in a few SH bands).
    occlusion : bool
        Trace rays (default); ``False`` counts every ray as escaping (nothing is traced).
    per_ray : callable, optional
        ``per_ray(sl, directions, distances, backface)`` with the rays of the points in ``sl``
        (world directions (k, M, 3), first-hit distances (k, M), ``inf`` on escape, back-face
        flags (k, M)) returns a dict of per-point arrays (k, ...), gathered into
        :attr:`SphereRays.reduced`: what a caller needs of every ray without holding all rays
        of all points at once. Given, rays are traced for their first hit even from surface
        points.
    progress : bool
    desc : str
        The progress bar's label.

    Returns
    -------
    SphereRays
    """
    p = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    m = int(rays)
    rng = np.random.default_rng([int(seed), int(stream)])
    local = sphere_pattern(m, rng)
    world_from_local = random_rotations(len(p), rng)
    y_local = eval_sh(local, bands) * (4.0 * np.pi / m)
    rotate = ShRotation.for_bands(bands)
    surface = normals is not None
    if surface:
        n = np.asarray(normals, np.float64).reshape(-1, 3)
        origins_all = offset_origins(p, n, diagonal=tracer.diagonal)
    else:
        origins_all = p
    first_hits = per_ray is not None or not surface
    face_normal = None
    if first_hits:
        corners = tracer.positions.astype(np.float64)[tracer.faces]
        face_normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    visibility = np.zeros((len(p), bands * bands))
    backface = np.zeros(len(p))
    reduced: dict[str, np.ndarray] = {}

    def chunk(sl: slice):
        """(visibility SH, back-face fraction, per_ray's arrays or None) of the points in sl."""
        dirs = np.einsum("pij,mj->pmi", world_from_local[sl], local)  # (k, M, 3)
        k = len(dirs)
        visible = np.ones((k, m), bool)
        distances = np.full((k, m), np.inf, np.float32)
        back = np.zeros((k, m), bool)
        if occlusion:
            traced = np.ones((k, m), bool)
            if surface:
                traced = np.einsum("pmi,pi->pm", dirs, n[sl]) > 0.0
            origins = np.broadcast_to(origins_all[sl][:, None, :], (k, m, 3))[traced]
            flat_dirs = dirs[traced]
            if not first_hits:  # surface points: occlusion only
                visible[traced] = ~tracer.occluded(origins, flat_dirs)
            else:
                hits = tracer.first_hit(origins, flat_dirs)
                hit = hits.face >= 0
                facing = np.zeros(len(hit), bool)
                facing[hit] = np.einsum("hj,hj->h", flat_dirs[hit],
                                        face_normal[hits.face[hit]]) > 0
                visible[traced] = ~hit
                distances[traced] = hits.t
                back[traced] = facing
        # V = 1 − O: the constant's SH is exact (√(4π) in coefficient 0), so only the occluded
        # rays carry the lattice's quadrature error, and an unoccluded point is exact.
        vis_sh = -rotate((~visible).astype(np.float64) @ y_local, world_from_local[sl])
        vis_sh[:, 0] += np.sqrt(4.0 * np.pi)
        extra = per_ray(sl, dirs, distances, back) if per_ray is not None else None
        return vis_sh, back.mean(axis=1), extra

    # Point chunks on the precompute threads (prtbench.transport.parallel); the rotations are drawn
    # for all points up front, so every thread count gives the same bits.
    chunks = parallel_chunks(len(p), max(1, RAYS_PER_CHUNK // m))
    with tqdm(total=len(p), desc=desc, unit="pt", disable=not progress) as bar:
        for (vis, back, extra), sl in zip(map_chunks(chunk, chunks), chunks):
            visibility[sl] = vis
            backface[sl] = back
            for name, values in (extra or {}).items():
                if name not in reduced:
                    reduced[name] = np.zeros((len(p),) + values.shape[1:], values.dtype)
                reduced[name][sl] = values
            bar.update(sl.stop - sl.start)
    return SphereRays(visibility, backface, reduced)
