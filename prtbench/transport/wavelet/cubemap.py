"""Cubemaps 6×N×N: face/axis convention, exact texel solid angles, resampling of lat-long lights.

Convention (OpenGL's cube-map table, so a cubemap uploads to ``GL_TEXTURE_CUBE_MAP`` as is).
Faces in the order +X, −X, +Y, −Y, +Z, −Z. Texel ``(f, i, j)`` is row ``i`` (GL's t axis) and
column ``j`` (GL's s axis) of face ``f``; its centre has face coordinates

    a = 2(j + ½)/N − 1,   b = 2(i + ½)/N − 1          (both in (−1, 1))

and the (unnormalised) direction ``a·U_f + b·V_f + W_f`` with the rows of
:data:`FACE_FRAMES` (U, V, W)::

    +X: U = −Z, V = −Y, W = +X        −X: U = +Z, V = −Y, W = −X
    +Y: U = +X, V = +Z, W = +Y        −Y: U = +X, V = −Z, W = −Y
    +Z: U = +X, V = −Y, W = +Z        −Z: U = −X, V = −Y, W = −Z

Solid angles are exact: on the plane at distance 1 the area element is
dω = da db / (1 + a² + b²)^{3/2}, whose integral from the face centre to (a, b) is
``atan2(a·b, √(a² + b² + 1))``; a texel's solid angle is that corner function's
inclusion–exclusion over its four corners, and the 6N² texels sum to 4π to rounding.

Resampling a lat-long light (:func:`from_lat_long`) integrates it over each texel: S×S
midpoints per texel, each weighted by its area element, so the texel value is the texel's mean
radiance (not a point sample), evaluated through :meth:`EnvironmentLight.radiance` (Mitsuba's
bilinear lookup, the radiance every method and the reference see). S defaults to at least two
subsamples per lat-long sample spacing (:func:`default_supersample`).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from prtbench.api.cache import cached_arrays, content_key
from prtbench.api.errors import InvalidInputError
from prtbench.transport.latlong import lat_long_directions

if TYPE_CHECKING:
    from prtbench.transport.lights import EnvironmentLight

FACE_NAMES = ("+X", "-X", "+Y", "-Y", "+Z", "-Z")
#: (6, 3, 3): rows U (a axis), V (b axis), W (face normal) of each face, see the module docstring.
FACE_FRAMES = np.array([
    [[0, 0, -1], [0, -1, 0], [1, 0, 0]],
    [[0, 0, 1], [0, -1, 0], [-1, 0, 0]],
    [[1, 0, 0], [0, 0, 1], [0, 1, 0]],
    [[1, 0, 0], [0, 0, -1], [0, -1, 0]],
    [[1, 0, 0], [0, -1, 0], [0, 0, 1]],
    [[-1, 0, 0], [0, -1, 0], [0, 0, -1]],
], dtype=np.float64)
#: Largest accepted face resolution (6·1024² = 6.3 M texels per signal).
MAX_RESOLUTION = 1024
#: Largest supersampling factor per texel side used by :func:`from_lat_long`.
MAX_SUPERSAMPLE = 32
#: Bump when :func:`from_lat_long` changes (part of the cached light cubemaps' key).
RESAMPLE_VERSION = 1


def check_resolution(n, *, what: str = "cubemap") -> int:
    """``n`` as an int if it is a power of two in [1, :data:`MAX_RESOLUTION`], else an error."""
    ok = isinstance(n, (int, np.integer)) and not isinstance(n, bool) and 1 <= n <= MAX_RESOLUTION
    if not ok or int(n) & (int(n) - 1):
        raise InvalidInputError(f"{what}={n!r}; accepted: a power of two 1..{MAX_RESOLUTION} "
                                "(the Haar transform halves each face down to one texel)")
    return int(n)


def face_coordinates(n: int) -> np.ndarray:
    """(N,) float64 texel-centre face coordinates 2(j + ½)/N − 1."""
    return (2.0 * np.arange(n) + 1.0) / n - 1.0


def _face_points(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Unnormalised directions (6, *a.shape, 3) of face coordinates (a, b) on every face."""
    u, v, w = FACE_FRAMES[:, 0], FACE_FRAMES[:, 1], FACE_FRAMES[:, 2]
    extra = (None,) * a.ndim
    return (a[None, ..., None] * u[(slice(None), *extra)] + b[None, ..., None] * v[(slice(None), *extra)]
            + w[(slice(None), *extra)])


