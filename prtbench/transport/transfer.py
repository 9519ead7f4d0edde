"""Transfer precompute: points + normals -> SH transfer vectors (DESIGN.md §5, §8).

Shadowed diffuse transfer (Sloan et al. 2002), no albedo and no 1/π::

    T_i(p) = ∫ Y_i(ω) V(p, ω) max(n·ω, 0) dω         B(p) = kd(p)/π · Σ_i T_i L_i

Estimator. Rays are cosine-weighted about the normal, so T_i ≈ π/M Σ_j Y_i(ω_j) V(ω_j). The M
local directions come from a Fibonacci lattice in the unit square, Cranley–Patterson shifted at
random and mapped to the hemisphere by Malley's method (stratified, and unbiased over the
shift). There are 16 such independently shifted patterns; point i uses pattern i mod 16, spun
by its own random angle about the normal (all seeded and per point, so the rays depend neither
on chunking nor on the band count: fewer bands are a truncation of more, up to rounding).

Speed. Per-ray numpy work is what limits throughput (Embree traces a ray in ~0.1 µs), so SH are
never evaluated per ray. A point's M directions are a fixed local pattern rotated by its frame
R_p, so the visibility-weighted sum is formed in the local frame by one matrix product against
SH values evaluated once per pattern, c_p = π/M · Y_localᵀ v_p, and then rotated to the world
frame, T_p = D(R_p) c_p, with D built from ZYZ Euler angles (:class:`ShRotation`: O(n³) per
point, no trigonometry per ray). Both run in float32 (the sums in blocks of 256 rays added in
float64: ~2e-6 relative error at any M, see :func:`_local_sh_tables`). Chunks of points (rays,
trace, SH sums) run on the precompute threads of :mod:`prtbench.transport.parallel` (``PRTBENCH_THREADS``,
default all cores): embree releases the GIL, and since a chunk's rays depend only on its points
and the chunks only on the point and ray counts (:func:`point_chunks`), every thread count gives the
same bits. :func:`compute_transfer_with_stderr` evaluates SH per ray instead (it needs every
sample's square); both give the same transfer up to rounding.

Interreflected transfer (Sloan's bounces) is in :mod:`prtbench.transport.bounce_transfer`; the
ray pattern and the SH rotation in :mod:`prtbench.transport.ray_pattern`.
"""

from __future__ import annotations

import sys
import threading
from typing import TYPE_CHECKING

import numpy as np
from tqdm import tqdm

from prtbench.api.cache import cached_arrays, content_key
from prtbench.api.errors import InvalidInputError
from prtbench.transport.parallel import (
    Scratch,
    map_chunks,
    parallel_chunks,
    repeat_rows,
    single_threaded_blas,
)
from prtbench.transport.ray_pattern import RayPattern, ShRotation
from prtbench.transport.raytrace import Tracer, offset_origins
from prtbench.transport.sh import eval_sh, eval_sh_coefficient_major

if TYPE_CHECKING:
    from prtbench.scene.model import Scene

#: Bump when the estimator changes: it is part of every transfer cache key.
TRANSFER_VERSION = 3  # 2: float32 SH products and rotation; 3: a shorter first chunk

#: Rays per chunk: bounds memory (~60 bytes per ray, two chunks per thread in flight) and keeps
#: chunks small enough to balance the threads. Fixed, so results never depend on threads.
MAX_RAYS_PER_CHUNK = 1 << 18

#: Size of the first default chunk relative to the others. Equal chunks keep the threads in
#: lockstep: all finish tracing together and then contend for the GIL in their numpy SH
#: sums (and wait for the one building the SH tables), leaving cores idle. A short first
#: chunk staggers them, so that one thread's sums run while the others trace (measured on 2
#: cores: the rotation 0.9 ms per chunk instead of 1.8, and the tables' wait gone).
LEAD_CHUNK_FRACTION = 0.5

#: Scratch budget (bytes) of one SH evaluation block.
_SCRATCH_BYTES = 32 << 20



