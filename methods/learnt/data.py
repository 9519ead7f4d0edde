"""Training and held-out data of the learnt transfer (thesis §4.1.2–4.1.3).

Training points are drawn area-uniformly with Turk's square-root method and kept off vertices
and edges (``prtbench.scene.geometry.sample_surface`` with a minimum barycentric coordinate); their
transfer T_i(p) = ∫ Y_i V max(n·ω, 0) dω comes from the core precompute
(``prtbench.transport.transfer.compute_transfer``), tracing against the whole scene. The held-out set is
the mesh vertices, which the margin keeps out of the training set (the thesis's test set).

Transfer depends on geometry only, so both sets are cached by a hash of positions, faces and
normals: the diffuse and glossy variants of a scene share them (and share trained networks).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from prtbench.api.cache import cached_arrays, content_key
from prtbench.api.errors import InvalidInputError
from prtbench.scene.geometry import sample_surface
from prtbench.transport import transfer
from prtbench.transport.transfer import compute_transfer

#: Bump when the sampling or the held-out selection changes.
DATA_VERSION = 1


@dataclass(frozen=True)
class TransferSamples:
    """Surface points with their transfer vectors.

    Attributes
    ----------
    points, normals : ndarray, shape (N, 3), float32
        World positions and unit normals.
    transfer : ndarray, shape (N, n²), float32
    object_ids : ndarray, shape (N,), int32
        Index into ``scene.objects`` of each point.
    """

    points: np.ndarray
    normals: np.ndarray
    transfer: np.ndarray
    object_ids: np.ndarray

    def __len__(self) -> int:
        return len(self.points)

    def subset(self, rows: np.ndarray) -> "TransferSamples":
        """The samples at ``rows`` (indices or a boolean mask)."""
        return TransferSamples(self.points[rows], self.normals[rows], self.transfer[rows],
                               self.object_ids[rows])


def geometry_key(scene) -> str:
    """Hash of what transfer depends on: object names, positions, faces, normals (no materials)
    and the version of the core transfer code, so a fix there retires cached training data."""
    return content_key("learnt-geometry", transfer.TRANSFER_VERSION,
                       [[o.name, o.mesh.positions, o.mesh.faces, o.mesh.normals]
                        for o in scene.objects])


def check_finite(what: str, *arrays: np.ndarray) -> None:
    """Raise InvalidInputError if any row of ``arrays`` holds NaN/Inf (names the count)."""
    bad = np.zeros(len(arrays[0]), dtype=bool)
    for a in arrays:
        a = np.asarray(a)
        bad |= ~np.all(np.isfinite(a.reshape(len(a), -1)), axis=1)
    if bad.any():
        raise InvalidInputError(
            f"{what}: {int(bad.sum())} of {len(bad)} rows contain NaN/Inf (first row "
            f"{int(np.argmax(bad))}); accepted: finite inputs and targets only")


def object_counts(scene, samples: int, balance: float) -> np.ndarray:
    """Samples per object: shares ∝ area^(1 − balance), rounded to sum to ``samples``.

    ``balance`` = 0 is area-uniform over the whole scene (the thesis); 1 gives every object the
    same count. Within an object, points stay area-uniform.
    """
    areas = np.array([o.mesh.triangle_areas().sum() for o in scene.objects], np.float64)
    weights = np.where(areas > 0, areas, 0.0) ** (1.0 - balance)
    share = weights / weights.sum() * samples
    counts = np.floor(share).astype(np.int64)
    # Largest remainders get the leftover samples (deterministic).
    counts[np.argsort(counts - share)[:samples - counts.sum()]] += 1
    return counts


def _draw(scene, samples: int, *, seed: int, vertex_margin: float, balance: float):
    """Turk samples: whole-scene area-uniform (balance 0) or per-object counts."""

    if balance == 0:
        drawn = sample_surface(scene, samples, seed=seed, min_barycentric=vertex_margin)
        return drawn.points, drawn.normals, drawn.object_ids
    points, normals, ids = [], [], []
    counts = object_counts(scene, samples, balance)
    for index, (obj, count) in enumerate(zip(scene.objects, counts)):
        if count == 0:
            continue
        drawn = sample_surface(obj.mesh, int(count), seed=[seed, index],
                               min_barycentric=vertex_margin)
        points.append(drawn.points)
        normals.append(drawn.normals)
        ids.append(np.full(int(count), index, np.int64))
    return np.concatenate(points), np.concatenate(normals), np.concatenate(ids)


def training_samples(scene, *, samples: int, rays_per_point: int, bands: int, seed: int,
                     vertex_margin: float, object_balance: float = 0.0,
                     progress: bool = True, visibility: bool = True) -> TransferSamples:
    """Turk samples of the whole scene with their transfer (cached by geometry).

    Parameters
    ----------
    scene : Scene
    samples : int
        Number of points N.
    rays_per_point : int
    bands : int
        SH bands n (transfer has n² coefficients).
    seed : int
    vertex_margin : float
        Minimum barycentric coordinate (keeps points off vertices and edges).
    object_balance : float
        0: area-uniform over the scene; > 0: per-object counts, see :func:`object_counts`.
    progress : bool
    visibility : bool
        Trace occlusion (default); ``False``: unshadowed transfer (V = 1).

    Returns
    -------
    TransferSamples
    """
    parts = [DATA_VERSION, geometry_key(scene), samples, rays_per_point, bands, seed,
             vertex_margin]
    if object_balance:  # keeps the keys of area-uniform data sets unchanged
        parts.append(object_balance)
    if not visibility:  # likewise for shadowed data sets
        parts.append("unshadowed")
    key = content_key("learnt-train", *parts)

    def compute() -> dict[str, np.ndarray]:
        points, normals, ids = _draw(scene, samples, seed=seed, vertex_margin=vertex_margin,
                                     balance=object_balance)
        transfer = compute_transfer(scene, points, normals, bands=bands,
                                    rays_per_point=rays_per_point, seed=seed, progress=progress,
                                    use_cache=False, visibility=visibility)
        return {"points": points.astype(np.float32), "normals": normals.astype(np.float32),
                "transfer": np.asarray(transfer, np.float32),
                "object_ids": ids.astype(np.int32)}

    arrays = cached_arrays("learnt-data", key, compute)
    return TransferSamples(arrays["points"], arrays["normals"], arrays["transfer"],
                           arrays["object_ids"])


def heldout_samples(scene, *, max_vertices: int, rays_per_point: int, bands: int, seed: int,
                    progress: bool = True, visibility: bool = True) -> TransferSamples:
    """Transfer at mesh vertices (a seeded subset of at most ``max_vertices``), cached.

    Vertices are never training points (those keep a barycentric margin), so the error here
    measures how well the network interpolates the surface rather than how it memorises.
    """
    key = content_key("learnt-heldout", DATA_VERSION, geometry_key(scene), max_vertices,
                      rays_per_point, bands, seed, *(() if visibility else ("unshadowed",)))

    def compute() -> dict[str, np.ndarray]:
        positions, normals, _, _ = scene.merged()
        object_ids = np.concatenate([np.full(o.mesh.n_vertices, i, np.int32)
                                     for i, o in enumerate(scene.objects)])
        rows = np.arange(len(positions))
        if len(rows) > max_vertices:
            rng = np.random.default_rng([seed, 0x484F])  # stream tag "HO"
            rows = np.sort(rng.choice(len(rows), size=max_vertices, replace=False))
        transfer = compute_transfer(scene, positions[rows], normals[rows], bands=bands,
                                    rays_per_point=rays_per_point, seed=seed + 7919,
                                    progress=progress, use_cache=False, visibility=visibility)
        return {"points": positions[rows].astype(np.float32),
                "normals": normals[rows].astype(np.float32),
                "transfer": np.asarray(transfer, np.float32), "object_ids": object_ids[rows]}

    arrays = cached_arrays("learnt-data", key, compute)
    return TransferSamples(arrays["points"], arrays["normals"], arrays["transfer"],
                           arrays["object_ids"])
