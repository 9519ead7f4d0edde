"""The ``prtphong`` Mitsuba plug-in is exactly the DESIGN.md §4 BRDF, and samples it without bias.

All directions are in the local shading frame (n = +Z). Mitsuba's ``si.wi`` is our ωo (towards
the viewer) and its ``wo`` is our ωi (towards the light); ``eval`` returns f·cos θ_light.
The reference values come from NumPy (:func:`prtbench.render.mitsuba_bsdf.brdf`, float64) and from
quadratures that never call the plug-in.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.special
import scipy.stats

mi = pytest.importorskip("mitsuba")
dr = pytest.importorskip("drjit")

from prtbench.api.errors import InvalidInputError  # noqa: E402
from prtbench.render import mitsuba_bsdf as mb  # noqa: E402
from prtbench.render import mitsuba_variant  # noqa: E402
from prtbench.scene.model import Material, Texture  # noqa: E402

KD = (0.3, 0.2, 0.1)
KS = (0.5, 0.6, 0.7)


def _use_variant(monkeypatch: pytest.MonkeyPatch, names: tuple[str, ...]) -> str:
    for name in names:
        monkeypatch.setenv(mitsuba_variant.VARIANT_ENV, name)
        try:
            return mitsuba_variant.select_variant()
        except InvalidInputError:
            continue
    pytest.skip(f"none of {names} works here")


@pytest.fixture
def jit(monkeypatch):
    """A vectorised variant (cuda where usable, else llvm): whole arrays per call."""
    return _use_variant(monkeypatch, ("cuda_ad_rgb", "llvm_ad_rgb"))


def _bsdf(kd=KD, ks=KS, s=32.0):
    mb.ensure_registered()
    return mi.load_dict({"type": mb.PLUGIN_NAME, "kd": {"type": "rgb", "value": list(kd)},
                         "ks": {"type": "rgb", "value": list(ks)}, "shininess": float(s)})


def _si(view: np.ndarray):
    si = dr.zeros(mi.SurfaceInteraction3f, len(view))
    si.wi = mi.Vector3f(np.ascontiguousarray(view.T, dtype=np.float32))
    return si


def _eval_pdf(bsdf, view: np.ndarray, light: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vectorised eval_pdf: (N, 3) value (f·cos) and (N,) pdf."""
    value, pdf = bsdf.eval_pdf(mi.BSDFContext(), _si(view),
                               mi.Vector3f(np.ascontiguousarray(light.T, dtype=np.float32)))
    return np.array(value, dtype=np.float64).T, np.array(pdf, dtype=np.float64)


def _sample(bsdf, view: np.ndarray, u1: np.ndarray, u2: np.ndarray):
    bs, weight = bsdf.sample(mi.BSDFContext(), _si(view), mi.Float(u1.astype(np.float32)),
                             mi.Point2f(np.ascontiguousarray(u2.T, dtype=np.float32)))
    return (np.array(bs.wo, dtype=np.float64).T, np.array(bs.pdf, dtype=np.float64),
            np.array(weight, dtype=np.float64).T)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _direction(theta_deg: float) -> np.ndarray:
    t = math.radians(theta_deg)
    return np.array([math.sin(t), 0.0, math.cos(t)])


def _hemisphere_grid(n_mu: int, n_phi: int) -> tuple[np.ndarray, np.ndarray]:
    """Directions (N, 3) and solid-angle weights (N,) of a product quadrature of the z > 0
    hemisphere: Gauss–Legendre in μ = cos θ, midpoint (spectrally accurate, periodic) in φ."""
    x, w = scipy.special.roots_legendre(n_mu)
    mu, w_mu = 0.5 * (x + 1.0), 0.5 * w
    phi = (np.arange(n_phi) + 0.5) * (2 * math.pi / n_phi)
    mu_g, phi_g = np.meshgrid(mu, phi, indexing="ij")
    sin_t = np.sqrt(1.0 - mu_g ** 2)
    dirs = np.stack([sin_t * np.cos(phi_g), sin_t * np.sin(phi_g), mu_g], axis=-1).reshape(-1, 3)
    weights = (w_mu[:, None] * np.full(n_phi, 2 * math.pi / n_phi)[None, :]).ravel()
    return dirs, weights


