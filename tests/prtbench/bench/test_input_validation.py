"""Ordinary but bad values are one-line errors (exit 2) that write nothing (issue #12 §2).

Every case goes through ``prtbench.cli.main`` as a user would: the error line must name the
bad value and what is accepted, and the output folder, the results store and the cache must
stay empty (nothing half-written).
"""

from __future__ import annotations

import dataclasses
import typing

import numpy as np
import pytest

from prtbench.api.config import SEED_HIGH
from prtbench.api.errors import InvalidInputError
from prtbench.api.method import METHODS
from prtbench.cli import main
from prtbench.io import imageio
from prtbench.render import mitsuba_variant, reference
from prtbench.transport.lights import MAX_RADIANCE


def _run_fails(tmp_path, monkeypatch, capfd, argv):
    """Run ``prtbench run ARGV``; returns its stderr after checking exit 2 and no writes."""
    cache = tmp_path / "cache"
    monkeypatch.setenv("PRTBENCH_CACHE", str(cache))
    out, results = tmp_path / "out", tmp_path / "results.sqlite"
    status = main(["run", *argv, "--profile", "smoke", "--out", str(out), "--results",
                   str(results)])
    captured = capfd.readouterr()
    err = captured.err.strip()
    assert status == 2, err
    # One line on stderr and nothing from libraries on stdout (capfd sees file descriptors).
    assert err.startswith("prtbench: error: ") and "\n" not in err, err
    assert captured.out.strip() == ""
    assert not out.exists() and not results.exists()
    assert not cache.exists() or not any(p.is_file() for p in cache.rglob("*"))
    return err


@pytest.mark.parametrize("argv, fragments", [
    # Method knobs: seeds are uint32 for every RNG here.
    (["--method", "vertex", "--scene", "plane", "--set", "seed=-1"],
     ["'seed'", "-1", f"[0, {SEED_HIGH}]"]),
    (["--method", "vertex", "--scene", "plane", "--set", f"seed={SEED_HIGH + 1}"],
     ["'seed'", str(SEED_HIGH + 1)]),
    # Scene parameters: type, sign, finiteness, range.
    (["--method", "vertex", "--scene", "plants", "--scene-param", "seed=-1"],
     ["seed='-1'", "integers 0..4294967295"]),
    (["--method", "vertex", "--scene", "plane", "--scene-param", "size=-2"],
     ["size='-2'", "(0, 1e+06]"]),
    (["--method", "vertex", "--scene", "plane", "--scene-param", "size=0"], ["size='0'"]),
    (["--method", "vertex", "--scene", "plane", "--scene-param", "size=nan"], ["size='nan'"]),
    (["--method", "vertex", "--scene", "plane", "--scene-param", "size=inf"], ["size='inf'"]),
    (["--method", "vertex", "--scene", "sphere-over-plane", "--scene-param", "radius=-0.5"],
     ["radius='-0.5'"]),
    (["--method", "vertex", "--scene", "plane", "--scene-param", "subdivisions=2.5"],
     ["subdivisions='2.5'", "integers 1.."]),
    (["--method", "vertex", "--scene", "room", "--scene-param", "normal_mapped_floor=maybe"],
     ["normal_mapped_floor='maybe'", "true or false"]),
    # Memory: 2·k² triangles at 512 B each.
    (["--method", "vertex", "--scene", "plants", "--scene-param", "ground_subdivisions=100000"],
     ["ground_subdivisions='100000'", "2e+10 triangles", "TiB", "accepted: integers 1..",
      "this machine's memory"]),
    # Degenerate scenes: a size float32 rounds to 0 leaves every vertex at one point (any
    # other size is rendered in the canonical frame).
    (["--method", "vertex", "--scene", "plane", "--scene-param", "size=1e-50"],
     ["size=1e-50", "has zero extent (bounds diagonal 0", "accepted: a bounds diagonal > 0"]),
    (["--method", "vertex", "--scene", "sphere-over-plane", "--scene-param", "radius=1e-60",
      "--scene-param", "height=1e-59", "--scene-param", "plane_size=1e-58"],
     ["radius=1e-60", "height=1e-59", "plane_size=1e-58", "has zero extent"]),
    # Method knobs whose memory is a product of knobs (bytes estimated in validate()).
    (["--method", "texture-tp", "--scene", "plane", "--set", "texture_resolution=8192",
      "--set", "sh_bands=8", "--set", "bounces=8"],
     ["texture_resolution=8192", "would need 1013.0 GiB", "texture_resolution <="]),
    (["--method", "learnt", "--scene", "plane", "--set", "batch_size=4194304",
      "--set", "hidden=4096"],
     ["batch_size=4194304", "hidden=4096", "would need 1.0 TiB"]),
    (["--method", "data-driven", "--scene", "cornell", "--set", "configurations=4096",
      "--set", "lightmap_resolution=4096"],
     ["configurations=4096", "lightmap_resolution=4096", "would need 2.3 TiB"]),
    (["--method", "learnt", "--scene", "plane", "--set", "grid_cells=2,0,2"],
     ["'grid_cells'", "(2, 0, 2)", "[1, 64]"]),
])
def test_bad_values_are_one_line_errors(tmp_path, monkeypatch, capfd, argv, fragments):
    err = _run_fails(tmp_path, monkeypatch, capfd, argv)
    for fragment in fragments:
        assert fragment in err, (fragment, err)


