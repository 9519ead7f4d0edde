"""prtbench.transport.env_sampling: directions drawn where an environment's light is."""

from __future__ import annotations

import numpy as np
import pytest

from prtbench.transport.env_sampling import EnvironmentSampler
from prtbench.transport.lights import get_light


@pytest.mark.parametrize("name", ["sky", "sun", "white"])
def test_sampled_densities_are_the_densities_of_the_sampled_directions(name):
    sampler = EnvironmentSampler(get_light(name))
    dirs, pdf = sampler.sample(np.random.default_rng(0).random((20_000, 3)))
    assert np.allclose(np.linalg.norm(dirs, axis=1), 1.0)
    assert np.allclose(sampler.pdf(dirs), pdf, rtol=1e-9)
    assert (pdf > 0).all()


@pytest.mark.parametrize("name", ["sky", "sun", "purple"])
def test_the_density_integrates_to_one_and_radiance_over_density_to_the_power(name):
    light = get_light(name)
    sampler = EnvironmentSampler(light)
    # ∫ pdf dω = 1: each cell's density is constant and its cells tile the sphere.
    assert float((sampler.cell_probability).sum()) == pytest.approx(1.0, abs=1e-12)
    assert float(sampler.cell_solid_angle.sum()) == pytest.approx(4 * np.pi, rel=1e-12)
    # Importance sampling is unbiased: E[L(ω)/p(ω)] = ∫ L dω, the light's exact total power.
    dirs, pdf = sampler.sample(np.random.default_rng(1).random((400_000, 3)))
    estimate = (light.radiance(dirs) / pdf[:, None]).mean(axis=0)
    assert estimate == pytest.approx(light.total_power(), rel=0.01)


def test_a_bright_source_gets_most_samples_and_dark_sky_still_some():
    light = get_light("sun")
    sampler = EnvironmentSampler(light)
    dirs, _ = sampler.sample(np.random.default_rng(2).random((10_000, 3)))
    near_sun = dirs @ light.brightest_direction() > np.cos(np.radians(5.0))
    # The sun's few degrees hold under 1 % of the sphere but most of the draws; the uniform
    # share keeps every other direction reachable.
    assert near_sun.mean() > 0.5 and (~near_sun).sum() > 100
