"""Seeded procedural environments for training on many lights.

Learnt transport (the neural wavelet method) generalises to a held-out light only as far as its
training lights span light space: Raghavan et al. 2023 train on about 1000 HDR maps, each at
three rotations, where prtbench ships eight HDRIs and three analytic lights. A random
environment here is the analytic ``sky``/``sun`` recipe with every parameter drawn:

* a background: zenith and horizon colours blended over the upper hemisphere and a ground
  colour below a soft horizon, each a random hue at a log-uniform intensity;
* one to three sources: discs (the ``sun`` profile, limb-darkened, anti-aliased edge) of
  log-uniform angular radius in [1.5°, 25°] delivering a log-uniform irradiance in [π/4, 2.5π]
  at normal incidence, inside a glow (the ``sky`` light's exp((cos γ − 1)/w), w log-uniform
  in [0.005, 0.2], peak up to half the background's zenith-to-horizon scale), at a random
  azimuth and an elevation uniform in [−5°, 80°] (so low sources, as at sunrise, are as
  likely as high ones), each of a random warm-to-cool colour.

The i-th environment of a seed is a pure function of (seed, i): the same lights, bit for bit,
on every machine, so they can sit in a cache key by their knobs alone.
"""

from __future__ import annotations

import math

import numpy as np

from prtbench.transport.lights import EnvironmentLight
from prtbench.transport.procedural import add_sun, grid_directions, smoothstep, sun_direction

#: Rows of a random environment's lat-long map (texel ≈ 0.7°, finer than the smallest source).
RANDOM_HEIGHT = 256
#: Bump when the recipe changes: it is part of every random light's name.
RANDOM_VERSION = 1
SOURCE_RADIUS_DEG = (1.5, 25.0)
SOURCE_IRRADIANCE = (0.25 * math.pi, 2.5 * math.pi)
SOURCE_ELEVATION_DEG = (-5.0, 80.0)


def _log_uniform(rng: np.random.Generator, low: float, high: float) -> float:
    return float(math.exp(rng.uniform(math.log(low), math.log(high))))


def _colour(rng: np.random.Generator, saturation: float) -> np.ndarray:
    """A random RGB of unit mean, ``saturation`` in [0, 1] away from grey."""
    hue = rng.dirichlet(np.ones(3))
    colour = (1.0 - saturation) + saturation * 3.0 * hue
    return colour / colour.mean()


def _warm_to_cool(rng: np.random.Generator) -> np.ndarray:
    """A source colour between a warm (sunrise) and a cool (overcast) white, unit mean."""
    t = rng.uniform()
    warm, cool = np.array([1.0, 0.62, 0.32]), np.array([0.75, 0.88, 1.15])
    colour = (1.0 - t) * warm + t * cool
    return colour / colour.mean()


def random_environment(index: int, *, seed: int = 0) -> EnvironmentLight:
    """The ``index``-th random environment of ``seed`` (module docstring); name
    ``random<version>-<seed>-<index>``."""
    if int(index) != index or index < 0:
        raise ValueError(f"index={index!r}; accepted: integers >= 0")
    rng = np.random.default_rng([int(seed), int(index), 0x524C])  # stream tag "RL"
    dirs = grid_directions(RANDOM_HEIGHT)
    y = dirs[..., 1]
    zenith = _log_uniform(rng, 0.05, 1.0) * _colour(rng, 0.6)
    horizon = _log_uniform(rng, 0.05, 1.0) * _colour(rng, 0.6)
    ground = _log_uniform(rng, 0.01, 0.3) * _colour(rng, 0.4)
    blend = ((1.0 - np.clip(y, 0.0, 1.0)) ** rng.uniform(1.0, 6.0))[..., None]
    upper = zenith * (1.0 - blend) + horizon * blend
    softness = math.radians(rng.uniform(1.0, 10.0))
    above = smoothstep(-softness, softness, np.arcsin(np.clip(y, -1.0, 1.0)))[..., None]
    image = upper * above + ground * (1.0 - above)
    scale = float(np.mean(zenith + horizon))
    for _ in range(int(rng.integers(1, 4))):
        direction = sun_direction(rng.uniform(*SOURCE_ELEVATION_DEG), rng.uniform(0.0, 360.0))
        colour = _warm_to_cool(rng)
        cos_gamma = np.clip(dirs @ direction, -1.0, 1.0)
        glow = rng.uniform(0.0, 0.5) * scale * np.exp((cos_gamma - 1.0)
                                                      / _log_uniform(rng, 0.005, 0.2))
        image = image + glow[..., None] * colour
        add_sun(image, dirs, direction, _log_uniform(rng, *SOURCE_RADIUS_DEG),
                 _log_uniform(rng, *SOURCE_IRRADIANCE), colour)
    name = f"random{RANDOM_VERSION}-{int(seed)}-{int(index)}"
    return EnvironmentLight(name, image.astype(np.float32), source=f"procedural:{name}")


def random_environments(count: int, *, seed: int = 0) -> list[EnvironmentLight]:
    """The first ``count`` random environments of ``seed``."""
    if int(count) != count or count < 0:
        raise ValueError(f"count={count!r}; accepted: integers >= 0")
    return [random_environment(i, seed=seed) for i in range(int(count))]
