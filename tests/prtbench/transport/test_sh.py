"""Spherical-harmonic identities (DESIGN.md §5): basis, zonal lobes, triple products."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.integrate
import scipy.special

from prtbench.api.errors import InvalidInputError
from prtbench.transport import sh


def _random_dirs(n: int, seed: int = 0) -> np.ndarray:
    d = np.random.default_rng(seed).normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def _scipy_real_sh(l: int, m: int, dirs: np.ndarray) -> np.ndarray:
    """scipy's complex Y_l^m (with Condon–Shortley phase) converted to our real basis."""
    theta = np.arccos(np.clip(dirs[:, 2], -1, 1))
    phi = np.arctan2(dirs[:, 1], dirs[:, 0])
    y = scipy.special.sph_harm_y(l, abs(m), theta, phi)
    # (-1)^m removes the Condon–Shortley phase scipy includes.
    if m > 0:
        return math.sqrt(2) * (-1) ** m * y.real
    if m < 0:
        return math.sqrt(2) * (-1) ** m * y.imag
    return y.real


def test_eval_sh_matches_scipy_to_band_15():
    dirs = _random_dirs(500)
    # Include the poles and the equator, where recurrences in θ/φ usually break first.
    dirs = np.concatenate([dirs, [[0, 0, 1], [0, 0, -1], [1, 0, 0], [0, 1, 0]]])
    bands = 16
    ours = sh.eval_sh(dirs, bands)
    worst = 0.0
    for l in range(bands):
        for m in range(-l, l + 1):
            worst = max(worst, np.abs(ours[:, sh.index(l, m)] - _scipy_real_sh(l, m, dirs)).max())
    assert worst < 1e-10


def test_basis_is_orthonormal_by_exact_quadrature():
    bands = 12
    dirs, weights = sh.sphere_quadrature(2 * (bands - 1))
    y = sh.eval_sh(dirs, bands)
    gram = (y * weights[:, None]).T @ y
    assert np.abs(gram - np.eye(bands * bands)).max() < 1e-12


def test_low_bands_have_closed_forms():
    d = _random_dirs(50)
    y = sh.eval_sh(d, 3)
    x_, y_, z_ = d.T
    assert np.allclose(y[:, 0], 0.5 / math.sqrt(math.pi))
    c1 = math.sqrt(3 / (4 * math.pi))
    assert np.allclose(y[:, 1:4], c1 * np.stack([y_, z_, x_], axis=1))
    assert np.allclose(y[:, sh.index(2, 0)], math.sqrt(5 / (16 * math.pi)) * (3 * z_**2 - 1))


def test_sh_stays_finite_and_bounded_at_high_bands():
    y = sh.eval_sh(_random_dirs(200), 40)
    bound = np.sqrt((2 * np.arange(40) + 1) / (4 * np.pi))  # |Y_lm| <= √((2l+1)/4π)·√2
    ls, _ = sh.lm_of(40)
    assert np.all(np.isfinite(y)) and np.all(np.abs(y) <= math.sqrt(2) * bound[ls] + 1e-9)


def test_clamped_cosine_zonal_constants():
    g = sh.clamped_cosine_zonal(6)
    assert g[0] == pytest.approx(math.sqrt(math.pi) / 2, rel=1e-14)
    assert g[1] == pytest.approx(math.sqrt(math.pi / 3), rel=1e-14)
    assert g[2] == pytest.approx(math.sqrt(5 * math.pi) / 8, rel=1e-14)
    assert g[3] == pytest.approx(0.0, abs=1e-15) and g[5] == pytest.approx(0.0, abs=1e-15)


def test_phong_lobe_is_zero_behind_the_mirror_plane_at_every_exponent():
    # The lobe phong_zonal projects: (s+1)/(2π) cos^s α for cos α > 0, else 0, also at s = 0
    # (the hemisphere about r, integral 1), never the 0^0 = 1 full sphere.
    cos = np.array([-1.0, -1e-9, 0.0, 0.5, 1.0])
    for s in (0.0, 1.0, 64.0):
        want = np.where(cos > 0, (s + 1) / (2 * np.pi) * np.maximum(cos, 1e-300) ** s, 0.0)
        assert np.array_equal(sh.phong_lobe(cos, s), want), s
    assert sh.phong_lobe(np.float32([0.5]), np.float32(3.0)).dtype == np.float32
    mu = np.linspace(-1.0, 1.0, 200_001)  # ∫ lobe dω = 2π ∫ lobe(μ) dμ = 1 at s = 0 too
    assert 2 * np.pi * np.trapezoid(sh.phong_lobe(mu, 0.0), mu) == pytest.approx(1.0, abs=1e-4)


@pytest.mark.filterwarnings("ignore::scipy.integrate.IntegrationWarning")  # quad near eps
@pytest.mark.parametrize("s", [0, 1, 10, 100, 1000, 10000])
def test_phong_zonal_matches_adaptive_quadrature(s):
    bands = 8
    g = sh.phong_zonal(s, bands)
    assert np.all(np.isfinite(g))
    for l in range(bands):
        norm = math.sqrt((2 * l + 1) / (4 * math.pi))
        p_l = scipy.special.legendre(l)
        # The lobe is concentrated in μ ∈ [1 − ~30/s, 1]: give quad the breakpoint.
        split = max(0.0, 1.0 - 40.0 / max(s, 1.0))
        integrand = lambda mu: (s + 1) * mu**s * p_l(mu)  # 2π·(s+1)/(2π)·μ^s·P_l
        value = sum(scipy.integrate.quad(integrand, a, b, epsabs=0, epsrel=1e-11, limit=400)[0]
                    for a, b in ((0.0, split), (split, 1.0)) if b > a)
        expected = norm * value
        assert g[l] == pytest.approx(expected, rel=1e-8, abs=1e-14 * norm * (s + 1))


