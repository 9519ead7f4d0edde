"""Scene parameters are declared (type, range, memory estimate) and checked in one place."""

from __future__ import annotations

import inspect

import pytest

from prtbench.api.errors import InvalidInputError
from prtbench.scene import params as P
from prtbench.scene.registry import SCENES, get_scene


def _builders():
    return [(name, SCENES.get(name)) for name in SCENES.names()]


def test_every_builder_declares_every_parameter_and_its_defaults_pass():
    for name, builder in _builders():
        specs = getattr(builder, "scene_params", None)
        assert specs is not None, f"scene '{name}' registered without params="
        signature = inspect.signature(builder).parameters
        accepted = [p for p in signature if p != "variant"]
        assert sorted(specs) == sorted(accepted), name
        for key, spec in specs.items():
            default = signature[key].default
            assert isinstance(default, spec.kind), (name, key, default, spec.kind)
            # The defaults sit inside their own declared range.
            assert P.check_params(name, {key: spec}, {key: default}) == {key: default}


def test_neural_bunny_sizes_match_the_network_table():
    from prtbench.transport.neural_sdf import SIZES

    spec = SCENES.get("sdf-bunny-neural").scene_params["size"]
    assert set(spec.choices) == set(SIZES)


def test_command_line_strings_are_typed_like_python_values():
    kw = dict(size="2.5", subdivisions="3")
    a = get_scene("plane", **kw)
    b = get_scene("plane", size=2.5, subdivisions=3)
    assert a.params == b.params == {"size": 2.5, "subdivisions": 3}
    assert a.content_hash() == b.content_hash()
    assert get_scene("room", normal_mapped_floor="true").params["normal_mapped_floor"] is True


def test_memory_bound_is_the_largest_count_that_fits():
    spec = P.grid_subdivisions()
    budget = 1 << 30
    k = spec.memory_high(budget)
    # 2·k² triangles at BYTES_PER_TRIANGLE bytes each fit, 2·(k+1)² do not.
    assert 2 * k * k * P.BYTES_PER_TRIANGLE <= budget < 2 * (k + 1) ** 2 * P.BYTES_PER_TRIANGLE
    assert P.check_params("plane", {"subdivisions": spec}, {"subdivisions": k},
                          budget=budget) == {"subdivisions": k}
    with pytest.raises(InvalidInputError) as info:
        P.check_params("plane", {"subdivisions": spec}, {"subdivisions": k + 1}, budget=budget)
    message = str(info.value)
    assert f"subdivisions={k + 1}" in message and f"accepted: integers 1..{k}" in message
    assert "(≤ 1.0 GiB, this machine's memory)" in message
    # The example: 100000 subdivisions ask for 2e10 triangles.
    with pytest.raises(InvalidInputError, match=r"2e\+10 triangles \(9\.3 TiB\)"):
        P.check_params("plane", {"subdivisions": spec}, {"subdivisions": 100_000},
                       budget=budget)


def test_marching_cubes_resolution_counts_its_grid():
    spec = SCENES.get("sdf-car").scene_params["mc_resolution"]
    assert spec.bytes(1024) >= 5 * 1024**3  # the float32 grid and its mask alone
    with pytest.raises(InvalidInputError, match="mc_resolution=1024"):
        P.check_params("sdf-car", {"mc_resolution": spec}, {"mc_resolution": 1024},
                       budget=4 << 30)
    with pytest.raises(InvalidInputError, match="integers 16..1024"):
        P.check_params("sdf-car", {"mc_resolution": spec}, {"mc_resolution": 4096})


@pytest.mark.parametrize("value", ["-1", "0", "nan", "inf", "-inf", "1e7", "abc", True])
def test_lengths_must_be_positive_finite_numbers(value):
    with pytest.raises(InvalidInputError, match=r"accepted: finite numbers in \(0, 1e\+06\]"):
        get_scene("plane", size=value)


def test_scenes_far_from_the_origin_relative_to_their_size_are_accepted_and_conditioned():
    """Mitsuba's offset grows with max|p|: a small scene far away would lose its shadows as
    built, so it is accepted and rendered in the canonical frame instead (DESIGN.md §22)."""
    from prtbench.scene.frame import is_conditioned
    from prtbench.scene.geometry import grid_plane

    def plane_at(x: float, size: float):
        positions = grid_plane(size, 1, center=(x, 0.0, 0.0)).positions
        return positions.min(axis=0), positions.max(axis=0)

    for x, size in ((0.0, 1.0), (100.0, 2.0), (1000.0, 0.1)):
        P.check_extent("moved", *plane_at(x, size), {"x": x})
    assert is_conditioned(*plane_at(0.0, 1.0))
    assert not is_conditioned(*plane_at(100.0, 2.0))  # offset 9e-3 > 0.1 % of 2.8
    assert not is_conditioned(*plane_at(1000.0, 0.1))