def test_scenes_of_any_size_are_accepted_in_the_canonical_frame():
    """Sizes Mitsuba's absolute float32 ray offset could not render as built (a 1e-30 plane)
    are moved to the canonical frame (DESIGN.md §22); the builder's length bound still holds."""
    from prtbench.scene.registry import get_scene

    for size in (1e-30, 1e-6):
        scene = get_scene("plane", size=size)
        assert scene.diagonal() == pytest.approx(2.0, rel=1e-6)
        lo, hi = scene.world_bounds()
        assert float(np.linalg.norm(hi - lo)) == pytest.approx(size * np.sqrt(2), rel=1e-6)
    large = get_scene("plane", size=1e6)  # well conditioned as built: left as it is
    assert large.world_from_canonical.is_identity
    assert large.diagonal() == pytest.approx(1e6 * np.sqrt(2), rel=1e-6)
    with pytest.raises(InvalidInputError, match="size=2000000.0"):
        get_scene("plane", size=2e6)


def test_every_numeric_method_knob_declares_a_range():
    """Numeric knobs without bounds let -1 or 10**12 reach numpy; every one must declare both."""
    unbounded = []
    for name in METHODS.names():
        cls = METHODS.get(name).Config
        hints = typing.get_type_hints(cls)
        for f in dataclasses.fields(cls):
            tp = hints[f.name]
            numeric = tp in (int, float) or (typing.get_origin(tp) is tuple
                                             and typing.get_args(tp)[0] in (int, float))
            if numeric and not f.metadata.get("choices") and (
                    f.metadata.get("low") is None or f.metadata.get("high") is None):
                unbounded.append(f"{name}.{f.name}")
    assert unbounded == []
    seeds = [f for name in METHODS.names()
             for f in dataclasses.fields(METHODS.get(name).Config) if f.name == "seed"]
    assert len(seeds) >= 8
    assert all((f.metadata["low"], f.metadata["high"]) == (0, SEED_HIGH) for f in seeds)


def test_largest_seed_is_accepted():
    cfg = METHODS.get("vertex").make_config({"seed": str(SEED_HIGH)}, profile="smoke")
    assert cfg.seed == SEED_HIGH
    np.random.default_rng(cfg.seed)  # the RNGs take it


# --- lights -----------------------------------------------------------------------------------

def _latlong(value: float) -> np.ndarray:
    image = np.ones((16, 32, 3), np.float32)
    image[3, 5:9] = value
    return image