def _albedo(view: np.ndarray, s: float, *, kd=KD, ks=KS) -> np.ndarray:
    """∫_H f(ωi, ωo) cos θi dωi by dense quadrature of the NumPy formula, (3,)."""
    dirs, weights = _hemisphere_grid(1200, 2400)
    f = mb.brdf(np.array(kd), np.array(ks), s, np.array([0.0, 0.0, 1.0]), dirs,
                np.broadcast_to(view, dirs.shape))
    return (f * (dirs[:, 2] * weights)[:, None]).sum(axis=0)


def _lobe_mass_below_horizon(view: np.ndarray, s: float) -> float:
    """Mass of the normalised Phong lobe about r = reflect(view) with z < 0.

    In the lobe's own frame a direction at angle α from r and azimuth φ has
    z = cos α·r_z + sin α·cos φ·sin θ_r (r in the x–z plane), so the fraction of φ below the
    horizon at each α is 1 − arccos(clip(−cos α·r_z / (sin α·sin θ_r))) / π: a 1-D integral.
    """
    r = np.array([-view[0], -view[1], view[2]])
    sin_r = math.hypot(r[0], r[1])
    x, w = scipy.special.roots_legendre(4000)
    alpha = 0.25 * math.pi * (x + 1.0)  # [0, π/2]: the lobe is zero beyond
    w = 0.25 * math.pi * w
    with np.errstate(divide="ignore", invalid="ignore"):
        c = -np.cos(alpha) * r[2] / (np.sin(alpha) * sin_r)
    frac = 1.0 - np.arccos(np.clip(c, -1.0, 1.0)) / math.pi
    density = (s + 1.0) * np.cos(alpha) ** s * np.sin(alpha)  # (s+1)/(2π)·cos^s α·sin α·2π
    return float(np.sum(w * density * frac))


# --- eval ------------------------------------------------------------------------------------

