"""Building blocks of procedural environment maps: directions of a lat-long grid, sun discs with
an exact irradiance, smooth horizons. The built-in lights (``scenes/lights.py``), the random
training lights (:mod:`prtbench.transport.random_lights`) and the stability matrix's extreme
lights are drawn with them.
"""

from __future__ import annotations

import math

import numpy as np

from prtbench.transport.latlong import lat_long_directions

#: Rows of a procedural light's lat-long image (columns: twice as many).
PROCEDURAL_HEIGHT = 512


def sun_direction(elevation_deg: float, azimuth_deg: float) -> np.ndarray:
    """Direction at ``elevation_deg`` above the horizon, ``azimuth_deg`` from +Z towards +X."""
    el, az = math.radians(elevation_deg), math.radians(azimuth_deg)
    return np.array([math.cos(el) * math.sin(az), math.sin(el), math.cos(el) * math.cos(az)])


def grid_directions(height: int) -> np.ndarray:
    """Sample directions (H, 2H, 3) of a lat-long image of ``height`` rows."""
    w = 2 * height
    u = (np.arange(w) + 0.5) / w
    v = np.arange(height) / (height - 1)
    return lat_long_directions(u[None, :], v[:, None])


def smoothstep(edge0: float, edge1: float, x: np.ndarray) -> np.ndarray:
    t = np.clip((x - edge0) / (edge1 - edge0), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def disc_profile(angle: np.ndarray, radius: float, edge: float) -> np.ndarray:
    """Limb-darkened disc of angular ``radius`` with a smooth ``edge`` (both radians), peak 1.

    The peak at the centre makes the brightest texel the one nearest the disc's centre.
    """
    r = np.clip(angle / radius, 0.0, 1.0)
    limb = 1.0 - 0.6 * (1.0 - np.sqrt(1.0 - r * r))
    return limb * (1.0 - smoothstep(radius - edge, radius + edge, angle))


def disc_irradiance_per_unit(radius: float, edge: float) -> float:
    """∫ profile(γ) cos γ dω around the disc axis (analytic profile; Gauss–Legendre pieces).

    The pieces split at the profile's kinks (start of the edge, rim, end of the edge).
    """
    nodes, weights = np.polynomial.legendre.leggauss(48)
    total = 0.0
    for lo, hi in ((0.0, radius - edge), (radius - edge, radius), (radius, radius + edge)):
        gamma = lo + 0.5 * (hi - lo) * (nodes + 1.0)
        integrand = disc_profile(gamma, radius, edge) * np.cos(gamma) * np.sin(gamma)
        total += 0.5 * (hi - lo) * float(np.sum(weights * integrand))
    return 2.0 * np.pi * total


def add_sun(image: np.ndarray, dirs: np.ndarray, direction: np.ndarray, radius_deg: float,
             irradiance: float, color: np.ndarray) -> None:
    """Add a sun disc delivering ``irradiance`` (analytically) at normal incidence."""
    radius = math.radians(radius_deg)
    texel = np.pi / (image.shape[0] - 1)
    edge = 0.5 * texel  # anti-aliasing: the edge spans about one texel
    angle = np.arccos(np.clip(dirs @ direction, -1.0, 1.0))
    scale = irradiance / disc_irradiance_per_unit(radius, edge)
    image += (scale * disc_profile(angle, radius, edge))[..., None] * color
