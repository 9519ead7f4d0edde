"""Cubemaps, the non-standard Haar transform and non-linear selection (DESIGN.md §17)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from prtbench.api.errors import InvalidInputError
from prtbench.transport.latlong import lat_long_directions
from prtbench.transport.lights import EnvironmentLight, get_light
from prtbench.transport.wavelet import cubemap, haar, selection

# --- cubemap ------------------------------------------------------------------------------------

@pytest.mark.parametrize("n", [1, 2, 8, 32, 128])
def test_solid_angles_sum_to_four_pi(n):
    omega = cubemap.texel_solid_angles(n)
    assert omega.shape == (6, n, n) and np.all(omega > 0)
    assert abs(omega.sum() - 4.0 * math.pi) < 1e-12
    # A face centre texel: ≈ (2/N)² (the area element is 1 there); corners are smaller.
    if n >= 32:
        centre = (2.0 / n) ** 2 * (1.0 + 2.0 / n**2) ** -1.5  # the area element at (1/N, 1/N)
        assert abs(omega[0, n // 2, n // 2] / centre - 1.0) < 5.0 / n**2
        corner = (2.0 / n) ** 2 * 3.0 ** -1.5  # the area element at (±1, ±1)
        assert abs(omega[0, 0, 0] / corner - 1.0) < 10.0 / n


def test_solid_angles_match_direction_sampling():
    # Independent check: the fraction of uniform sphere directions landing in each texel.
    n = 4
    rng = np.random.default_rng(3)
    d = rng.normal(size=(2_000_000, 3))
    face, row, col, _, _ = cubemap.directions_to_texels(d, n)
    counts = np.bincount((face * n + row) * n + col, minlength=6 * n * n).reshape(6, n, n)
    expected = cubemap.texel_solid_angles(n) / (4 * math.pi) * len(d)
    assert np.max(np.abs(counts - expected) / np.sqrt(expected)) < 5.0


def test_face_convention_is_opengl():
    d = cubemap.texel_directions(2)
    # Each face's texels point towards its axis.
    for f, axis in enumerate([(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]):
        assert np.all(d[f] @ np.array(axis, float) > 0.5)
    # GL table: on +X, s grows towards -Z and t towards -Y; on +Y, t grows towards +Z.
    assert d[0, 0, 1, 2] < d[0, 0, 0, 2] and d[0, 1, 0, 1] < d[0, 0, 0, 1]
    assert d[2, 1, 0, 2] > d[2, 0, 0, 2]


@pytest.mark.parametrize("n", [1, 4, 16])
def test_directions_to_texels_inverts_texel_directions(n):
    d = cubemap.texel_directions(n).reshape(-1, 3)
    face, row, col, _, _ = cubemap.directions_to_texels(d, n)
    assert np.array_equal((face * n + row) * n + col, np.arange(6 * n * n))


def test_resolution_must_be_a_power_of_two():
    for bad in (0, 3, 48, 2048, 32.0, True):
        with pytest.raises(InvalidInputError, match="power of two"):
            cubemap.texel_solid_angles(bad)


def _smooth_light(height=64):
    w = 2 * height
    d = lat_long_directions(((np.arange(w) + 0.5) / w)[None, :], (np.arange(height) / (height - 1))[:, None])
    image = 1.0 + 0.5 * d[..., 1:2] + 0.3 * d[..., 0:1] * np.array([1.0, 0.5, 0.2]) + 0.2 * d[..., 2:3] ** 2
    return EnvironmentLight("smooth", image.astype(np.float32))


def test_resampling_integrates_the_light():
    # Σ L_t Ω_t is the light's power: exact for the bilinear map up to the midpoint rule.
    for light, tol in ((_smooth_light(), 1e-5), (get_light("sun"), 1e-4), (get_light("sky"), 2e-5)):
        cube = cubemap.from_lat_long(light, 16)
        power = np.einsum("fijc,fij->c", cube, cubemap.texel_solid_angles(16))
        assert np.allclose(power, light.total_power(), rtol=tol), (light.name, power,
                                                                   light.total_power())


def test_resampling_is_an_average_not_a_point_sample():
    # A sun smaller than a texel: point sampling at texel centres misses most of it (or hits it
    # at its peak); integration keeps its power within a texel's worth of error.
    light = get_light("sun")
    n = 8
    cube = cubemap.from_lat_long(light, n)
    point = light.radiance(cubemap.texel_directions(n).reshape(-1, 3)).reshape(6, n, n, 3)
    omega = cubemap.texel_solid_angles(n)
    exact = light.total_power()[0]
    assert abs(np.sum(cube[..., 0] * omega) / exact - 1.0) < 3e-3
    assert abs(np.sum(point[..., 0] * omega) / exact - 1.0) > 0.2


def test_lat_long_cube_lat_long_round_trip_of_a_smooth_light():
    light = _smooth_light(height=64)
    cube = cubemap.from_lat_long(light, 64)
    back = cubemap.to_lat_long(cube, light.height)
    err = np.abs(back - light.image)
    # Bilinear inside faces (error O(h²)), half-texel clamp at face edges (O(h)): the image
    # gradient is <= 0.8 per radian, half a texel is <= 1/64 rad (measured 0.0046, mean 1.4e-4).
    assert err.max() < 0.4 * 2 / 64, err.max()
    assert err.mean() < 5e-4, err.mean()
    nearest = cubemap.to_lat_long(cube, light.height, interpolation="nearest")
    assert np.abs(nearest - light.image).mean() > 2 * err.mean()


# --- Haar ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("n", [1, 2, 8, 32])
def test_haar_parseval_and_inverse(n):
    rng = np.random.default_rng(n)
    x = rng.normal(size=(5, 6, n, n)) * rng.lognormal(size=(5, 1, 1, 1))
    c = haar.forward(x)
    assert c.shape == x.shape
    assert np.allclose(np.sum(c * c, axis=(1, 2, 3)), np.sum(x * x, axis=(1, 2, 3)),
                       rtol=1e-12, atol=0)
    assert np.max(np.abs(haar.inverse(c) - x)) < 1e-12 * np.max(np.abs(x))
    # Orthonormal: the transform of a dot product's pair preserves it too.
    y = rng.normal(size=x.shape)
    assert np.allclose(np.sum(c * haar.forward(y), axis=(1, 2, 3)), np.sum(x * y, axis=(1, 2, 3)),
                       rtol=1e-12, atol=1e-12)


def test_haar_basis_functions():
    n = 8
    eye = np.eye(n * n).reshape(n * n, n, n)
    basis = haar.inverse(eye)  # row i: the image of coefficient i
    gram = basis.reshape(n * n, -1) @ basis.reshape(n * n, -1).T
    assert np.allclose(gram, np.eye(n * n), atol=1e-14)
    assert np.allclose(basis[0], 1.0 / n)  # the scaling function is constant
    # Each detail's support has the side the layout says; it averages to zero.
    side = haar.support_texels(n).reshape(-1)
    for i in range(1, n * n):
        nonzero = np.abs(basis[i]) > 1e-12
        assert nonzero.sum() == side[i] ** 2, i
        assert abs(basis[i].sum()) < 1e-12


def test_support_solid_angles():
    n = 16
    support = haar.support_solid_angles(n)
    assert np.allclose(support[:, 0, 0], 4 * math.pi / 6, rtol=1e-12)
    omega = cubemap.texel_solid_angles(n)
    eye = np.eye(n * n).reshape(n * n, n, n)
    basis = haar.inverse(eye)
    for i in (1, 5, 40, 200, 255):
        assert np.isclose(support[0].reshape(-1)[i], omega[0][np.abs(basis[i]) > 1e-12].sum(),
                          rtol=1e-12)


def test_all_coefficients_give_exactly_the_cubemap_integral():
    # Weights live in the transport: T_t = Ω_t · f(ω_t); L_t is radiance.
    n = 16
    light = cubemap.from_lat_long(get_light("sky"), n)[..., 1]
    d = cubemap.texel_directions(n)
    transport = cubemap.texel_solid_angles(n) * np.maximum(d[..., 1] * 0.6 + d[..., 0] * 0.8, 0)
    direct = float(np.sum(light * transport))
    wavelet = float(np.sum(haar.forward(light) * haar.forward(transport)))
    assert abs(wavelet - direct) <= 1e-12 * abs(direct)
    keep = selection.select_terms(haar.forward(light).reshape(-1), 6 * n * n, rule="magnitude")
    assert len(keep) == 6 * n * n


# --- selection ----------------------------------------------------------------------------------

@pytest.mark.parametrize("light_name", ["sun", "sky"])
def test_lighting_error_decreases_monotonically_with_k(light_name):
    n = 16
    cube = cubemap.from_lat_long(get_light(light_name), n)
    coeffs = haar.forward(np.moveaxis(cube, -1, 0)).reshape(3, -1).T  # (6N², 3)
    support = haar.support_solid_angles(n).reshape(-1)
    total = np.sum(coeffs**2)
    ks = [1, 2, 4, 8, 16, 32, 64, 128, 256, 512, 1024, 6 * n * n]
    for rule in selection.SELECTION_RULES:
        weights = {"support": support, "transport_weight": support ** 0.5}
        errors = []
        for k in ks:
            approx = selection.approximate(coeffs, k, rule=rule, **weights)
            # Error measured in the texel domain: Parseval makes it the dropped energy.
            image = haar.inverse(approx.T.reshape(3, 6, n, n))
            errors.append(float(np.sum((image - np.moveaxis(cube, -1, 0)) ** 2)))
        assert all(b <= a * (1 + 1e-12) + 1e-300 for a, b in zip(errors, errors[1:])), (rule, errors)
        assert errors[-1] < 1e-20 * total and errors[0] > 1e-3 * total
        if rule == "magnitude":
            magnitude_errors = errors
        else:  # the L²-optimal rule is never beaten in L²
            assert all(m <= e * (1 + 1e-9) for m, e in zip(magnitude_errors, errors))
    # The sun is compact: 64 terms hold almost all its energy (what makes k = 64 enough).
    if light_name == "sun":
        assert magnitude_errors[ks.index(64)] < 0.05 * total


def test_selection_rules_and_bad_k():
    c = np.array([[3.0, 0, 0], [0, 0, -4.0], [1.0, 1.0, 1.0], [0.1, 0, 0]])
    assert list(selection.select_terms(c, 2, rule="magnitude")) == [0, 1]
    area = np.array([0.1, 0.1, 10.0, 100.0])
    assert list(selection.select_terms(c, 2, rule="area", support=area)) == [2, 3]
    assert list(selection.select_terms(c, 1, rule="transport",
                                       transport_weight=np.array([1, 0.5, 0, 0]))) == [0]
    for k in (0, 5, 2.5):
        with pytest.raises(InvalidInputError, match="light_terms"):
            selection.select_terms(c, k, rule="magnitude")
    with pytest.raises(InvalidInputError, match="needs support"):
        selection.select_terms(c, 1, rule="area")
    with pytest.raises(InvalidInputError, match="accepted: magnitude"):
        selection.select_terms(c, 1, rule="largest")