@pytest.mark.parametrize("s", [1.0, 32.0, 1000.0])
def test_eval_matches_formula(jit, s):
    rng = np.random.default_rng(int(s))
    n = 1000
    view = _unit(rng.normal(size=(n, 3)))
    light = _unit(rng.normal(size=(n, 3)))
    # Half the pairs near the mirror direction, where the lobe (and any error in it) lives.
    mirror = view * np.array([-1.0, -1.0, 1.0])
    light[: n // 2] = _unit(mirror[: n // 2] + rng.normal(scale=1.5 / math.sqrt(s + 1),
                                                          size=(n // 2, 3)))
    view, light = view.astype(np.float32), light.astype(np.float32)
    kd = rng.uniform(0, 0.5, 3)
    ks = rng.uniform(0, 0.5, 3)
    value, pdf = _eval_pdf(_bsdf(kd, ks, s), view, light)
    v64, l64 = view.astype(np.float64), light.astype(np.float64)
    front = (v64[:, 2] > 0) & (l64[:, 2] > 0)
    expected = mb.brdf(kd, ks, s, np.array([0.0, 0.0, 1.0]), l64, v64) \
        * (l64[:, 2] * front)[:, None]
    diffuse_only = kd / math.pi * (l64[:, 2] * front)[:, None]
    assert front.sum() > 100 and np.abs(expected - diffuse_only).max() > 0.05  # lobe is hit
    # float32 cos α carries ~2e-7 relative error, which cos^s α amplifies s-fold.
    rtol = 1e-5 + 3e-7 * s
    assert np.allclose(value, expected, rtol=rtol, atol=1e-7)
    assert np.all(value[~front] == 0) and np.all(pdf[~front] == 0)


def test_pdf_is_the_mixture_density(jit):
    rng = np.random.default_rng(7)
    view = _unit(rng.normal(size=(500, 3)) * [1, 1, 0.3] + [0, 0, 0.8])
    light = _unit(rng.normal(size=(500, 3)) * [1, 1, 0.3] + [0, 0, 0.8])
    s = 20.0
    _, pdf = _eval_pdf(_bsdf(KD, KS, s), view, light)
    w_d = np.mean(KD) / (np.mean(KD) + np.mean(KS))
    r = view * [-1, -1, 1]
    cos_a = np.maximum(np.sum(light * r, axis=1), 0)
    expected = w_d * light[:, 2] / math.pi + (1 - w_d) * (s + 1) / (2 * math.pi) * cos_a ** s
    front = (view[:, 2] > 0) & (light[:, 2] > 0)
    assert np.allclose(pdf[front], expected[front], rtol=2e-5, atol=1e-7)


@pytest.mark.parametrize("theta", [0.0, 40.0, 70.0])
@pytest.mark.parametrize("s", [1.0, 32.0, 1000.0])
def test_pdf_integrates_to_one_minus_lobe_mass_below_horizon(jit, theta, s):
    view = _direction(theta)
    dirs, weights = _hemisphere_grid(600, 1200)
    _, pdf = _eval_pdf(_bsdf(KD, KS, s), np.broadcast_to(view, dirs.shape), dirs)
    integral = float(np.sum(pdf * weights))
    w_d = np.mean(KD) / (np.mean(KD) + np.mean(KS))
    below = 0.0 if theta == 0 else _lobe_mass_below_horizon(view, s)
    assert integral == pytest.approx(1.0 - (1.0 - w_d) * below, abs=2e-4)
    if theta == 70.0 and s == 1.0:
        assert below > 0.05  # the check exercises the below-horizon mass


# --- sampling ---------------------------------------------------------------------------------

@pytest.mark.parametrize("theta", [0.0, 45.0, 75.0])
@pytest.mark.parametrize("s", [1.0, 32.0, 1000.0])
def test_sample_weight_is_unbiased_for_the_albedo(jit, theta, s):
    view = _direction(theta)
    n = 1 << 19
    rng = np.random.default_rng(1000 + int(theta) + int(s))
    wo, pdf, weight = _sample(_bsdf(KD, KS, s), np.broadcast_to(view, (n, 3)),
                              rng.random(n), rng.random((n, 2)))
    mean = weight.mean(axis=0)
    stderr = weight.std(axis=0) / math.sqrt(n)
    albedo = _albedo(view, s)
    assert np.all(albedo <= np.array(KD) + np.array(KS) + 1e-9)
    assert np.all(np.abs(mean - albedo) <= 4 * stderr + 1e-4), (mean, albedo, stderr)
    # The sample record is self-consistent: weight = eval / pdf and pdf = pdf(wo).
    value, pdf_again = _eval_pdf(_bsdf(KD, KS, s), np.broadcast_to(view, (n, 3)).astype(
        np.float32), wo.astype(np.float32))
    above = wo[:, 2] > 0
    assert np.allclose(pdf[above], pdf_again[above], rtol=1e-4)
    assert np.allclose(weight[above] * pdf[above, None], value[above], rtol=1e-4, atol=1e-7)
    assert np.all(weight[~above] == 0) and np.all(pdf[~above] == 0)
    if theta == 75.0 and s == 1.0:
        assert (~above).mean() > 0.02  # lobe samples below the horizon do occur


def test_sampled_directions_follow_pdf_chi_square(jit):
    """Pearson χ² of sampled directions in (μ, φ) bins against the integrated pdf."""
    view = _direction(50.0)
    s = 24.0
    bsdf = _bsdf(KD, KS, s)
    n = 400_000
    rng = np.random.default_rng(3)
    wo, _, _ = _sample(bsdf, np.broadcast_to(view, (n, 3)), rng.random(n), rng.random((n, 2)))
    n_mu, n_phi = 16, 32
    above = wo[:, 2] > 0
    mu_bin = np.minimum((wo[above, 2] * n_mu).astype(int), n_mu - 1)
    phi = np.mod(np.arctan2(wo[above, 1], wo[above, 0]), 2 * math.pi)
    phi_bin = np.minimum((phi / (2 * math.pi) * n_phi).astype(int), n_phi - 1)
    observed = np.bincount(mu_bin * n_phi + phi_bin, minlength=n_mu * n_phi).astype(float)
    # Expected mass per bin: Gauss–Legendre (μ) × midpoint (φ) inside each bin.
    k = 12
    x, w = scipy.special.roots_legendre(k)
    mu = ((np.arange(n_mu)[:, None] + 0.5 * (x + 1)) / n_mu).ravel()
    w_mu = np.tile(w / (2 * n_mu), n_mu)
    phis = (np.arange(n_phi * k) + 0.5) * (2 * math.pi / (n_phi * k))
    mu_g, phi_g = np.meshgrid(mu, phis, indexing="ij")
    sin_t = np.sqrt(1 - mu_g ** 2)
    dirs = np.stack([sin_t * np.cos(phi_g), sin_t * np.sin(phi_g), mu_g], -1).reshape(-1, 3)
    _, pdf = _eval_pdf(bsdf, np.broadcast_to(view, dirs.shape), dirs)
    mass = (pdf.reshape(n_mu * k, n_phi * k) * w_mu[:, None] * (2 * math.pi / (n_phi * k)))
    expected = mass.reshape(n_mu, k, n_phi, k).sum(axis=(1, 3)).ravel() * n
    # The lower hemisphere is one bin: everything the sampler put there (weight 0).
    observed = np.append(observed, (~above).sum())
    expected = np.append(expected, n - expected.sum())
    big = expected >= 5
    # Bins the pdf gives (almost) no mass are pooled; sampling into them at all would fail.
    obs = np.append(observed[big], observed[~big].sum())
    exp = np.append(expected[big], max(expected[~big].sum(), 1e-3))
    chi2 = float(np.sum((obs - exp) ** 2 / exp))
    p_value = scipy.stats.chi2.sf(chi2, len(obs) - 1)
    assert p_value > 1e-3, (chi2, len(obs))


def test_scalar_variant_agrees_with_vectorised(monkeypatch):
    """Same random numbers → same samples, pdfs and weights in scalar_rgb and a JIT variant."""
    rng = np.random.default_rng(11)
    n = 200
    view = _unit(rng.normal(size=(n, 3)) * [1, 1, 0.5] + [0, 0, 0.6]).astype(np.float32)
    u1 = rng.random(n).astype(np.float32)
    u2 = rng.random((n, 2)).astype(np.float32)
    s = 32.0
    _use_variant(monkeypatch, ("cuda_ad_rgb", "llvm_ad_rgb"))
    wo_j, pdf_j, weight_j = _sample(_bsdf(KD, KS, s), view, u1, u2)
    value_j, _ = _eval_pdf(_bsdf(KD, KS, s), view, wo_j.astype(np.float32))
    _use_variant(monkeypatch, ("scalar_rgb",))
    bsdf = _bsdf(KD, KS, s)
    ctx = mi.BSDFContext()
    for i in range(n):
        si = dr.zeros(mi.SurfaceInteraction3f)
        si.wi = mi.Vector3f(*view[i])
        bs, weight = bsdf.sample(ctx, si, float(u1[i]), mi.Point2f(*u2[i]))
        assert np.allclose(np.array(bs.wo), wo_j[i], atol=2e-5)
        assert float(bs.pdf) == pytest.approx(pdf_j[i], rel=2e-4, abs=1e-6)
        assert np.allclose(np.array(weight), weight_j[i], rtol=2e-4, atol=1e-6)
        value = np.array(bsdf.eval(ctx, si, mi.Vector3f(*wo_j[i].astype(np.float32))))
        assert np.allclose(value, value_j[i], rtol=2e-4, atol=1e-7)
    assert (pdf_j > 0).sum() > n // 2


def test_viewer_below_horizon_is_black(jit):
    view = np.array([[0.3, 0.0, -0.95]] * 64)
    rng = np.random.default_rng(5)
    _, pdf, weight = _sample(_bsdf(), view, rng.random(64), rng.random((64, 2)))
    value, pdf_eval = _eval_pdf(_bsdf(), view, np.array([[0.0, 0.0, 1.0]] * 64))
    assert np.all(weight == 0) and np.all(pdf == 0) and np.all(value == 0) and np.all(pdf_eval == 0)


# --- material conversion ----------------------------------------------------------------------

def test_material_conversion_uses_builtin_diffuse_only_for_ks_zero(jit):
    assert mb.material_bsdf(Material(kd=(0.2, 0.3, 0.4)), has_uvs=False)["type"] == "diffuse"
    glossy = mb.material_bsdf(Material(ks=(0.1, 0.1, 0.1), shininess=8.0), has_uvs=False)
    assert glossy["type"] == mb.PLUGIN_NAME and glossy["shininess"]["value"] == 8.0
    forced = mb.material_bsdf(Material(), has_uvs=False, use_builtin_diffuse=False)
    assert forced["type"] == mb.PLUGIN_NAME


def test_unsupported_material_features_are_named(jit):
    tex = Texture(np.full((2, 2, 3), 0.5, np.float32), name="albedo")
    with pytest.raises(InvalidInputError, match="no uvs"):
        mb.material_bsdf(Material(kd=tex), has_uvs=False)
    with pytest.raises(InvalidInputError, match="normal maps"):
        mb.material_bsdf(Material(normal_map=tex), has_uvs=True)