def test_phong_lobe_is_normalised_for_every_exponent():
    for s in (0.0, 0.5, 3.7, 64.0, 1e4):
        assert sh.phong_zonal(s, 4)[0] == pytest.approx(sh.band_norms(1)[0], rel=1e-14)


def test_phong_zonal_rejects_out_of_range_exponent():
    with pytest.raises(InvalidInputError, match="accepted"):
        sh.phong_zonal(-1.0, 4)
    with pytest.raises(InvalidInputError, match="accepted"):
        sh.phong_zonal(2e4, 4)


def test_zonal_convolution_of_a_delta_like_light_reproduces_the_lobe():
    # Convolving the SH of Y-projected cosine lobe: (cos ⋆ L)(n) for a constant light L = 1 is π.
    bands = 6
    white = np.zeros(bands * bands)
    white[0] = math.sqrt(4 * math.pi)
    axes = _random_dirs(20)
    irradiance = sh.zonal_convolve(white, sh.clamped_cosine_zonal(bands), axes)
    assert np.allclose(irradiance, math.pi, rtol=1e-12)


def test_zonal_convolution_matches_direct_integration():
    # Light = a smooth band-limited function; the convolution equals ∫ L(ω) g(ω·a) dω.
    bands, s = 5, 7.0
    rng = np.random.default_rng(3)
    light = rng.normal(size=bands * bands)
    axis = _random_dirs(3, seed=4)
    dirs, w = sh.sphere_quadrature(60)
    values = sh.eval_sh(dirs, bands) @ light
    lobe = (s + 1) / (2 * math.pi) * np.maximum(dirs @ axis.T, 0.0) ** s
    direct = (values[:, None] * lobe * w[:, None]).sum(axis=0)
    ours = sh.zonal_convolve(light, sh.phong_zonal(s, bands), axis)
    # The clamped lobe is not band-limited, but projecting the light onto 5 bands is exact.
    assert np.allclose(ours, direct, rtol=1e-6, atol=1e-6)


def test_triple_product_tensor_identities():
    bands = 5
    gamma = sh.triple_product_tensor(bands)
    n = bands * bands
    assert gamma.shape == (n, n, n)
    assert np.allclose(gamma[0], np.eye(n) / math.sqrt(4 * math.pi), atol=1e-14)
    # Fully symmetric.
    assert np.allclose(gamma, gamma.transpose(1, 0, 2)) and np.allclose(gamma, gamma.transpose(0, 2, 1))
    ls, _ = sh.lm_of(bands)
    l1, l2, l3 = np.meshgrid(ls, ls, ls, indexing="ij")
    forbidden = ((l1 + l2 + l3) % 2 == 1) | (l1 > l2 + l3) | (l2 > l1 + l3) | (l3 > l1 + l2)
    assert np.abs(gamma[forbidden]).max() < 1e-14
    assert np.abs(gamma[~forbidden]).max() > 0.1  # not trivially zero


def test_triple_product_equals_projection_of_the_product():
    # H = Γ(T, L) must be the SH projection of T(ω)·L(ω) restricted to n bands.
    bands = 4
    rng = np.random.default_rng(1)
    t, light = rng.normal(size=(2, bands * bands))
    dirs, w = sh.sphere_quadrature(3 * (bands - 1))
    y = sh.eval_sh(dirs, bands)
    expected = sh.project((y @ t) * (y @ light), dirs, w, bands)
    assert np.allclose(sh.triple_product(t[None], light, bands)[0], expected, atol=1e-12)
    m = sh.tpfl_matrix(light, bands)
    assert np.allclose(t @ m, expected, atol=1e-12)


def test_tpfl_matrix_rgb_and_bounds():
    light = np.random.default_rng(2).normal(size=(16, 3))
    m = sh.tpfl_matrix(light, 4)
    assert m.shape == (16, 16, 3)
    with pytest.raises(InvalidInputError):
        sh.triple_product_tensor(9)
    with pytest.raises(InvalidInputError):
        sh.tpfl_matrix(np.zeros(9), 4)


def test_sparse_triple_product_is_cached_and_complete(tmp_path, monkeypatch):
    monkeypatch.setenv("PRTBENCH_CACHE", str(tmp_path))
    ijk, values = sh.triple_product_sparse(4)
    dense = np.zeros((16, 16, 16))
    dense[tuple(ijk.T)] = values
    assert np.allclose(dense, sh.triple_product_tensor(4))
    assert list((tmp_path / "sh-triple").glob("*.npz"))


def test_windows():
    assert np.all(sh.window(5) == 1)
    h = sh.window(5, kind="hanning", width=4)
    assert h[0] == 1 and h[4] == pytest.approx(0.0) and np.all(np.diff(h) <= 0)
    with pytest.raises(InvalidInputError, match="known"):
        sh.window(5, kind="gauss")
