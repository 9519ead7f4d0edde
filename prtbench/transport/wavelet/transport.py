"""Shadowed diffuse transport of surface points on a cubemap, in Haar, truncated per point.

For a point p with normal n and every texel t of a 6×N×N cubemap (Ng 2003, diffuse case)::

    T_t(p) = ∫_texel V(p, ω) max(n·ω, 0) dω  ≈  Σ_s w_s V(p, ω_s) max(n·ω_s, 0)

over S×S midpoint subsamples ω_s of the texel with area-element weights w_s summing to the
texel's exact solid angle (:func:`prtbench.transport.wavelet.cubemap.subsample_pattern`; S = 1 is one ray
through the texel centre, weighted by its solid angle). The solid angles live here, in the
transport (:mod:`prtbench.transport.wavelet`), so with the light's texel-mean radiance L_t the diffuse
radiance is B = kd/π · Σ_t T_t L_t = kd/π · Σ_i T̂_i L̂_i in Haar.

One occlusion ray per subsample with n·ω > 0 goes through embree (others contribute 0 and are
not traced), from the origin offset of :func:`prtbench.transport.raytrace.offset_origins`. Chunks of
points (rays, trace, Haar, truncation) run on the precompute threads; each chunk depends only
on its points, so every thread count gives the same bits.

Per point the ``keep`` largest-magnitude Haar coefficients are kept (exact zeros, e.g. of the
hemisphere below the surface, are never stored): the non-linear approximation of the
transport, which Ng 2003 also quantises (:mod:`prtbench.transport.wavelet.sparse`).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from tqdm import tqdm

from prtbench.api.cache import cached_arrays, content_key
from prtbench.api.errors import InvalidInputError
from prtbench.transport.parallel import map_chunks, parallel_chunks
from prtbench.transport.raytrace import Tracer, offset_origins
from prtbench.transport.wavelet import haar
from prtbench.transport.wavelet.cubemap import check_resolution, subsample_pattern
from prtbench.transport.wavelet.sparse import STORAGE_DTYPES, SparseTransport, as_float16

if TYPE_CHECKING:
    from prtbench.scene.model import Scene

#: Bump when the transport estimator changes (part of cache keys).
TRANSPORT_VERSION = 1

#: Candidate rays (before the n·ω > 0 cull) per chunk: bounds a chunk's memory (~50 bytes per
#: traced ray, two chunks per thread in flight) and balances the threads.
MAX_RAYS_PER_CHUNK = 1 << 19


def cosines(normals: np.ndarray, dirs_t: np.ndarray) -> np.ndarray:
    """(P, R) float32 n·ω of normals (P, 3) float32 and directions ``dirs_t`` (3, R) float32.

    Three broadcast multiply-adds: a (P, 3) @ (3, R) product with an inner size of 3 is ~15×
    slower through BLAS. The ray set traced is exactly where this is > 0.
    """
    out = normals[:, 0:1] * dirs_t[0]
    term = normals[:, 1:2] * dirs_t[1]
    out += term
    np.multiply(normals[:, 2:3], dirs_t[2], out=term)  # the same products, one temporary
    out += term
    return out


def keep_count(keep: float, n_coeffs: int) -> int:
    """Coefficients kept per point: ``keep`` in (0, 1] is a fraction of ``n_coeffs`` (at least
    one), ``keep`` > 1 an integer count (at most ``n_coeffs``)."""
    if not keep > 0:
        raise InvalidInputError(f"keep={keep!r}; accepted: a fraction in (0, 1] or an integer "
                                f"count 2..{n_coeffs}")
    if keep <= 1.0:
        return max(1, int(round(keep * n_coeffs)))
    if float(keep) != int(keep) or keep > n_coeffs:
        raise InvalidInputError(f"keep={keep!r}; accepted: a fraction in (0, 1] or an integer "
                                f"count 2..{n_coeffs} (6·N² coefficients per point)")
    return int(keep)


#: A float32 3-vector padded to 16 bytes, as one opaque record: numpy's ``repeat`` copies a
#: 16-byte item with one move, a 12-byte one by ``memcpy`` (~8× slower), and embree reads the
#: padded rows in place (:func:`_vectors`).
_VEC4 = np.dtype((np.void, 16))


def _records(vectors: np.ndarray) -> np.ndarray:
    """(R,) 16-byte records holding float32 vectors (R, 3), zero-padded."""
    padded = np.zeros((len(vectors), 4), dtype=np.float32)
    padded[:, :3] = vectors
    return padded.view(_VEC4).reshape(-1)


def _vectors(records: np.ndarray) -> np.ndarray:
    """(R, 3) float32 view (row stride 16 bytes) of (R,) records from :func:`_records`."""
    return records.view(np.float32).reshape(-1, 4)[:, :3]


def _negated_magnitude_keys(c: np.ndarray) -> np.ndarray:
    """(P, M) int32 keys ordered like −|c| for finite float32 ``c``: minus the bits of |c|.

    The bits of a non-negative finite float32, read as an integer, increase with its value,
    so the keys sort exactly as −|c| does (±0 both give 0), and numpy partitions int32 rows
    ~1.5× faster than float32 ones.
    """
    keys = c.view(np.int32) & np.int32(0x7FFF_FFFF)
    np.negative(keys, out=keys)
    return keys


def row_counts(mask: np.ndarray) -> np.ndarray:
    """(P,) int64 true entries of each row of a (P, M) bool ``mask``.

    ``np.count_nonzero(mask, axis=1)``, ~3× faster on C-contiguous rows of a multiple of 8
    bytes: each 8-byte word of 0/1 bytes times 0x0101…01 holds its byte sum in its top byte.
    """
    if mask.ndim != 2 or mask.shape[1] % 8 or not mask.flags.c_contiguous:
        return np.count_nonzero(mask, axis=1).astype(np.int64)
    words = mask.view(np.uint64)
    words = words * np.uint64(0x0101_0101_0101_0101)
    words >>= np.uint64(56)
    return words.sum(axis=1, dtype=np.int64)


def truncate(c: np.ndarray, k: int) -> np.ndarray:
    """Entries kept of each row: its nonzero coefficients among its ``k`` largest in magnitude.

    Exactly the entries that ``argpartition`` of −|c| at ``k − 1``, row by row, puts first,
    less the zeros. A row with at most ``k`` nonzero coefficients keeps all of them, whatever
    order a partition would put its zeros in. In the other rows, the values at most the k-th
    smallest −|c| (one ``partition``, cheaper than ``argpartition``) are the kept set whenever
    there are exactly k of them; only rows with equal magnitudes straddling the cut are
    partitioned by index, each on its own (which of the equal ones ``argpartition`` keeps
    depends only on the row). Finite float32 rows are cut on integer keys
    (:func:`_negated_magnitude_keys`), the same order.

    Parameters
    ----------
    c : ndarray, shape (P, M)
        Finite values.
    k : int

    Returns
    -------
    ndarray, shape (P, M), bool
    """
    keep = c != 0
    if k >= c.shape[1]:
        return keep
    over = row_counts(keep) > k
    if not over.any():
        return keep
    every = bool(over.all())  # the usual case: no row gathered, none scattered back
    full = None if every else np.flatnonzero(over)
    rows = c if every else c[full]
    if rows.dtype == np.float32:
        magnitude = _negated_magnitude_keys(np.ascontiguousarray(rows))
    else:
        magnitude = np.abs(rows)
        np.negative(magnitude, out=magnitude)
    cut = np.partition(magnitude, k - 1, axis=1)[:, k - 1:k]  # −(k-th largest |c|) < 0
    # More than k nonzeros: the k-th largest |c| is > 0, so every chosen entry is nonzero.
    chosen = magnitude <= cut
    tied = np.flatnonzero(row_counts(chosen) != k)
    if len(tied):  # argpartition's own pick among the equal ones, on the values themselves
        negated = np.abs(rows[tied])
        np.negative(negated, out=negated)
        top = np.argpartition(negated, k - 1, axis=1)[:, :k]
        redo = np.zeros((len(tied), c.shape[1]), dtype=bool)
        np.put_along_axis(redo, top, True, axis=1)
        chosen[tied] = redo
    if every:
        return chosen
    keep[full] = chosen
    return keep


def _entries(c: np.ndarray, keep: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The kept entries of ``c`` (P, M), row by row, as compressed sparse rows.

    Returns
    -------
    counts : ndarray, shape (P,), int64
        Entries of each row.
    cols : ndarray, shape (nnz,), int32
    values : ndarray, shape (nnz,), ``c``'s dtype
    """
    counts = row_counts(keep)
    flat = np.flatnonzero(keep)
    cols = flat.astype(np.int32)
    cols -= np.repeat(np.arange(0, len(c) * c.shape[1], c.shape[1], dtype=np.int32), counts)
    return counts, cols, c.reshape(-1).take(flat)


