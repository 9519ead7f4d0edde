"""The extreme lights of the stability matrix (issue #15), built procedurally.

Each is an ordinary :class:`prtbench.transport.lights.EnvironmentLight` (so the reference and every method
see the same map) plus the display-exposure factor its case applies to the scene, so that an
image lit by a light a million times brighter is displayed, and measured, at the brightness of
the usual one: the case then measures the method's arithmetic at that magnitude, not the sRGB
clip of a white image.

Names and what they probe:

* ``black``: radiance 0 everywhere (the reference is black; so must the method be).
* ``huge-constant``: radiance 10⁶ everywhere (exposure 10⁻⁶): float32 sums and half-float
  storage of light coefficients.
* ``below-horizon``: radiance 1 only below the horizon (y < 0): an up-facing ground sees
  nothing; SH truncation rings it into the upper hemisphere.
* ``single-texel``: one texel of an otherwise black 256 × 512 map, bright enough to deliver
  irradiance π at normal incidence: a delta light a lat-long map can hold.
* ``sun-0.1deg``: a 0.1°-radius sun (every texel within max(0.1°, half a texel) of its centre)
  over a background 10⁸ times dimmer, irradiance π: a near-delta light at 10⁸ : 1.
* ``hdri-2048``: the ``sky`` light resampled to 2048 × 1024 (exactly its bilinear interpolant),
  the largest map the cases use.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from prtbench.transport.latlong import lat_long_directions
from prtbench.transport.lights import EnvironmentLight, get_light
from prtbench.transport.procedural import sun_direction

#: Direction of the small and point-like suns: the built-in ``sun`` light's (55° up, 60° from
#: +Z towards +X), so their shadows fall where that light's do.
SUN_DIRECTION = sun_direction(55.0, 60.0)

#: Radiance of the huge constant light.
HUGE_RADIANCE = 1.0e6
#: Dynamic range of the near-delta sun (sun texel / background texel).
SUN_DYNAMIC_RANGE = 1.0e8
#: Angular radius of the near-delta sun, degrees.
SUN_RADIUS_DEG = 0.1


@dataclass(frozen=True)
class StabilityLight:
    """A case light: how to build it and the exposure factor its case applies.

    Attributes
    ----------
    name : str
    build : callable
        ``() -> EnvironmentLight`` (memoised).
    exposure_factor : float
        Multiplies the scene's display exposure.
    note : str
        What the light probes (one line, for the report).
    """

    name: str
    build: Callable[[], object]
    exposure_factor: float
    note: str


def _directions(height: int) -> np.ndarray:
    """Sample directions (H, 2H, 3) of a lat-long map (Mitsuba's sample positions)."""

    w = 2 * height
    u = (np.arange(w) + 0.5) / w
    v = np.arange(height) / (height - 1)
    return lat_long_directions(u[None, :], v[:, None])


def _light(name: str, image: np.ndarray):
    return EnvironmentLight(f"stability-{name}", image.astype(np.float32),
                            source=f"procedural:stability-{name}")


@lru_cache(maxsize=None)
def black():
    """Radiance 0 everywhere, (32, 64) texels."""
    return _light("black", np.zeros((32, 64, 3)))


@lru_cache(maxsize=None)
def huge_constant():
    """Radiance :data:`HUGE_RADIANCE` everywhere, (32, 64) texels."""
    return _light("huge-constant", np.full((32, 64, 3), HUGE_RADIANCE))


@lru_cache(maxsize=None)
def below_horizon():
    """Radiance 1 where the direction points below the horizon (y < 0), else 0."""
    dirs = _directions(128)
    return _light("below-horizon", np.repeat((dirs[..., 1:2] < 0.0).astype(np.float64), 3, -1))


def _irradiance_scale(image_mask: np.ndarray, height: int, direction: np.ndarray) -> float:
    """Radiance that makes the texels of ``image_mask`` deliver irradiance π along ``direction``."""

    probe = EnvironmentLight("probe", np.repeat(image_mask[..., None], 3, -1).astype(np.float32))
    dirs = probe.texel_directions()
    cosine = np.clip(dirs @ direction, 0.0, None)
    irradiance = float(np.sum(image_mask * probe.texel_solid_angles() * cosine))
    return math.pi / irradiance


def _sun_direction() -> np.ndarray:
    return np.asarray(SUN_DIRECTION, dtype=np.float64)


@lru_cache(maxsize=None)
def single_texel():
    """One bright texel (nearest the ``sun`` light's direction) of a black (256, 512) map."""
    height = 256
    dirs = _directions(height)
    mask = np.zeros(dirs.shape[:2])
    j, i = np.unravel_index(int(np.argmax(dirs @ _sun_direction())), mask.shape)
    mask[j, i] = 1.0
    peak = _irradiance_scale(mask, height, dirs[j, i])
    return _light("single-texel", np.repeat((peak * mask)[..., None], 3, -1))


@lru_cache(maxsize=None)
def near_delta_sun():
    """A :data:`SUN_RADIUS_DEG` sun at the ``sun`` light's direction, background 10⁻⁸ of it."""
    height = 1024
    dirs = _directions(height)
    sun = _sun_direction()
    angle = np.arccos(np.clip(dirs @ sun, -1.0, 1.0))
    half_texel = 0.5 * math.pi / (height - 1)
    mask = (angle <= max(math.radians(SUN_RADIUS_DEG), half_texel)).astype(np.float64)
    peak = _irradiance_scale(mask, height, sun)
    image = np.where(mask > 0, peak, peak / SUN_DYNAMIC_RANGE)
    return _light("sun-0.1deg", np.repeat(image[..., None], 3, -1))


@lru_cache(maxsize=None)
def hdri_2048():
    """The ``sky`` light's bilinear interpolant sampled on a 2048 × 1024 map."""

    sky = get_light("sky")
    dirs = _directions(1024)
    image = sky.radiance(dirs.reshape(-1, 3)).reshape(*dirs.shape[:2], 3)
    return _light("hdri-2048", image)


#: name -> light, in report order.
LIGHTS: dict[str, StabilityLight] = {light.name: light for light in (
    StabilityLight("black", black, 1.0, "all-black light: the image must be black"),
    StabilityLight("huge-constant", huge_constant, 1.0 / HUGE_RADIANCE,
                   f"constant radiance {HUGE_RADIANCE:.0e}, exposure scaled back"),
    StabilityLight("below-horizon", below_horizon, 1.0,
                   "light only below the horizon: SH ringing onto up-facing surfaces"),
    StabilityLight("single-texel", single_texel, 1.0,
                   "one bright texel of a black 512x256 map (irradiance pi)"),
    StabilityLight("sun-0.1deg", near_delta_sun, 1.0,
                   f"0.1 deg sun at {SUN_DYNAMIC_RANGE:.0e}:1 over its background (irradiance pi)"),
    StabilityLight("hdri-2048", hdri_2048, 1.0, "the sky resampled to a 2048x1024 map"),
)}
