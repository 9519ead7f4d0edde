"""Importance sampling of an environment light: directions drawn where its radiance is.

The lat-long map is interpolated bilinearly between its samples
(:meth:`prtbench.transport.lights.EnvironmentLight.radiance`), so the natural pieces are its
interpolation cells: cell (j, i) lies between sample rows j, j+1 (θ = πj/(H−1) …) and sample
columns i, i+1 (φ = 2π(i+½)/W …, wrapping). The radiance inside a cell never exceeds its
brightest corner, so a cell's probability is proportional to its brightest corner's luminance
times its solid angle -- every direction with light has a non-zero density -- mixed with a
small share proportional to solid angle alone (:data:`UNIFORM_SHARE`), so a density can never
be far below the light's and a rare bright texel cannot starve the rest. Inside a cell,
directions are uniform in solid angle (φ uniform, cos θ uniform), so the density of a
direction is exactly ``P(cell) / Ω(cell)``: what multiple importance sampling needs to weigh
these samples against BRDF samples (Veach 1997, the balance heuristic).

Building a sampler is per-light work (one pass over the map and a cumulative sum): a renderer
does it when the light changes, not per frame.
"""

from __future__ import annotations

import numpy as np

from prtbench.transport.latlong import lat_long_uv
from prtbench.transport.lights import LUMINANCE_WEIGHTS, EnvironmentLight

#: Share of the probability spread by solid angle alone, whatever the radiance.
UNIFORM_SHARE = 0.05


class EnvironmentSampler:
    """Draws directions from an environment light in proportion to (a bound on) its radiance.

    Parameters
    ----------
    light : EnvironmentLight
        The map, (H, W, 3) in Mitsuba's lat-long layout.

    Attributes
    ----------
    cell_probability : ndarray, shape (H−1, W), float64
        Probability of each interpolation cell, summing to 1.
    cell_solid_angle : ndarray, shape (H−1, W), float64
        Solid angle of each cell (sums to 4π).
    """

    def __init__(self, light: EnvironmentLight):
        h, w = light.height, light.width
        self.height, self.width = h, w
        lum = np.maximum(light.image.astype(np.float64) @ LUMINANCE_WEIGHTS, 0.0)
        corners = np.maximum(np.maximum(lum[:-1], lum[1:]),  # rows j and j+1 ...
                             np.maximum(np.roll(lum[:-1], -1, axis=1),  # ... columns i, i+1
                                        np.roll(lum[1:], -1, axis=1)))
        theta = np.pi * np.arange(h) / (h - 1)
        band = np.cos(theta[:-1]) - np.cos(theta[1:])  # ∫ sin θ dθ over each cell row
        self.cell_solid_angle = np.repeat((band * 2.0 * np.pi / w)[:, None], w, axis=1)
        weight = corners * self.cell_solid_angle
        total = weight.sum()
        uniform = self.cell_solid_angle / (4.0 * np.pi)
        if total > 0:
            self.cell_probability = (1.0 - UNIFORM_SHARE) * weight / total \
                + UNIFORM_SHARE * uniform
        else:  # a black light: any direction will do (it contributes nothing)
            self.cell_probability = uniform
        self._cdf = np.cumsum(self.cell_probability.reshape(-1))
        self._cdf /= self._cdf[-1]
        self._cos_theta = np.cos(theta)

    def sample(self, xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Directions for uniform numbers ``xi``.

        Parameters
        ----------
        xi : ndarray, shape (..., 3)
            Uniform [0, 1) numbers: the cell, then φ and cos θ inside it.

        Returns
        -------
        directions : ndarray, shape (..., 3), float64
            Unit directions (towards the light).
        pdf : ndarray, shape (...), float64
            Density per steradian of each direction under this sampler.
        """
        xi = np.asarray(xi, dtype=np.float64)
        shape = xi.shape[:-1]
        flat = np.minimum(np.searchsorted(self._cdf, xi[..., 0].reshape(-1), side="right"),
                          self._cdf.size - 1)
        j, i = np.divmod(flat, self.width)
        u = (i + 0.5 + xi[..., 1].reshape(-1)) / self.width
        phi = 2.0 * np.pi * u
        cos_theta = self._cos_theta[j] + (self._cos_theta[j + 1] - self._cos_theta[j]) \
            * xi[..., 2].reshape(-1)
        sin_theta = np.sqrt(np.maximum(1.0 - cos_theta * cos_theta, 0.0))
        dirs = np.stack([np.sin(phi) * sin_theta, cos_theta, -np.cos(phi) * sin_theta], axis=-1)
        pdf = self.cell_probability[j, i] / self.cell_solid_angle[j, i]
        return dirs.reshape(*shape, 3), pdf.reshape(shape)

    def pdf(self, directions: np.ndarray) -> np.ndarray:
        """Density per steradian with which :meth:`sample` draws ``directions`` (..., 3)."""
        d = np.asarray(directions, dtype=np.float64)
        shape = d.shape[:-1]
        u, v = lat_long_uv(d.reshape(-1, 3))
        x = u * self.width - 0.5
        i = np.floor(x - self.width * np.floor(x / self.width)).astype(np.int64) % self.width
        j = np.minimum(np.floor(np.clip(v, 0.0, 1.0) * (self.height - 1)).astype(np.int64),
                       self.height - 2)
        return (self.cell_probability[j, i] / self.cell_solid_angle[j, i]).reshape(shape)

    def resident_bytes(self) -> int:
        """Bytes the sampler keeps (cell tables and the cumulative distribution)."""
        return int(self.cell_probability.nbytes + self.cell_solid_angle.nbytes
                   + self._cdf.nbytes + self._cos_theta.nbytes)