def compute_wavelet_transport(scene: "Scene", points: np.ndarray, normals: np.ndarray, *,
                              n: int, keep: float = 1.0, texel_samples: int = 1,
                              storage: str = "float32", visibility: bool = True,
                              progress: bool = True, tracer: Tracer | None = None,
                              cosine: bool = True,
                              lobes: Callable[[slice, np.ndarray], np.ndarray] | None = None,
                              n_lobes: int = 1,
                              ) -> tuple[SparseTransport, dict[str, float]]:
    """Per-point Haar transport, truncated to ``keep`` coefficients and stored sparse.

    Parameters
    ----------
    scene : Scene
        Occluders (all objects).
    points, normals : ndarray, shape (P, 3)
        Surface points and normals (normalised here).
    n : int
        Cubemap face resolution N (a power of two).
    keep : float
        Fraction in (0, 1] or count of coefficients kept per point (:func:`keep_count`).
    texel_samples : int
        S: S×S rays per texel.
    storage : {"float32", "float16", "int8"}
        Stored value type.
    visibility : bool
        False sets V = 1 (the unshadowed transport: no ray is traced).
    progress : bool
        tqdm bar on stderr.
    tracer : Tracer, optional
        One already built for ``scene``.
    cosine : bool
        True (default): the transport V·max(n·ω, 0) with solid angles. False: the texel's
        visible fraction V_t alone (front-facing unoccluded subsamples / S², no cosine, no
        weight), the visibility factor of Ng 2004's triple product, whose
        BRDF factor carries the cosine and the solid angles.
    lobes : callable, optional
        ``lobes(sl, dirs_t) -> (c, n_lobes, R)`` float32 per-ray factors of the points ``sl``
        (c of them) for the ray directions ``dirs_t`` (3, R), texel-major: each lobe is its
        own transport row, ``V·max(n·ω, 0)·lobe(ω)`` (e.g. a BRDF term for a fixed view, as
        a fixed-view method does). The rays are traced once for all lobes.
    n_lobes : int
        Lobes ``lobes`` returns (1 without ``lobes``).

    Returns
    -------
    transport : SparseTransport
        P × 6N², or (P·n_lobes) × 6N² with ``lobes`` (row p·n_lobes + l: point p, lobe l).
    stats : dict
        ``rays`` traced, ``candidate_rays`` (before the cull), ``trace_s`` (seconds inside
        embree, summed over threads).
    """

    n = check_resolution(n)
    m = 6 * n * n
    k = keep_count(keep, m)
    if storage not in STORAGE_DTYPES:  # before any tracing, not after it
        raise InvalidInputError(f"storage '{storage}'; accepted: {', '.join(STORAGE_DTYPES)}")
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    nrm = np.asarray(normals, dtype=np.float64).reshape(-1, 3)
    if p.shape != nrm.shape:
        raise InvalidInputError(f"{len(p)} points but {len(nrm)} normals; accepted: one each")
    length = np.linalg.norm(nrm, axis=1, keepdims=True)
    if np.any(~np.isfinite(length)) or np.any(length < 1e-12):
        raise InvalidInputError("wavelet transport normals must be finite and non-zero")
    nrm = nrm / length
    dirs, weights = subsample_pattern(n, texel_samples)
    ss = weights.shape[-1]
    dirs32 = dirs.reshape(-1, 3).astype(np.float32)  # (M·S², 3), texel-major
    ray_weight = np.broadcast_to(weights, (6, *weights.shape)).reshape(-1).astype(np.float32)
    if visibility and tracer is None:
        tracer = Tracer.from_scene(scene)
    origins = (offset_origins(p, nrm, diagonal=tracer.diagonal).astype(np.float32)
               if visibility else None)
    per_point = len(dirs32)
    dirs_t = np.ascontiguousarray(dirs32.T)
    nrm32 = nrm.astype(np.float32)
    n_lobes = int(n_lobes) if lobes is not None else 1
    chunks = parallel_chunks(len(p), max(1, MAX_RAYS_PER_CHUNK // (per_point * n_lobes)))

    # Ray origins and directions as 12-byte records: whole rays are copied by one repeat / one
    # masked gather, several times faster than numpy's row-wise copies of (R, 3) arrays.
    origin_records = _records(origins) if visibility else None
    direction_records = (_records(np.tile(dirs32, (max(1, chunks[0].stop - chunks[0].start), 1)))
                         if visibility and chunks else None)

    def chunk(sl: slice):
        cos = cosines(nrm32[sl], dirs_t)  # (c, M·S²)
        visible = cos > 0
        traced, seconds = 0, 0.0
        if visibility:
            front = visible.reshape(-1)
            counts = row_counts(visible)
            ray_origins = np.repeat(origin_records[sl], counts)
            # compress, not a boolean index: the same records, ~3× faster on 16-byte items
            ray_dirs = direction_records[:len(front)].compress(front)
            traced = len(ray_dirs)
            start = time.perf_counter()
            blocked = tracer.occluded(_vectors(ray_origins), _vectors(ray_dirs))
            seconds = time.perf_counter() - start
            visible = np.zeros_like(front)
            visible[front] = ~blocked
            visible = visible.reshape(cos.shape)
        if cosine:
            cos *= visible  # in place: V·max(n·ω, 0) · w per ray, float32 like the rays
            cos *= ray_weight
        else:
            cos = visible.astype(np.float32)  # V per ray; / S² makes the texel mean below
            cos *= np.float32(1.0 / ss)
        if lobes is not None:  # one transport row per (point, lobe), the rays traced once
            cos = (cos[:, None, :] * lobes(sl, dirs_t)).reshape(-1, per_point)
        t = cos.reshape(len(cos), 6, n, n, ss)
        if ss > 1:  # texel integrals (solid angle folded in), accumulated in float64
            t = t.sum(axis=-1, dtype=np.float64)
        # float32 Haar: the values are stored at float32 or less (S > 1 sums stay float64).
        c = haar.forward(t.reshape(len(cos), 6, n, n), dtype=t.dtype).reshape(len(cos), m)
        counts, cols, vals = _entries(c, truncate(c, k))
        if storage == "float16":  # rounded here, on the threads (the same values, elementwise)
            vals = as_float16(vals)
        return counts, cols, vals, traced, seconds

    parts, stats = [], {"rays": 0, "candidate_rays": int(len(p) * per_point), "trace_s": 0.0}
    with tqdm(total=len(p), desc=f"wavelet transport {scene.name}", unit="pt", file=sys.stderr,
              disable=not progress, dynamic_ncols=True) as bar:
        for (counts, cols, vals, traced, seconds), sl in zip(map_chunks(chunk, chunks), chunks):
            parts.append((counts, cols, vals))
            stats["rays"] += traced
            stats["trace_s"] += seconds
            bar.update(sl.stop - sl.start)
    # Chunks come in point order: their rows, concatenated, are the transport's rows.
    counts, cols, vals = (np.concatenate([q[i] for q in parts]) if parts else np.zeros(0, dt)
                          for i, dt in enumerate((np.int64, np.int32, np.float32)))
    transport = SparseTransport.from_rows(counts, cols, vals, n_coeffs=m, storage=storage)
    return transport, stats


def cached_transport(name: str, *key_parts, scene: "Scene", points: np.ndarray,
                     normals: np.ndarray, config, progress: bool = True,
                     **transport_options) -> tuple[SparseTransport, int, float]:
    """:func:`compute_wavelet_transport` with ``config``'s knobs (cubemap, keep, texel_samples,
    storage, visibility), cached under ``content_key(name, TRANSPORT_VERSION, *key_parts)``.

    Every wavelet method keys its transport by its precompute knobs only, so render-time knobs
    reuse it. Returns the transport, its traced ray count and trace seconds (NaN for an entry
    cached before trace time was stored).
    """

    def compute() -> dict[str, np.ndarray]:
        transport, stats = compute_wavelet_transport(
            scene, points, normals, n=config.cubemap, keep=config.keep,
            texel_samples=config.texel_samples, storage=config.storage,
            visibility=config.visibility, progress=progress, **transport_options)
        return {**transport.arrays(), "rays": np.array(stats["rays"]),
                "trace_s": np.array(stats["trace_s"])}

    arrays = dict(cached_arrays("wavelet-transport",
                                content_key(name, TRANSPORT_VERSION, *key_parts), compute))
    rays = int(arrays.pop("rays"))
    trace_s = float(arrays.pop("trace_s")) if "trace_s" in arrays else float("nan")
    return SparseTransport.from_arrays(arrays), rays, trace_s