@pytest.mark.parametrize("value, fragment", [
    (1e30, f"exceed {MAX_RADIANCE:.3g} (max 1e+30), which overflows float32 in the reference"),
    (3e38, "overflows float32"),
    (np.inf, "not finite"),
    (-10.0, "negative"),
])
def test_bad_light_file_is_refused_before_anything_is_cached(tmp_path, monkeypatch, capfd,
                                                             value, fragment):
    path = tmp_path / "hot.exr"
    imageio.write_exr(path, _latlong(value))
    err = _run_fails(tmp_path, monkeypatch, capfd, [
        "--method", "vertex", "--scene", "plane", "--light", str(path)])
    assert "light 'hot'" in err and fragment in err, err


def test_bright_light_within_bound_renders_a_finite_reference(tmp_path, monkeypatch):
    """At MAX_RADIANCE the reference's float32 sums stay finite (the bound is not too loose)."""
    from prtbench.scene.registry import get_scene
    from prtbench.transport.lights import EnvironmentLight

    monkeypatch.setenv("PRTBENCH_CACHE", str(tmp_path / "cache"))
    scene = get_scene("sphere-over-plane", sphere_segments=16)
    light = EnvironmentLight("hot", _latlong(MAX_RADIANCE))
    ref = reference.render_reference(scene, light, scene.trajectory.views[0], width=12,
                                     height=8, spp=8, use_cache=False)
    assert np.all(np.isfinite(ref.image)) and ref.image.max() > 1e20
    assert np.all(np.isfinite(light.sh(3)))


def test_corrupt_light_exr_is_one_line_with_openexrs_reason(tmp_path, monkeypatch, capfd):
    path = tmp_path / "broken.exr"
    imageio.write_exr(path, np.random.default_rng(0).random((64, 128, 3)).astype(np.float32))
    data = bytearray(path.read_bytes())
    middle = len(data) // 2
    data[middle:middle + 400] = bytes(b ^ 0xFF for b in data[middle:middle + 400])
    path.write_bytes(bytes(data))
    err = _run_fails(tmp_path, monkeypatch, capfd, [
        "--method", "vertex", "--scene", "plane", "--light", str(path)])
    assert "cannot read EXR" in err and "broken.exr" in err
    # OpenEXR's own line (printed on fd 2 by the C++ library) is folded into ours.
    assert "EXR_ERR" in err or "corrupt" in err, err


# --- Mitsuba variant --------------------------------------------------------------------------

def test_bogus_variant_fails_in_check_variant_naming_what_works(monkeypatch, tmp_path):
    monkeypatch.setenv("PRTBENCH_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv(mitsuba_variant.VARIANT_ENV, "bogus")
    with pytest.raises(InvalidInputError) as info:
        mitsuba_variant.check_variant()
    message = str(info.value)
    assert "\n" not in message and "'bogus'" in message
    working = mitsuba_variant.usable_variants()
    assert working and "scalar_rgb" in working
    assert f"accepted (working here): {', '.join(working)}" in message
    assert not (tmp_path / "cache").exists()
    monkeypatch.delenv(mitsuba_variant.VARIANT_ENV)
    assert mitsuba_variant.check_variant() in mitsuba_variant.VARIANT_ORDER


def test_bogus_variant_fails_in_run_before_the_precompute(monkeypatch, tmp_path, capfd):
    """`prtbench run` calls check_variant() in prepare(): exit 2 and an empty cache, so the
    bad variant is never found only after minutes of precompute."""
    monkeypatch.setenv(mitsuba_variant.VARIANT_ENV, "bogus")
    err = _run_fails(tmp_path, monkeypatch, capfd, ["--method", "vertex", "--scene", "plane"])
    assert "'bogus'" in err and "scalar_rgb" in err


def test_bad_thread_count_fails_in_run_before_any_work(monkeypatch, tmp_path, capfd):
    monkeypatch.setenv("PRTBENCH_THREADS", "0")
    err = _run_fails(tmp_path, monkeypatch, capfd, ["--method", "vertex", "--scene", "plane"])
    assert "PRTBENCH_THREADS='0'" in err and "1..256" in err
