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
and the chunks only on the point and ray counts (:func:`_chunks`), every thread count gives the
same bits. :func:`compute_transfer_with_stderr` evaluates SH per ray instead (it needs every
sample's square); both give the same transfer up to rounding.

Interreflected transfer (Sloan's bounces) is in :func:`compute_bounce_transfer`.
"""

from __future__ import annotations

import math
import sys
import threading
from collections.abc import Iterator
from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np

from prtbench.api.cache import cached_arrays, content_key
from prtbench.api.errors import InvalidInputError
from prtbench.transport.parallel import (
    Scratch,
    _openblas_threads,  # noqa: F401  (re-exported for users)
    map_chunks,
    parallel_chunks,
    repeat_rows,
)
from prtbench.transport.parallel import single_threaded_blas as _single_threaded_blas
from prtbench.transport.raytrace import Tracer, offset_origins
from prtbench.transport.sh import eval_sh, eval_sh_coefficient_major, sphere_quadrature

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

#: Distinct randomly shifted direction patterns (SH tables are evaluated once per pattern).
N_PATTERNS = 16

#: Scratch budget (bytes) of one SH evaluation block.
_SCRATCH_BYTES = 32 << 20

_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


# --- directions ---------------------------------------------------------------------------------

def cosine_hemisphere(u: np.ndarray) -> np.ndarray:
    """Malley's method: unit-square points (M, 2) -> cosine-weighted local directions (M, 3), +Z up."""
    r = np.sqrt(u[:, 0])
    phi = 2.0 * np.pi * u[:, 1]
    return np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(np.maximum(1.0 - u[:, 0], 0.0))],
                    axis=1)


def fibonacci_square(m: int, *, shift: np.ndarray = np.zeros(2)) -> np.ndarray:
    """Fibonacci lattice ((j + ½)/m, frac(j/φ)) in [0, 1)², toroidally shifted: (m, 2)."""
    j = np.arange(m, dtype=np.float64)
    u = np.stack([(j + 0.5) / m, np.mod(j * _GOLDEN, 1.0)], axis=1)
    return np.mod(u + np.asarray(shift, dtype=np.float64), 1.0)


