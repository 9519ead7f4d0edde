"""Analytic lights of the data-driven method and the lighting families its datasets draw from.

The paper (Belcour et al. 2022, §4.1) builds its dataset from "many random lighting
configurations": spot lights placed around the asset. prtbench's light registry holds only
environment maps, so the delta lights live here:

* :class:`PointLight`: radiant intensity I (W/sr, RGB) at a position; E = I cos / d².
* :class:`SpotLight`: a point light with Mitsuba 3's ``spot`` profile: full intensity inside
  ``beam_width``, a linear ramp in angle down to 0 at ``cutoff_angle``, black outside.
* :class:`DirectionalLight`: irradiance E (RGB) on a surface facing ``to_light``.

An :class:`~prtbench.transport.lights.EnvironmentLight` is drawn at run time as ``k`` directional lights
from Debevec's median-cut sampling of the map (each region's power at its energy centroid), the
usual way a rasteriser shadows an environment; the bake and the reference see the map itself.

The lighting families a dataset draws from are in :mod:`.families`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Union

import numpy as np

from prtbench.api.errors import InvalidInputError
from prtbench.transport.lights import EnvironmentLight

Rgb = tuple[float, float, float]


def _rgb(value: Any, what: str) -> Rgb:
    rgb = tuple(float(c) for c in np.broadcast_to(np.asarray(value, dtype=np.float64), (3,)))
    if not all(math.isfinite(c) and c >= 0 for c in rgb):
        raise InvalidInputError(f"{what}={value!r}; accepted: 3 finite values >= 0")
    return rgb


def _unit(value: Any, what: str) -> tuple[float, float, float]:
    v = np.asarray(value, dtype=np.float64).reshape(3)
    n = float(np.linalg.norm(v))
    if not math.isfinite(n) or n == 0:
        raise InvalidInputError(f"{what}={value!r}; accepted: a finite non-zero 3-vector")
    return tuple(float(c) for c in v / n)


@dataclass(frozen=True)
class PointLight:
    """Isotropic point light.

    Attributes
    ----------
    position : 3 floats
    intensity : RGB
        Radiant intensity (W/sr); a surface at distance d facing it receives I / d².
    name : str
    """

    position: tuple[float, float, float]
    intensity: Rgb = (1.0, 1.0, 1.0)
    name: str = "point"

    def __post_init__(self) -> None:
        object.__setattr__(self, "position", tuple(float(c) for c in np.reshape(self.position, 3)))
        object.__setattr__(self, "intensity", _rgb(self.intensity, "point light intensity"))

    def mitsuba_dict(self) -> dict[str, Any]:
        return {"type": "point", "position": list(self.position),
                "intensity": {"type": "rgb", "value": list(self.intensity)}}


@dataclass(frozen=True)
class SpotLight:
    """Spot light with Mitsuba's linear angular falloff.

    Attributes
    ----------
    position : 3 floats
    direction : 3 floats
        Axis of the cone (the way the light shines), normalised.
    cutoff_deg : float
        Half-angle beyond which the light is black, (0, 90].
    beam_deg : float or None
        Half-angle of full intensity; default ¾ of ``cutoff_deg`` (Mitsuba's default).
    intensity : RGB
        Radiant intensity on the axis (W/sr).
    name : str
    """

    position: tuple[float, float, float]
    direction: tuple[float, float, float]
    cutoff_deg: float = 30.0
    beam_deg: float | None = None
    intensity: Rgb = (1.0, 1.0, 1.0)
    name: str = "spot"

    def __post_init__(self) -> None:
        object.__setattr__(self, "position", tuple(float(c) for c in np.reshape(self.position, 3)))
        object.__setattr__(self, "direction", _unit(self.direction, "spot direction"))
        object.__setattr__(self, "intensity", _rgb(self.intensity, "spot intensity"))
        cutoff = float(self.cutoff_deg)
        beam = 0.75 * cutoff if self.beam_deg is None else float(self.beam_deg)
        if not (0.0 < cutoff <= 90.0 and 0.0 <= beam < cutoff):
            raise InvalidInputError(f"spot cutoff_deg={self.cutoff_deg}, beam_deg={self.beam_deg}; "
                                    "accepted: 0 < cutoff <= 90 and 0 <= beam < cutoff")
        object.__setattr__(self, "cutoff_deg", cutoff)
        object.__setattr__(self, "beam_deg", beam)

    def falloff(self, emitted: np.ndarray) -> np.ndarray:
        """Mitsuba's profile for unit directions ``emitted`` (N, 3) leaving the light, (N,)."""
        cos_t = np.clip(np.asarray(emitted, dtype=np.float64) @ np.asarray(self.direction), -1, 1)
        cutoff, beam = math.radians(self.cutoff_deg), math.radians(self.beam_deg)
        ramp = (cutoff - np.arccos(cos_t)) / (cutoff - beam)
        inner = np.where(cos_t >= math.cos(beam), 1.0, ramp)
        return np.where(cos_t > math.cos(cutoff), inner, 0.0)

    def mitsuba_dict(self) -> dict[str, Any]:
        import mitsuba as mi

        target = np.asarray(self.position) + np.asarray(self.direction)
        up = [0.0, 1.0, 0.0] if abs(self.direction[1]) < 0.9 else [1.0, 0.0, 0.0]
        return {"type": "spot", "cutoff_angle": self.cutoff_deg, "beam_width": self.beam_deg,
                "intensity": {"type": "rgb", "value": list(self.intensity)},
                "to_world": mi.ScalarTransform4f().look_at(
                    origin=list(self.position), target=[float(c) for c in target], up=up)}


@dataclass(frozen=True)
class DirectionalLight:
    """Distant light (sun-like delta).

    Attributes
    ----------
    to_light : 3 floats
        Unit direction from the scene towards the light.
    irradiance : RGB
        Irradiance on a surface facing the light (W/m²).
    name : str
    """

    to_light: tuple[float, float, float]
    irradiance: Rgb = (1.0, 1.0, 1.0)
    name: str = "directional"

    def __post_init__(self) -> None:
        object.__setattr__(self, "to_light", _unit(self.to_light, "directional to_light"))
        object.__setattr__(self, "irradiance", _rgb(self.irradiance, "directional irradiance"))

    def mitsuba_dict(self) -> dict[str, Any]:
        # Mitsuba's `direction` is the way the light travels.
        return {"type": "directional", "direction": [-c for c in self.to_light],
                "irradiance": {"type": "rgb", "value": list(self.irradiance)}}


AnalyticLight = Union[PointLight, SpotLight, DirectionalLight]


@dataclass(frozen=True)
class LightSet:
    """Several analytic lights lit together (one lighting configuration).

    Attributes
    ----------
    lights : tuple of analytic lights
    name : str
    """

    lights: tuple = ()
    name: str = "lights"
    meta: dict = field(default_factory=dict, compare=False)


def light_name(light: Any) -> str:
    return str(getattr(light, "name", type(light).__name__))


def is_environment(light: Any) -> bool:
    return hasattr(light, "image") and hasattr(light, "radiance")


# --- environment maps ------------------------------------------------------------------------

def rotate_environment(light: Any, columns: int, *, name: str | None = None):
    """``light`` turned about +Y by ``columns`` lat-long columns (exact: a roll of the image)."""

    k = int(columns) % light.width
    return EnvironmentLight(name or f"{light.name}@{k}", np.roll(light.image, k, axis=1),
                            source=f"{light.source}|roll {k}")


class EnvironmentRotations(Sequence):
    """Rotations of one environment map, each built when indexed (maps are large)."""

    def __init__(self, environment: Any, columns: Sequence[int]):
        self.environment = environment
        self.columns = [int(c) for c in columns]

    def __len__(self) -> int:
        return len(self.columns)

    def __getitem__(self, index):
        if isinstance(index, slice):
            return EnvironmentRotations(self.environment, self.columns[index])
        return rotate_environment(self.environment, self.columns[index])


def median_cut(light: Any, count: int, *, max_height: int = 128) -> list[DirectionalLight]:
    """Debevec's median-cut sampling of an environment map into ``count`` directional lights.

    The map is summed to at most ``max_height`` rows with its exact texel solid angles, then
    split recursively across its longer side (width measured at the region's mean latitude) at
    the luminance median; each region becomes a light at its energy centroid carrying the
    region's RGB power ∫ L dω (so a surface facing all of them unshadowed receives the right
    irradiance to first order). ``count`` is rounded down to a power of two.

    Returns
    -------
    list of DirectionalLight
        Regions without energy are dropped.
    """
    if count < 1:
        raise InvalidInputError(f"median-cut light count {count}; accepted: >= 1")
    image = light.image.astype(np.float64)
    omega = light.texel_solid_angles()
    dirs = light.texel_directions()
    h, w = image.shape[:2]
    factor = max(1, int(math.ceil(h / max_height)))
    hh, ww = h // factor, w // factor
    if hh < 2:
        factor, hh, ww = 1, h, w
    crop = (slice(0, hh * factor), slice(0, ww * factor))
    power = (image * omega[..., None])[crop].reshape(hh, factor, ww, factor, 3).sum(axis=(1, 3))
    # Leftover rows (when h is not a multiple) are folded into the last row so no energy is lost.
    if hh * factor < h:
        power[-1] += (image * omega[..., None])[hh * factor:, :ww * factor].reshape(
            -1, ww, factor, 3).sum(axis=(0, 2))
    wdir = (dirs * (image @ np.array([0.212671, 0.715160, 0.072169]) * omega)[..., None])
    wdir = wdir[: hh * factor, : ww * factor].reshape(hh, factor, ww, factor, 3).sum(axis=(1, 3))
    lum = power @ np.array([0.212671, 0.715160, 0.072169])
    theta = (np.arange(hh) + 0.5) / hh * np.pi
    levels = int(math.floor(math.log2(count)))
    regions = [(0, hh, 0, ww)]
    for _ in range(levels):
        nxt = []
        for r0, r1, c0, c1 in regions:
            block = lum[r0:r1, c0:c1]
            height = r1 - r0
            width = (c1 - c0) * math.sin(float(theta[r0:r1].mean()))
            if (height >= width and height > 1) or (c1 - c0) <= 1:
                axis_sum = np.cumsum(block.sum(axis=1))
                cut = r0 + int(np.searchsorted(axis_sum, axis_sum[-1] / 2)) + 1
                cut = min(max(cut, r0 + 1), r1 - 1) if height > 1 else r1
                nxt += [(r0, cut, c0, c1)] + ([(cut, r1, c0, c1)] if cut < r1 else [])
            else:
                axis_sum = np.cumsum(block.sum(axis=0))
                cut = c0 + int(np.searchsorted(axis_sum, axis_sum[-1] / 2)) + 1
                cut = min(max(cut, c0 + 1), c1 - 1)
                nxt += [(r0, r1, c0, cut), (r0, r1, cut, c1)]
        regions = nxt
    lights = []
    for k, (r0, r1, c0, c1) in enumerate(regions):
        rgb = power[r0:r1, c0:c1].reshape(-1, 3).sum(axis=0)
        centroid = wdir[r0:r1, c0:c1].reshape(-1, 3).sum(axis=0)
        if rgb.max() <= 0 or np.linalg.norm(centroid) == 0:
            continue
        lights.append(DirectionalLight(tuple(centroid), tuple(np.maximum(rgb, 0.0)),
                                       name=f"{light.name}/mc{k}"))
    return lights


def analytic_lights(light: Any, *, env_lights: int) -> list[AnalyticLight]:
    """The analytic lights a renderer draws for ``light``.

    Parameters
    ----------
    light : EnvironmentLight, analytic light, LightSet or sequence of analytic lights
    env_lights : int
        Median-cut lights per environment map.
    """
    if is_environment(light):
        return median_cut(light, env_lights)
    if isinstance(light, (PointLight, SpotLight, DirectionalLight)):
        return [light]
    if isinstance(light, LightSet):
        return list(light.lights)
    if isinstance(light, (list, tuple)):
        out: list[AnalyticLight] = []
        for item in light:
            out += analytic_lights(item, env_lights=env_lights)
        return out
    raise InvalidInputError(f"light of type {type(light).__name__}; accepted: EnvironmentLight, "
                            "PointLight, SpotLight, DirectionalLight, LightSet")


# --- families --------------------------------------------------------------------------------

def light_spec(light: Any) -> Any:
    """JSON-able identity of a light (for cache keys)."""
    if is_environment(light):
        return {"env": light.content_hash()}
    if isinstance(light, LightSet):
        return [light_spec(item) for item in light.lights]
    if isinstance(light, (list, tuple)):
        return [light_spec(item) for item in light]
    return {"type": type(light).__name__, **{k: v for k, v in light.__dict__.items()
                                             if k != "name"}}
