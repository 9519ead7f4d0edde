"""Seeded procedural environments (prtbench.transport.random_lights): reproducible and varied."""

from __future__ import annotations

import numpy as np
import pytest

from prtbench.transport.random_lights import (
    SOURCE_ELEVATION_DEG,
    random_environment,
    random_environments,
)


def test_an_environment_is_a_pure_function_of_seed_and_index():
    first = random_environment(3, seed=7)
    again = random_environment(3, seed=7)
    assert first.name == again.name == "random1-7-3"
    assert first.content_hash() == again.content_hash()
    others = {random_environment(i, seed=s).content_hash() for s, i in ((7, 4), (8, 3), (0, 0))}
    assert first.content_hash() not in others and len(others) == 3
    assert [lt.name for lt in random_environments(2, seed=1)] == ["random1-1-0", "random1-1-1"]


def test_environments_span_source_elevations_and_stay_in_the_hdris_power_range():
    lights = random_environments(48, seed=0)
    elevations = np.degrees(np.arcsin([lt.brightest_direction()[1] for lt in lights]))
    # Texel centres: the brightest texel sits within a texel (0.7 deg) of a source's centre.
    assert elevations.min() >= SOURCE_ELEVATION_DEG[0] - 1.0
    assert elevations.max() <= SOURCE_ELEVATION_DEG[1] + 1.0
    # Low suns (sunrise, sunset: 3-8 deg) and high ones are both common, not extrapolations.
    assert np.sum(elevations < 15.0) >= 6 and np.sum(elevations > 50.0) >= 6, elevations
    power = np.array([lt.total_power().mean() for lt in lights])
    # Our HDRIs' mean total power spans 2.3 (night) to 13 (interior); a random map's sources
    # deliver pi/4..2.5 pi each (1-3 of them) over a dim sky.
    assert power.min() > 0.5 and power.max() < 40.0, power
    assert np.isfinite(np.stack([lt.image for lt in lights])).all()


def test_bad_counts_are_refused():
    with pytest.raises(ValueError, match="index=-1"):
        random_environment(-1)
    with pytest.raises(ValueError, match="count=2.5"):
        random_environments(2.5)