def texel_directions(n: int) -> np.ndarray:
    """Unit directions of the texel centres, (6, N, N, 3) float64."""
    n = check_resolution(n)
    c = face_coordinates(n)
    b, a = np.meshgrid(c, c, indexing="ij")  # row i ↔ b, column j ↔ a
    d = _face_points(a, b)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def _corner(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solid angle of the face rectangle [0, a] × [0, b] (signed)."""
    return np.arctan2(a * b, np.sqrt(a * a + b * b + 1.0))


def texel_solid_angles(n: int) -> np.ndarray:
    """Exact solid angle of every texel, (6, N, N) float64, summing to 4π.

    The same on every face (each face is the same square seen from the centre).
    """
    n = check_resolution(n)
    edges = 2.0 * np.arange(n + 1) / n - 1.0
    b, a = np.meshgrid(edges, edges, indexing="ij")
    f = _corner(a, b)  # (N+1, N+1), [row edge, column edge]
    face = f[1:, 1:] - f[:-1, 1:] - f[1:, :-1] + f[:-1, :-1]
    return np.broadcast_to(face, (6, n, n)).copy()


def directions_to_texels(dirs: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                             np.ndarray, np.ndarray]:
    """Texel containing each direction, and its face coordinates.

    Parameters
    ----------
    dirs : ndarray, shape (M, 3)
        Non-zero directions (need not be unit).
    n : int
        Face resolution.

    Returns
    -------
    face, row, col : ndarray, shape (M,), int64
    a, b : ndarray, shape (M,), float64
        Face coordinates in [−1, 1] (column and row axes).

    Directions on an edge between faces go to the first face in :data:`FACE_NAMES` order.
    """
    n = check_resolution(n)
    d = np.asarray(dirs, dtype=np.float64).reshape(-1, 3)
    if not np.all(np.isfinite(d)) or np.any(np.all(d == 0, axis=1)):
        raise InvalidInputError("cubemap lookup directions must be finite and non-zero")
    axis = np.argmax(np.abs(d), axis=1)
    negative = d[np.arange(len(d)), axis] < 0
    face = 2 * axis + negative
    frames = FACE_FRAMES[face]  # (M, 3, 3)
    ma = np.einsum("mk,mk->m", frames[:, 2], d)
    a = np.clip(np.einsum("mk,mk->m", frames[:, 0], d) / ma, -1.0, 1.0)
    b = np.clip(np.einsum("mk,mk->m", frames[:, 1], d) / ma, -1.0, 1.0)
    col = np.minimum(((a + 1.0) * 0.5 * n).astype(np.int64), n - 1)
    row = np.minimum(((b + 1.0) * 0.5 * n).astype(np.int64), n - 1)
    return face.astype(np.int64), row, col, a, b


def cubemap_lookup(cube: np.ndarray, dirs: np.ndarray, *, interpolation: str = "bilinear"
                   ) -> np.ndarray:
    """Values of a cubemap in directions ``dirs``.

    Parameters
    ----------
    cube : ndarray, shape (6, N, N, ...)
    dirs : ndarray, shape (M, 3)
    interpolation : {"bilinear", "nearest"}
        Bilinear between texel centres of the same face, clamped at face edges (no filtering
        across faces: the half-texel border is nearest-valued).

    Returns
    -------
    ndarray, shape (M, ...), float64
    """
    cube = np.asarray(cube)
    if cube.ndim < 3 or cube.shape[0] != 6 or cube.shape[1] != cube.shape[2]:
        raise InvalidInputError(f"cubemap shape {cube.shape}; accepted: (6, N, N, ...)")
    n = cube.shape[1]
    face, row, col, a, b = directions_to_texels(dirs, n)
    if interpolation == "nearest":
        return cube[face, row, col].astype(np.float64)
    if interpolation != "bilinear":
        raise InvalidInputError(f"interpolation '{interpolation}'; accepted: bilinear, nearest")
    x = np.clip((a + 1.0) * 0.5 * n - 0.5, 0.0, n - 1.0)
    y = np.clip((b + 1.0) * 0.5 * n - 0.5, 0.0, n - 1.0)
    j0 = np.minimum(np.floor(x).astype(np.int64), max(n - 2, 0))
    i0 = np.minimum(np.floor(y).astype(np.int64), max(n - 2, 0))
    j1, i1 = np.minimum(j0 + 1, n - 1), np.minimum(i0 + 1, n - 1)
    fx, fy = x - j0, y - i0
    shape = (-1,) + (1,) * (cube.ndim - 3)
    fx, fy = fx.reshape(shape), fy.reshape(shape)
    c = cube.astype(np.float64, copy=False)
    top = (1.0 - fx) * c[face, i0, j0] + fx * c[face, i0, j1]
    bottom = (1.0 - fx) * c[face, i1, j0] + fx * c[face, i1, j1]
    return (1.0 - fy) * top + fy * bottom


def default_supersample(n: int, light_height: int) -> int:
    """Subsamples per texel side giving at least two per lat-long sample spacing.

    A face-centre texel spans 2/N radians; lat-long rows are π/(H − 1) apart.
    """
    spacing = math.pi / max(light_height - 1, 1)
    return int(min(MAX_SUPERSAMPLE, max(2, math.ceil(2.0 * (2.0 / n) / spacing))))


def subsample_pattern(n: int, s: int) -> tuple[np.ndarray, np.ndarray]:
    """Midpoint subsamples of every texel: unit directions and solid-angle weights.

    Returns
    -------
    dirs : ndarray, shape (6, N, N, S·S, 3), float64
    weights : ndarray, shape (N, N, S·S), float64
        Area element × subsample area, renormalised so each texel's weights sum to its exact
        solid angle (the same on every face).
    """
    n = check_resolution(n)
    if int(s) != s or s < 1:
        raise InvalidInputError(f"supersample={s!r}; accepted: integers >= 1")
    s = int(s)
    fine = (2.0 * np.arange(n * s) + 1.0) / (n * s) - 1.0
    b, a = np.meshgrid(fine, fine, indexing="ij")  # (N·S, N·S)
    # (N·S, N·S) -> (N, S, N, S) -> (N, N, S·S): subsamples grouped by texel.
    def group(x: np.ndarray) -> np.ndarray:
        return x.reshape(n, s, n, s).transpose(0, 2, 1, 3).reshape(n, n, s * s)

    a, b = group(a), group(b)
    element = (1.0 + a * a + b * b) ** -1.5
    weights = element / element.sum(axis=-1, keepdims=True) * texel_solid_angles(n)[0][..., None]
    d = _face_points(a, b)
    return d / np.linalg.norm(d, axis=-1, keepdims=True), weights


def from_lat_long(light: "EnvironmentLight", n: int, *, supersample: int | None = None
                  ) -> np.ndarray:
    """Texel-mean radiance of a lat-long light on a cubemap, (6, N, N, 3) float64.

    Each texel's value is ``∫_texel L dω / Ω_texel`` by an S×S midpoint rule weighted by the
    area element (``supersample`` S, default :func:`default_supersample`), so
    ``Σ value · Ω`` approximates the light's total power to the rule's accuracy.
    """
    n = check_resolution(n)
    s = default_supersample(n, light.height) if supersample is None else supersample
    dirs, weights = subsample_pattern(n, s)
    out = np.empty((6, n, n, 3))
    for f in range(6):  # one face at a time bounds the lookup's temporaries
        radiance = light.radiance(dirs[f].reshape(-1, 3)).reshape(n, n, -1, 3)
        out[f] = np.einsum("ijsc,ijs->ijc", radiance, weights) / weights.sum(axis=-1)[..., None]
    return out


def light_cubemap(light: "EnvironmentLight", n: int) -> np.ndarray:
    """:func:`from_lat_long` at the default supersampling, cached per (light content, N)."""

    n = check_resolution(n)
    s = default_supersample(n, light.height)
    key = content_key("light-cubemap", light.content_hash(), n, s, RESAMPLE_VERSION)
    return cached_arrays("light-cubemap", key,
                         lambda: {"cube": from_lat_long(light, n, supersample=s)},
                         use_cache=not getattr(light, "_uncached", False))["cube"]


def to_lat_long(cube: np.ndarray, height: int, *, interpolation: str = "bilinear") -> np.ndarray:
    """A cubemap sampled at the sample directions of a lat-long image of ``height`` rows.

    Returns
    -------
    ndarray, shape (H, 2H, ...), float64
        Mitsuba's sample positions (:meth:`EnvironmentLight.texel_directions`).
    """

    w = 2 * height
    u = (np.arange(w) + 0.5) / w
    v = np.arange(height) / (height - 1)
    dirs = lat_long_directions(u[None, :], v[:, None]).reshape(-1, 3)
    values = cubemap_lookup(cube, dirs, interpolation=interpolation)
    return values.reshape(height, w, *values.shape[1:])