def tangent_frames(normals: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """Right-handed frames (t1, t2, n) about unit ``normals`` (N, 3), spun by ``angles`` (N,).

    Returns (N, 3, 3) float64 whose rows are t1, t2, n (local -> world is ``local @ frame``).
    """
    n = normals
    sign = np.where(n[:, 2] >= 0, 1.0, -1.0)
    a = -1.0 / (sign + n[:, 2])
    b = n[:, 0] * n[:, 1] * a
    t1 = np.stack([1.0 + sign * n[:, 0] ** 2 * a, sign * b, -sign * n[:, 0]], axis=1)
    t2 = np.stack([b, sign + n[:, 1] ** 2 * a, -n[:, 1]], axis=1)
    c, s = np.cos(angles)[:, None], np.sin(angles)[:, None]
    return np.stack([c * t1 + s * t2, c * t2 - s * t1, n], axis=1)


class RayPattern:
    """Seeded per-point cosine-weighted ray directions (see the module docstring).

    Point i uses pattern ``i % n_patterns`` (each pattern is independently, uniformly shifted,
    so every point's estimate is unbiased) spun by its own random angle about the normal.

    Parameters
    ----------
    n_points, rays_per_point, seed : int
    """

    def __init__(self, n_points: int, rays_per_point: int, seed: int):
        rng = np.random.default_rng([int(seed), 0x5052_5442])  # stream tag: "PRTB"
        self.rays_per_point = rays_per_point
        self.n_patterns = N_PATTERNS
        shifts = rng.random((self.n_patterns, 2))
        # All patterns in one pass: the same element-wise operations as
        # fibonacci_square(m, shift=s) for each shift, so the same values, in a tenth the time.
        shifted = np.mod(fibonacci_square(rays_per_point)[None] + shifts[:, None, :], 1.0)
        #: (P, M, 3) float64 local directions of each pattern.
        self.local = cosine_hemisphere(shifted.reshape(-1, 2)).reshape(self.n_patterns,
                                                                      rays_per_point, 3)
        self.angle_of_point = rng.random(n_points) * 2.0 * np.pi

    def frames(self, normals: np.ndarray, sl: slice) -> np.ndarray:
        """(n, 3, 3) local->world frames (rows t1, t2, n) of the points in ``sl``."""
        return tangent_frames(normals, self.angle_of_point[sl])

    def groups(self, sl: slice) -> Iterator[tuple[int, slice]]:
        """(pattern, rows of the chunk ``sl`` using it) pairs; rows are strided slices."""
        for k in range(min(self.n_patterns, sl.stop - sl.start)):
            yield (sl.start + k) % self.n_patterns, slice(k, None, self.n_patterns)

    def world_directions(self, frames: np.ndarray, sl: slice, *,
                         out: np.ndarray | None = None) -> np.ndarray:
        """(n, M, 3) float32 world directions of the points in ``sl`` with ``frames`` (n, 3, 3).

        ``out``, if given, is a C-contiguous (n, M, 3) float32 array to write them into.
        """
        if out is None:
            out = np.empty((len(frames), self.rays_per_point, 3), dtype=np.float32)
        f32 = frames.astype(np.float32)
        for k, rows in self.groups(sl):
            np.matmul(self.local[k].astype(np.float32)[None], f32[rows], out=out[rows])
        return out


# --- inputs -------------------------------------------------------------------------------------

def _check_inputs(points: np.ndarray, normals: np.ndarray, bands: int,
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


def _chunks(n_points: int, rays_per_point: int, chunk_points: int | None) -> list[slice]:
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


def _progress(total: int, desc: str, enabled: bool):
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit="pt", file=sys.stderr, disable=not enabled,
                dynamic_ncols=True)


# --- shadowed transfer --------------------------------------------------------------------------

def _rotation_x(degrees: float) -> np.ndarray:
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


class ShRotation:
    """Rotate SH coefficient vectors by per-point rotations (ZYZ Euler angles).

    For a rotation R, the function ω ↦ Σ_j c_j Y_j(Rᵀω) has coefficients D(R)·c. With
    R = Rz(a)·Ry(b)·Rz(c) and Ry(b) = Rx(−90°)·Rz(b)·Rx(90°), D(R) is three cheap z-rotations
    (cos/sin mixing of ±m pairs) and two constant band-diagonal matrices computed once by exact
    quadrature, so rotating costs O(n³) per point with no per-point SH evaluation.

    The work runs coefficient-major, on (n², N) arrays (:meth:`rotate_columns`): a band's
    ±m rows are then contiguous runs of N values, so each of the per-band numpy operations
    streams memory instead of striding across it (measured 1.3–1.7× faster than point-major
    for 256–4096 points). The band matrices are applied as ``(cᵀ @ Bᵀ)ᵀ``, the same BLAS
    product as point-major ``c @ Bᵀ``, so the results are bit for bit those of the point-major
    layout this replaced. Use :meth:`for_bands` to share the constant matrices between calls.
    """

    def __init__(self, bands: int):
        self.bands = bands
        dirs, weights = sphere_quadrature(2 * (bands - 1))
        y = eval_sh(dirs, bands) * weights[:, None]
        # D_ij = ∫ Y_i(ω) Y_j(Rᵀω) dω, exact: the integrand has degree <= 2(n-1).
        d_minus = y.T @ eval_sh(dirs @ _rotation_x(-90.0), bands)
        d_minus.flags.writeable = False  # constants, shared between threads by for_bands
        self.x_minus = [d_minus[l * l:(l + 1) ** 2, l * l:(l + 1) ** 2] for l in range(bands)]
        self.x_plus = [block.T for block in self.x_minus]  # D(R⁻¹) = D(R)ᵀ
        # float32 copies for float32 coefficients (mixed products would run in float64).
        self._blocks32 = ([b.astype(np.float32) for b in self.x_plus],
                          [b.astype(np.float32) for b in self.x_minus])

    @staticmethod
    def for_bands(bands: int) -> "ShRotation":
        """The rotation of ``bands`` bands, built once per process (its matrices are constants)."""
        return _rotation_for_bands(int(bands))

    def _z(self, c: np.ndarray, angle: np.ndarray) -> None:
        if self.bands < 2:
            return
        # e^{imγ} for m = 1 … n−1 by repeated products: two trig calls per point, not n².
        powers = np.cumprod(np.repeat(np.exp(1j * angle)[None, :], self.bands - 1, axis=0), axis=0)
        cos = np.ascontiguousarray(powers.real, dtype=c.dtype)
        sin = np.ascontiguousarray(powers.imag, dtype=c.dtype)
        for l in range(1, self.bands):
            # Band l's m = 1 … l are rows l²+l+1 … l²+2l and their partners −m run from
            # l²+l−1 down to l²: slices, not gathers (per-point cost of the rotation).
            centre = l * l + l
            pos = c[centre + 1:centre + l + 1]
            neg = c[centre - 1:(centre - l - 1 if centre - l - 1 >= 0 else None):-1]
            cl, sl = cos[:l], sin[:l]
            new_pos = pos * cl - neg * sl
            neg[...] = pos * sl + neg * cl
            pos[...] = new_pos

    def _x(self, c: np.ndarray, blocks: list[np.ndarray]) -> None:
        for l, block in enumerate(blocks):
            if l:
                rows = c[l * l:(l + 1) ** 2]
                rows[...] = (rows.T @ block.T).T

    def rotate_columns(self, coeffs_t: np.ndarray, world_from_local: np.ndarray) -> np.ndarray:
        """D(R_p)·c_p in place for coefficients stored coefficient-major.

        Parameters
        ----------
        coeffs_t : ndarray, shape (n², N), float64 or float32, C-contiguous
            Column p holds point p's coefficients; overwritten with the rotated ones. The
            rotation runs in its precision (angles are computed in float64 either way).
        world_from_local : ndarray, shape (N, 3, 3)

        Returns
        -------
        ndarray, shape (n², N): ``coeffs_t`` itself.
        """
        if coeffs_t.dtype == np.float32 and coeffs_t.shape[1] == 1:
            # One column would make the band products BLAS gemv calls, whose float32 sums
            # round differently from gemm's: rotate it as two equal columns instead.
            pair = np.repeat(coeffs_t, 2, axis=1)
            self.rotate_columns(pair, np.repeat(world_from_local, 2, axis=0))
            coeffs_t[...] = pair[:, :1]
            return coeffs_t
        r = world_from_local
        b = np.arccos(np.clip(r[:, 2, 2], -1.0, 1.0))
        sin_b = np.hypot(r[:, 0, 2], r[:, 1, 2])
        regular = sin_b > 1e-9
        a = np.where(regular, np.arctan2(r[:, 1, 2], r[:, 0, 2]),
                     np.where(r[:, 2, 2] > 0, np.arctan2(r[:, 1, 0], r[:, 0, 0]),
                              np.arctan2(-r[:, 1, 0], r[:, 1, 1])))
        c_ang = np.where(regular, np.arctan2(r[:, 2, 1], -r[:, 2, 0]), 0.0)
        x_plus, x_minus = (self._blocks32 if coeffs_t.dtype == np.float32
                           else (self.x_plus, self.x_minus))
        self._z(coeffs_t, c_ang)
        self._x(coeffs_t, x_plus)
        self._z(coeffs_t, b)
        self._x(coeffs_t, x_minus)
        self._z(coeffs_t, a)
        return coeffs_t

    def __call__(self, coeffs: np.ndarray, world_from_local: np.ndarray) -> np.ndarray:
        """D(R_p)·c_p for coefficients (N, n²) and rotations (N, 3, 3); returns a new array."""
        out = np.array(np.asarray(coeffs).T, dtype=np.float64, order="C")  # always a copy
        return np.ascontiguousarray(self.rotate_columns(out, world_from_local).T)


_rotation_for_bands = lru_cache(maxsize=16)(ShRotation)


#: Rays per float32 partial sum in :func:`_project` (their float64 total bounds the rounding).
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
    p, n = _check_inputs(points, normals, bands, rays_per_point)
    kind = "transfer-stderr" if with_stderr else "transfer"
    visibility = bool(visibility)

    def compute() -> dict[str, np.ndarray]:
        tr = tracer if tracer is not None else Tracer.from_scene(scene)
        chunks = _chunks(len(p), rays_per_point, chunk_points)
        with _progress(len(p), f"transfer {scene.name}", progress) as bar, _single_threaded_blas():
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


# --- interreflected transfer (Sloan et al. 2002, §5) ----------------------------------------------

#: Keep the per-chunk gather matrices between bounces when they fit in this many bytes;
#: otherwise the same (seeded) rays are traced again for every bounce.
_GATHER_CACHE_BYTES = 256 << 20


class _Albedo:
    """Diffuse albedo kd (RGB) at ray hits: per-object constants or textures sampled at UVs."""

    def __init__(self, scene: "Scene", faces: np.ndarray, object_of_face: np.ndarray):
        from prtbench.scene.model import Texture

        self.faces = faces
        self.object_of_face = object_of_face
        self.constant = np.zeros((len(scene.objects), 3))
        self.textures: dict[int, Texture] = {}
        uvs = []
        for i, obj in enumerate(scene.objects):
            kd, mesh = obj.material.kd, obj.mesh
            if isinstance(kd, Texture):
                if mesh.uvs is None:
                    raise InvalidInputError(
                        f"object '{obj.name}' has a textured kd but no uvs; accepted: a mesh "
                        "with uvs, or a constant kd")
                self.textures[i] = kd
            else:
                self.constant[i] = kd
            uvs.append(mesh.uvs if mesh.uvs is not None else np.zeros((mesh.n_vertices, 2)))
        self.uvs = np.concatenate(uvs).astype(np.float64) if uvs else np.zeros((0, 2))

    def __call__(self, face: np.ndarray, bary: np.ndarray) -> np.ndarray:
        """kd (H, 3) at hits on ``face`` (H,) with barycentrics ``bary`` (H, 3)."""
        obj = self.object_of_face[face]
        kd = self.constant[obj]
        for i, tex in self.textures.items():
            sel = np.flatnonzero(obj == i)
            if len(sel):
                uv = np.einsum("hk,hkj->hj", bary[sel], self.uvs[self.faces[face[sel]]])
                texel = tex.sample(uv)
                kd[sel] = texel[:, :3] if texel.shape[1] >= 3 else np.repeat(texel[:, :1], 3, axis=1)
        return kd


def _gather_matrices(tracer: Tracer, albedo: _Albedo, points: np.ndarray, normals: np.ndarray,
                     *, rays_per_point: int, seed: int,
                     chunks: list[slice]) -> Iterator[tuple[slice, list]]:
    """Per chunk, the RGB matrices W_c (n_chunk, V) with T^{b+1}_c = W_c · T^b_c.

    W_c[p, v] = 1/M Σ_j [ray j of p hits the front of a triangle at q_j] kd_c(q_j) β_v(q_j),
    i.e. π/M Σ_j (kd/π) T^b(q_j) with T^b interpolated by the barycentrics β of the hit.
    """
    from scipy.sparse import csr_matrix

    m = rays_per_point
    pattern = RayPattern(len(points), m, seed)
    origins_all = offset_origins(points, normals, diagonal=tracer.diagonal).astype(np.float32)
    n_vertices = len(tracer.positions)
    corners = tracer.positions.astype(np.float64)[tracer.faces]
    face_normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])

    def chunk(sl: slice) -> list:
        frames = pattern.frames(normals[sl], sl)
        dirs = pattern.world_directions(frames, sl).reshape(-1, 3)
        hits = tracer.first_hit(np.repeat(origins_all[sl], m, axis=0), dirs)
        ray = np.flatnonzero(hits.face >= 0)
        face = hits.face[ray]
        u, v = hits.u[ray].astype(np.float64), hits.v[ray].astype(np.float64)
        bary = np.stack([1.0 - u - v, u, v], axis=1)
        verts = tracer.faces[face]
        # One-sided surfaces: only a hit on the front (counter-clockwise side) reflects. The
        # triangle's own normal decides, not the interpolated shading normal: near a ray's
        # origin vertex that one is ~ the origin's normal and would call grazing hits on the
        # neighbouring faces of a concave surface back-facing.
        front = np.einsum("hj,hj->h", dirs[ray].astype(np.float64), face_normals[face]) < 0
        ray, face, bary, verts = ray[front], face[front], bary[front], verts[front]
        weight = bary[:, :, None] * albedo(face, bary)[:, None, :] / m  # (H, 3 verts, 3 rgb)
        # Hits come sorted by ray, hence by row: build CSR directly (duplicates are fine for
        # products), the three channels sharing one index structure.
        n_rows = sl.stop - sl.start
        per_row = np.bincount(ray // m, minlength=n_rows) * 3
        indptr = np.concatenate([[0], np.cumsum(per_row)]).astype(np.int64)
        indices = verts.reshape(-1).astype(np.int32)
        return [csr_matrix((np.ascontiguousarray(weight[:, :, c]).reshape(-1), indices, indptr),
                           shape=(n_rows, n_vertices)) for c in range(3)]

    # Chunks are built on the precompute threads and come back in chunk order.
    for mats, sl in zip(map_chunks(chunk, chunks), chunks):  # the pool first: it ends first
        yield sl, mats


class _Gather:
    """Applies W (all chunks) to vertex transfer, keeping the matrices if they fit in memory."""

    def __init__(self, make, n_rows: int, bar):
        self.make, self.n_rows, self.bar = make, n_rows, bar
        self.kept: list | None = None

    def __call__(self, vertex_transfer: np.ndarray) -> np.ndarray:
        """W · T for vertex transfer (V, n², 1 or 3); returns (n_rows, n², 3) float64."""
        out = np.zeros((self.n_rows, vertex_transfer.shape[1], 3))
        record = self.kept is None
        source = self.make() if record else self.kept
        kept, size = [], 0
        for sl, mats in source:
            for c, mat in enumerate(mats):
                out[sl, :, c] = mat @ vertex_transfer[:, :, min(c, vertex_transfer.shape[2] - 1)]
            if record:
                size += sum(m.data.nbytes for m in mats) + mats[0].indices.nbytes
                record = size <= _GATHER_CACHE_BYTES
                kept.append((sl, mats))
            self.bar.update(sl.stop - sl.start)
        if record:
            self.kept = kept
        return out


def compute_bounce_transfer(scene: "Scene", points: np.ndarray, normals: np.ndarray, *,
                            vertex_transfer: np.ndarray, bounces: int, rays_per_point: int,
                            seed: int = 0, progress: bool = True, use_cache: bool = True,
                            tracer: Tracer | None = None) -> np.ndarray:
    """Interreflected diffuse transfer (Sloan et al. 2002): shadowed transfer plus ``bounces``.

    T^{b+1}(p) = π/M Σ_j [ray j hits the front of a surface at q] (kd(q)/π) · T^b(q), with
    T^b(q) interpolated from the hit triangle's vertices by barycentrics; hits on the back of a
    triangle add nothing (surfaces are one-sided; the front is the counter-clockwise side, the
    side its vertex normals face).
    T^b for b >= 1 is iterated on all scene vertices, then gathered at ``points`` (when the
    points are the vertices this is exactly Sloan's per-vertex iteration). Only the diffuse part
    (kd) of the surfaces hit is propagated; their specular lobe (ks) is ignored. Each iteration
    re-uses the same rays. Radiance with an SH light L (n², 3): B = kd(p)/π · Σ_i T_i L_i.

    Parameters
    ----------
    scene : Scene
        Geometry and materials (textured kd is sampled at the hit UVs; it needs mesh uvs).
    points, normals : ndarray, shape (N, 3)
    vertex_transfer : ndarray, shape (V, n²)
        Shadowed (zero-bounce) transfer at all vertices of ``scene.merged()``, in that order.
    bounces : int
        Interreflection bounces (0 returns the shadowed transfer).
    rays_per_point : int
        Gather rays per point and per vertex.
    seed : int
    progress, use_cache : bool
    tracer : Tracer, optional
        Built for ``scene`` with :meth:`Tracer.from_scene`.

    Returns
    -------
    ndarray, shape (N, n², 3), float32
        T^0 + T^1 + … + T^bounces per RGB channel.
    """
    p, n = _check_inputs(points, normals, 1, rays_per_point)
    positions, vertex_normals, faces, object_of_face = scene.merged()
    vt = np.asarray(vertex_transfer, dtype=np.float64)
    bands = int(round(math.sqrt(vt.shape[1]))) if vt.ndim == 2 else 0
    if vt.ndim != 2 or len(vt) != len(positions) or bands * bands != vt.shape[1] or bands < 1:
        raise InvalidInputError(
            f"vertex_transfer shape {vt.shape}; accepted: ({len(positions)}, n²), one row per "
            f"vertex of scene '{scene.name}'")
    if not np.all(np.isfinite(vt)):
        raise InvalidInputError("vertex_transfer contains NaN/Inf; accepted: finite values")
    if int(bounces) != bounces or bounces < 0:
        raise InvalidInputError(f"bounces={bounces!r}; accepted: integers >= 0")
    bounces = int(bounces)
    albedo = _Albedo(scene, faces, object_of_face)  # fails early on textures without uvs
    at_vertices = (p.shape == positions.shape and np.array_equal(p, positions)
                   and np.array_equal(np.asarray(normals, np.float64).reshape(-1, 3), vertex_normals))

    def compute() -> dict[str, np.ndarray]:
        tr = tracer if tracer is not None else Tracer.from_scene(scene)
        if at_vertices:
            total = np.repeat(vt[:, :, None], 3, axis=2)
        else:
            total = np.repeat(compute_transfer(
                scene, p, n, bands=bands, rays_per_point=rays_per_point, seed=seed,
                progress=progress, use_cache=use_cache, tracer=tr)[:, :, None], 3, axis=2)
        if bounces == 0:
            return {"transfer": total.astype(np.float32)}
        vn = vertex_normals.astype(np.float64)
        length = np.linalg.norm(vn, axis=1, keepdims=True)
        vn_unit = np.where(length > 0, vn / np.maximum(length, 1e-300), [0.0, 1.0, 0.0])
        vertex_passes = bounces if at_vertices else bounces - 1
        n_rows = vertex_passes * len(positions) + (0 if at_vertices else bounces * len(p))
        with _progress(n_rows, f"bounces {scene.name}", progress) as bar:
            def gather(pts, nrm):
                return _Gather(lambda: _gather_matrices(
                    tr, albedo, pts, nrm, rays_per_point=rays_per_point, seed=seed,
                    chunks=_chunks(len(pts), rays_per_point, None)), len(pts), bar)

            at_vertex = gather(positions.astype(np.float64), vn_unit)
            at_point = at_vertex if at_vertices else gather(p, n)
            previous = vt[:, :, None]  # T^0 is grey: the same for every channel
            for b in range(1, bounces + 1):
                if at_vertices:
                    previous = at_vertex(previous)  # T^b at the vertices, which are the points
                    total += previous
                else:
                    total += at_point(previous)  # T^b at the points from T^(b-1) at vertices
                    if b < bounces:
                        previous = at_vertex(previous)
        return {"transfer": total.astype(np.float32)}

    key = content_key("transfer-bounce", TRANSFER_VERSION, scene.content_hash(), p, n, vt,
                      bounces, int(rays_per_point), int(seed))
    return cached_arrays("transfer-bounce", key, compute, use_cache=use_cache)["transfer"]