# --- inputs -------------------------------------------------------------------------------------

def check_inputs(points: np.ndarray, normals: np.ndarray, bands: int,
                  rays_per_point: int) -> tuple[np.ndarray, np.ndarray]:
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3) if np.size(points) else np.zeros((0, 3))
    n = np.asarray(normals, dtype=np.float64).reshape(-1, 3) if np.size(normals) else np.zeros((0, 3))
    if p.shape != n.shape:
        raise InvalidInputError(
            f"{len(p)} points but {len(n)} normals; accepted: one normal per point")
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(n))):
        raise InvalidInputError("transfer points/normals contain NaN/Inf; accepted: finite values")
    length = np.linalg.norm(n, axis=1)
    if np.any(length < 1e-12):
        raise InvalidInputError(f"{int(np.sum(length < 1e-12))} zero-length normals; "
                                "accepted: non-zero normals")
    if int(bands) != bands or not 1 <= bands <= 64:
        raise InvalidInputError(f"sh bands={bands!r}; accepted: integers 1..64")
    if int(rays_per_point) != rays_per_point or rays_per_point < 1:
        raise InvalidInputError(f"rays_per_point={rays_per_point!r}; accepted: integers >= 1")
    return p, n / length[:, None]


def point_chunks(n_points: int, rays_per_point: int, chunk_points: int | None) -> list[slice]:
    """Consecutive point slices: ``chunk_points`` each, or by default ~:data:`MAX_RAYS_PER_CHUNK`
    rays each after a shorter first one (:data:`LEAD_CHUNK_FRACTION`; one chunk if all fit).

    The boundaries depend only on the point and ray counts, never on the thread count.
    """
    if chunk_points is not None:
        if int(chunk_points) != chunk_points or chunk_points < 1:
            raise InvalidInputError(f"chunk_points={chunk_points!r}; accepted: integers >= 1")
        return parallel_chunks(n_points, int(chunk_points))
    step = max(1, MAX_RAYS_PER_CHUNK // rays_per_point)
    if n_points <= step:  # one chunk: its rays are split over the threads by the tracer
        return parallel_chunks(n_points, step)
    lead = max(1, int(step * LEAD_CHUNK_FRACTION))
    return [slice(0, lead)] + [slice(s, min(s + step, n_points))
                               for s in range(lead, n_points, step)]


def progress_bar(total: int, desc: str, enabled: bool):
    return tqdm(total=total, desc=desc, unit="pt", file=sys.stderr, disable=not enabled,
                dynamic_ncols=True)


# --- shadowed transfer --------------------------------------------------------------------------

SUM_BLOCK = 256


def _project(visible: np.ndarray, local_sh: np.ndarray, sl: slice, scratch: Scratch, *,
             scale: float) -> np.ndarray:
    """``scale`` · Σ_j Y_i(ω_j) V_j per point in its local frame, coefficient-major.

    One (rows × K) @ (K × n²) product per pattern and block of K rays, over the points using
    the pattern, all in one stacked matmul call; the blocks' partial sums are added in
    float64 (see :func:`_local_sh_tables`). Point ``sl.start + i`` uses pattern
    ``(sl.start + i) % P``; a chunk that does not start at pattern 0 or hold whole rounds of
    patterns (a ragged last chunk, or a caller's ``chunk_points``) is padded with
    zero-visibility rows to whole rounds, and the rays to whole blocks, so that every chunk
    takes one stacked product (in float32 a separate per-pattern loop rounded ~0.5 % of the
    coefficients differently). The bits can still depend on the chunk's size: OpenBLAS sums
    small products (M·N·K up to about 10⁶ on AVX-512 machines) in another kernel, in another
    order. The chunking depends only on the point and ray counts, never on the threads. The
    scaling writes the sums straight into the (n², n) layout
    :meth:`ShRotation.rotate_columns` works in (no separate transpose copy).

    Parameters
    ----------
    visible : ndarray, shape (n, M), bool
        Visibility of the rays of the points in ``sl``.
    local_sh : ndarray, shape (P, B, K, n²), float32 or float64
        SH of each pattern's local directions in B blocks of K (zero past M); the products
        run in its precision (the weights are 0/1, exact in either).

    Returns
    -------
    ndarray, shape (n², n), ``local_sh``'s dtype, C-contiguous (a new array)
    """
    n, m = visible.shape
    p, blocks, k, n2 = local_sh.shape
    lead = sl.start % p  # padding rows before the chunk's first point
    # At least 2 rows: with 1, numpy calls BLAS gemv, whose float32 sums round differently.
    rows = max(2, -(-(lead + n) // p))
    whole_rows = lead == 0 and n == rows * p  # every default-size chunk
    source = visible
    if not (whole_rows and m == blocks * k):
        source = np.zeros((rows * p, blocks * k), dtype=bool)
        source[lead:lead + n, :m] = visible
    weights = scratch.get("weights", (p, blocks, rows, k), local_sh.dtype)
    # [pattern, block, r] = padded point r·p + pattern, rays of that block
    np.copyto(weights, source.reshape(rows, p, blocks, k).transpose(1, 2, 0, 3))
    products = np.matmul(weights, local_sh, out=scratch.get("products", (p, blocks, rows, n2),
                                                            local_sh.dtype))
    sums = products[:, 0] if blocks == 1 else products.sum(axis=1, dtype=np.float64)
    # padded point r·p + k is sums[k, r]: (n², rows, p) is local_t's own memory order.
    local_t = np.empty((n2, rows * p), dtype=local_sh.dtype)
    np.multiply(sums.transpose(2, 1, 0), scale, out=local_t.reshape(n2, rows, p),
                casting="same_kind")
    if whole_rows:
        return local_t
    return np.ascontiguousarray(local_t[:, lead:lead + n])


def _local_sh_tables(pattern: RayPattern, bands: int) -> np.ndarray:
    """(P, B, K, n²) SH of each pattern's local directions, in blocks for :func:`_project`.

    float32 products (and rotation): twice the BLAS rate on the largest per-ray cost at high
    bands and half the memory traffic. A float32 sum of M rays rounds by up to ~M·2⁻²⁴
    (measured 2.5e-5 relative at M = 4096), so the rays go in blocks of at most
    :data:`SUM_BLOCK`, zero-padded, whose float32 sums are added in float64: measured
    2e-6 relative to the float64 per-ray estimator for M = 256 … 16384 on ``plants``, far
    below the 1/√M sampling noise. One band stays float64 and unblocked: its single column
    makes the products BLAS gemv calls, whose float32 sums would depend on the chunk's row
    count.
    """
    local = pattern.local
    n_patterns, m = local.shape[:2]
    n2 = bands * bands
    # One evaluation for all patterns (per direction: the same values), coefficient-major:
    # the faster layout to evaluate, transposed by the copy into the tables.
    y = eval_sh_coefficient_major(local.reshape(-1, 3), bands)
    if bands == 1:
        return y.reshape(n_patterns, 1, m, 1)
    k = min(m, SUM_BLOCK)
    blocks = -(-m // k)
    tables = np.zeros((n_patterns, blocks * k, n2), dtype=np.float32)
    # Rounded to float32 before the transposing copy: the same values, half the bytes moved.
    tables[:, :m] = y.astype(np.float32).reshape(n2, n_patterns, m).transpose(1, 2, 0)
    return tables.reshape(n_patterns, blocks, k, n2)


def _transfer_chunks(tracer: Tracer, points: np.ndarray, normals: np.ndarray, *, bands: int,
                     rays_per_point: int, seed: int, chunks: list[slice], with_stderr: bool,
                     bar, visibility: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
    m = rays_per_point
    n2 = bands * bands
    pattern = RayPattern(len(points), m, seed)
    # Origins padded to 16-byte rows: repeating a point's origin for its M rays then copies
    # 16-byte records, ~8x faster than 12-byte ones (the tracer takes the strided (N, 3) view).
    origins_all = np.zeros((len(points), 4), dtype=np.float32)
    origins_all[:, :3] = offset_origins(points, normals, diagonal=tracer.diagonal)
    transfer = np.zeros((len(points), n2), dtype=np.float64)
    stderr = np.zeros((len(points), n2), dtype=np.float64) if with_stderr else None
    if not chunks:
        return transfer, stderr
    tables: list = []
    tables_lock = threading.Lock()

    def sh_tables() -> tuple[ShRotation, np.ndarray]:
        """(rotation, :func:`_local_sh_tables`), built by the first chunk done
        tracing: the other threads' tracing hides the cost."""
        with tables_lock:
            if not tables:
                tables.extend([ShRotation.for_bands(bands), _local_sh_tables(pattern, bands)])
        return tables[0], tables[1]

    scratch = Scratch()  # per-thread ray buffers: no page faults for every chunk's rays

    def trace_visible(sl: slice) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        n = sl.stop - sl.start
        frames = pattern.frames(normals[sl], sl)
        dirs = pattern.world_directions(frames, sl,
                                        out=scratch.get("dirs", (n, m, 3), np.float32))
        origins = repeat_rows(origins_all[sl], m, out=scratch.get("origins", (n * m, 4),
                                                                  np.float32))[:, :3]
        if not visibility:  # the unshadowed transfer: V = 1, the same rays and estimator
            return frames, dirs, np.ones((n, m), dtype=bool)
        return frames, dirs, ~tracer.occluded(origins, dirs.reshape(-1, 3)).reshape(-1, m)

    def chunk(sl: slice) -> tuple[np.ndarray, np.ndarray | None]:
        """(transfer, stderr or None) of the points in ``sl``: rays, trace and SH sums."""
        frames, dirs, visible = trace_visible(sl)
        if with_stderr:  # per-ray SH: the second moment needs every sample
            mean = np.empty((len(visible), n2))
            error = np.empty((len(visible), n2))
            step = max(1, _SCRATCH_BYTES // (8 * m * n2))
            for s in range(0, len(visible), step):
                y = eval_sh(dirs[s:s + step].reshape(-1, 3).astype(np.float64), bands)
                y = y.reshape(-1, m, n2)
                v = visible[s:s + step].astype(np.float64)
                mu = np.einsum("pm,pmi->pi", v, y) * (np.pi / m)
                second = np.einsum("pm,pmi->pi", v, y * y) * (np.pi**2 / m)
                var = np.maximum(second - mu**2, 0.0) * (m / (m - 1)) if m > 1 else np.inf
                mean[s:s + len(v)] = mu
                error[s:s + len(v)] = np.sqrt(var / m)
            return mean, error
        rotate, local_sh = sh_tables()
        local_t = _project(visible, local_sh, sl, scratch, scale=np.pi / m)
        return rotate.rotate_columns(local_t, frames.transpose(0, 2, 1)).T, None

    # Chunks run on the precompute threads (embree and numpy's large operations release the
    # GIL); each chunk's rays depend only on its points, so any thread count gives these bits.
    for (t, e), sl in zip(map_chunks(chunk, chunks), chunks):  # the pool first: it ends first
        transfer[sl] = t
        if stderr is not None:
            stderr[sl] = e
        bar.update(sl.stop - sl.start)
    return transfer, stderr


def _transfer_key(kind: str, scene: "Scene", points, normals, bands, rays_per_point, seed,
                  visibility: bool = True) -> str:
    # Shadowed keys are unchanged from before the visibility switch existed (no cache rebuild).
    extra = () if visibility else ("unshadowed",)
    return content_key(kind, TRANSFER_VERSION, scene.content_hash(), points, normals, int(bands),
                       int(rays_per_point), int(seed), *extra)


def _compute(scene, points, normals, *, bands, rays_per_point, seed, chunk_points, progress,
             use_cache, tracer, with_stderr, visibility=True) -> dict[str, np.ndarray]:
    p, n = check_inputs(points, normals, bands, rays_per_point)
    kind = "transfer-stderr" if with_stderr else "transfer"
    visibility = bool(visibility)

    def compute() -> dict[str, np.ndarray]:
        tr = tracer if tracer is not None else Tracer.from_scene(scene)
        chunks = point_chunks(len(p), rays_per_point, chunk_points)
        with progress_bar(len(p), f"transfer {scene.name}", progress) as bar, single_threaded_blas():
            t, e = _transfer_chunks(tr, p, n, bands=bands, rays_per_point=rays_per_point,
                                    seed=seed, chunks=chunks, with_stderr=with_stderr, bar=bar,
                                    visibility=visibility)
        out = {"transfer": t.astype(np.float32)}
        if e is not None:
            out["stderr"] = e.astype(np.float32)
        return out

    # Without the cache the key is never read: skip hashing the scene and points.
    key = (_transfer_key(kind, scene, p, n, bands, rays_per_point, seed, visibility)
           if use_cache else "uncached")
    return cached_arrays(kind, key, compute, use_cache=use_cache)


def compute_transfer(scene: "Scene", points: np.ndarray, normals: np.ndarray, *, bands: int,
                     rays_per_point: int, seed: int = 0, chunk_points: int | None = None,
                     progress: bool = True, use_cache: bool = True,
                     tracer: Tracer | None = None, visibility: bool = True) -> np.ndarray:
    """Shadowed diffuse transfer vectors T_i(p) = ∫ Y_i V max(n·ω, 0) dω.

    Parameters
    ----------
    scene : Scene
        Occluders (all objects); part of the cache key by content hash.
    points, normals : ndarray, shape (N, 3)
        Surface points and normals (normalised here).
    bands : int
        SH bands n (n² coefficients; polar axis world +Z, see :mod:`prtbench.transport.sh`).
    rays_per_point : int
        Cosine-weighted rays M per point.
    seed : int
        Seeds the direction patterns and per-point rotations.
    chunk_points : int, optional
        Points per embree batch (default: ~1M rays per batch).
    progress : bool
        Show a tqdm bar on stderr.
    use_cache : bool
        Read/write the content-addressed cache (atomic writes: an interrupted run stores nothing).
    tracer : Tracer, optional
        A tracer already built for ``scene`` (saves the BVH build).
    visibility : bool
        Trace occlusion (default). ``False`` sets V = 1: the unshadowed transfer
        ∫ Y_i max(n·ω, 0) dω with the same rays and estimator, the trivial image a shadowed
        method must beat (:mod:`prtbench.bench.trivial`); no ray is traced.

    Returns
    -------
    ndarray, shape (N, n²), float32
    """
    return _compute(scene, points, normals, bands=bands, rays_per_point=rays_per_point, seed=seed,
                    chunk_points=chunk_points, progress=progress, use_cache=use_cache,
                    tracer=tracer, with_stderr=False, visibility=visibility)["transfer"]


def compute_transfer_with_stderr(scene: "Scene", points: np.ndarray, normals: np.ndarray, *,
                                 bands: int, rays_per_point: int, seed: int = 0,
                                 chunk_points: int | None = None, progress: bool = True,
                                 use_cache: bool = True, tracer: Tracer | None = None,
                                 ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`compute_transfer` plus a per-coefficient Monte-Carlo standard error.

    The error is the i.i.d. formula s/√M over the M per-ray samples π·Y_i(ω_j)·V(ω_j); the
    stratified estimator's true error is smaller, so it is conservative. SH are evaluated per
    ray here (slower than :func:`compute_transfer`); the transfer is the same up to rounding.

    Returns
    -------
    transfer, stderr : ndarray, shape (N, n²), float32
    """
    out = _compute(scene, points, normals, bands=bands, rays_per_point=rays_per_point, seed=seed,
                   chunk_points=chunk_points, progress=progress, use_cache=use_cache,
                   tracer=tracer, with_stderr=True)
    return out["transfer"], out["stderr"]
