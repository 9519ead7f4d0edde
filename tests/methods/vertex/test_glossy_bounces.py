"""sloan-matrix with interreflection (``bounces``): the bounce operator's furnace identities,
the RGB shader path, against the one-bounce path reference, and the knob's validation."""

from __future__ import annotations

import math

import numpy as np
import pytest

import methods.vertex.glossy  # noqa: F401  registers the methods
from methods.vertex.bounces import bounce_matrices
from prtbench.api.errors import InvalidInputError, PrtbenchError
from prtbench.api.method import METHODS, Artifact, load_or_precompute
from prtbench.scene.model import Material, Scene, SceneObject, Trajectory, TriangleMesh, View
from prtbench.scene.registry import get_scene
from prtbench.transport import sh
from prtbench.transport.lights import get_light
from scenes.primitives import uv_sphere


def _inside_of_sphere(kd, ks=(0.0, 0.0, 0.0), shininess=1.0) -> Scene:
    """A closed shell seen from inside: faces and normals point to its centre, so every ray
    leaving a vertex hits the front of the shell."""
    outer = uv_sphere(radius=1.0, segments=32, rings=16)
    mesh = TriangleMesh(outer.positions, outer.faces[:, ::-1], -outer.normals)
    view = View(eye=(0.0, 0.0, 0.0), target=(0.0, 0.0, -1.0), fov_y=60.0)
    return Scene("inside-sphere", [SceneObject("shell", mesh, Material(kd=kd, ks=ks,
                                                                      shininess=shininess))],
                 trajectory=Trajectory((view,)))


def test_furnace_inside_a_closed_diffuse_shell():
    # Every ray hits a diffuse surface, so each hit reflects kd/π·√(4π)·(row 0 of M^{b−1})
    # whatever its direction, and π/M Σ_j y_0(ω_j) = √π/2 exactly for cosine-weighted rays:
    # row 0 of M^b is kd^b times row 0 of M⁰ (a white furnace returns kd per bounce). The
    # other rows follow the unoccluded cosine transfer T_lm(n) = c_l·Y_lm(n), c = π, 2π/3, π/4.
    kd = np.array([0.8, 0.5, 0.2])
    scene = _inside_of_sphere(tuple(kd))
    bands, v = 3, scene.n_vertices
    rng = np.random.default_rng(0)
    d = rng.normal(size=(bands * bands, bands * bands))
    direct = np.broadcast_to(d, (v, bands * bands, bands * bands)).astype(np.float32)
    one = bounce_matrices(scene, direct, bounces=1, rays_per_point=256, progress=False)
    two = bounce_matrices(scene, direct, bounces=2, rays_per_point=256, progress=False)
    assert one.shape == (v, 9, 9, 3) and one.dtype == np.float32
    for c in range(3):
        np.testing.assert_allclose(one[:, 0, :, c], np.broadcast_to(d[0] * (1 + kd[c]), (v, 9)),
                                   rtol=1e-4, atol=1e-4)
        np.testing.assert_allclose(two[:, 0, :, c],
                                   np.broadcast_to(d[0] * (1 + kd[c] + kd[c] ** 2), (v, 9)),
                                   rtol=1e-4, atol=1e-4)
    normals = scene.objects[0].mesh.normals.astype(np.float64)
    ls, _ = sh.lm_of(bands)
    cosine = np.array([math.pi, 2 * math.pi / 3, math.pi / 4])[ls]
    transfer = cosine * sh.eval_sh(normals, bands)  # (V, 9); T_0 = √π/2
    # M¹_kic = T_k · kd_c/π·√(4π) · d_0i  (row 0: √π/2 · √(4π)/π = 1).
    expected = (transfer[:, :, None, None] * d[0][None, None, :, None] * kd
                * (math.sqrt(4 * math.pi) / math.pi))  # (V, 9, 9, 3)
    error = np.abs(one - direct[..., None] - expected)
    assert error.max() < 0.03 * np.abs(expected).max(), error.max()


def test_convex_object_has_nothing_to_interreflect():
    outer = uv_sphere(radius=0.5, segments=24, rings=12)
    scene = Scene("sphere", [SceneObject("sphere", outer, Material(kd=(0.9, 0.9, 0.9),
                                                                   ks=(0.1, 0.1, 0.1)))])
    direct = np.random.default_rng(1).normal(size=(scene.n_vertices, 4, 4)).astype(np.float32)
    out = bounce_matrices(scene, direct, bounces=2, rays_per_point=32, progress=False)
    assert np.array_equal(out, np.repeat(direct[..., None], 3, axis=3))


@pytest.mark.parametrize("shininess", [1.0, 64.0, 1000.0])
def test_glossy_furnace_inside_a_closed_shell_reflects_ks(shininess):
    # A pure Phong shell (kd = 0) under a constant incident field (H = identity · L with only
    # L_0): the normalised lobe integrates a constant to 1, so every hit sends ks·L_0·g_0
    # towards the gathering point whatever the mirror direction (g_0 = 1/√(4π) for every s),
    # and cosine-weighted rays that all hit give M¹_00 = √π/2 · ks · g_0 = ks/4 exactly.
    ks = np.array([0.9, 0.6, 0.3])
    scene = _inside_of_sphere((0.0, 0.0, 0.0), ks=tuple(ks), shininess=shininess)
    bands, v = 4, scene.n_vertices
    assert abs(sh.phong_zonal(shininess, bands)[0] - 1 / math.sqrt(4 * math.pi)) < 1e-9
    direct = np.broadcast_to(np.eye(bands * bands), (v, 16, 16)).astype(np.float32)
    one = bounce_matrices(scene, direct, bounces=1, rays_per_point=64, progress=False)
    np.testing.assert_allclose(one[:, 0, 0, :] - 1.0, np.broadcast_to(ks / 4, (v, 3)),
                               rtol=1e-4)
    # The directional columns follow each hit's mirror direction: not all zero.
    assert np.all(np.isfinite(one)) and np.abs(one[:, 0, 1:, 0]).max() > 1e-3


def test_glossy_floor_reflection_matches_quadrature():
    # A small downward-facing quad 0.1 above a (practically infinite) pure Phong floor whose
    # incident field is the light itself (M⁰ = identity there). The floor sends towards the
    # quad ks·(lobe ⋆ L)(Pω) along each ray ω, P the mirror through the floor plane (r =
    # reflect(−ω, +Y) = Pω), so at the quad's vertices
    #     M¹_ki = ks·√(4π/(2l_i+1))·g_l_i(s) ∫_{ω_y<0} Y_k(ω) Y_i(Pω) (−ω_y) dω,
    # evaluated here by Gauss-Legendre × uniform-φ quadrature.
    from prtbench.scene.geometry import grid_plane

    ks, shininess, bands = 0.8, 16.0, 4
    floor = grid_plane(400.0, 1)
    top = grid_plane(1.0, 1, center=(0.0, 0.1, 0.0))
    quad = TriangleMesh(top.positions, top.faces[:, ::-1], -top.normals)
    scene = Scene("mirror-gap", [
        SceneObject("floor", floor, Material(kd=(0.0, 0.0, 0.0), ks=(ks, ks, ks),
                                             shininess=shininess)),
        SceneObject("quad", quad, Material(kd=(0.5, 0.5, 0.5)))])
    n2 = bands * bands
    direct = np.broadcast_to(np.eye(n2), (scene.n_vertices, n2, n2)).astype(np.float32)
    one = bounce_matrices(scene, direct, bounces=1, rays_per_point=4096, progress=False)
    at_quad = one[floor.n_vertices:, :, :, 0] - direct[floor.n_vertices:]
    mu, w_mu = np.polynomial.legendre.leggauss(96)
    mu, w_mu = (mu + 1) / 2, w_mu / 2  # −ω_y in [0, 1]
    phi = (np.arange(192) + 0.5) * 2 * np.pi / 192
    mu_g, phi_g = np.meshgrid(mu, phi, indexing="ij")
    sin_t = np.sqrt(1 - mu_g**2)
    dirs = np.stack([sin_t * np.cos(phi_g), -mu_g, sin_t * np.sin(phi_g)], -1).reshape(-1, 3)
    weights = np.repeat(w_mu, len(phi)) * 2 * np.pi / len(phi) * mu_g.reshape(-1)
    ls, _ = sh.lm_of(bands)
    kernel = np.sqrt(4 * np.pi / (2 * ls + 1)) * sh.phong_zonal(shininess, bands)[ls]
    mirrored = dirs * np.array([1.0, -1.0, 1.0])
    exact = ks * (sh.eval_sh(dirs, bands) * weights[:, None]).T @ sh.eval_sh(mirrored, bands)
    exact = exact * kernel[None, :]
    assert np.abs(exact).max() > 0.1
    for matrix in at_quad:
        assert np.abs(matrix - exact).max() < 1e-2 * np.abs(exact).max(), \
            np.abs(matrix - exact).max()


def _renderer(scene, artifact, bands, *, width=64, height=48):
    cls = METHODS.get("sloan-matrix")
    config = cls.make_config({"sh_bands": bands})
    return cls.renderer(scene, artifact, config, width=width, height=height)


def test_rgb_matrices_render_like_scaled_grey_ones():
    # The shader's RGB layout (MATRIX_RGB): channel c of matrices f_c·M renders f_c times the
    # grey image's channel c (shading is linear in H; kd = ks colourless here).
    scene = get_scene("sphere-over-plane", plane_subdivisions=4, variant="glossy").with_views(1)
    cls = METHODS.get("sloan-matrix")
    bands = 3
    config = cls.make_config({"sh_bands": bands, "rays_per_point": 32})
    grey = load_or_precompute(cls, scene, config, progress=False)
    factors = np.array([1.0, 0.5, 0.25], np.float32)
    rgb = Artifact("sloan-matrix", {"matrices": grey.arrays["matrices"][..., None] * factors},
                   dict(grey.meta))
    images = []
    for artifact in (grey, rgb):
        renderer = _renderer(scene, artifact, bands)
        try:
            images.append(renderer.render(scene.trajectory.views[0], get_light("sky")))
            memory = renderer.memory_bytes()
        finally:
            renderer.release()
    assert memory == scene.n_vertices * bands**4 * 4 * 3
    assert images[0].max() > 0.05
    np.testing.assert_allclose(images[1], images[0] * factors, atol=1e-5)


def test_bounces_knob_keeps_zero_bounce_caches_and_validates():
    cls = METHODS.get("sloan-matrix")
    zero = cls.make_config({})
    assert zero.bounces == 0 and "bounces" not in cls.cache_identity(zero)
    assert cls.cache_identity(cls.make_config({"bounces": 1}))["bounces"] == 1
    scene = get_scene("cornell", variant="glossy")
    with pytest.raises(InvalidInputError, match=r"bounces=1 with compress=cpca"):
        cls.validate(scene, cls.make_config({"bounces": 1, "compress": "cpca", "clusters": 4,
                                             "pca_vectors": 2}))
    # RGB matrices triple the buffer the size limit is checked against.
    size = scene.n_vertices * 5**4 * 4
    cls.validate(scene, cls.make_config({"bounces": 0, "max_bytes": size}))
    with pytest.raises(InvalidInputError, match=r"V × 3 × 625 floats"):
        cls.validate(scene, cls.make_config({"bounces": 1, "max_bytes": size}))
    with pytest.raises(PrtbenchError, match="bounces"):
        cls.make_config({"bounces": -1})
    # Unshadowed matrices (the trivial image) trace no ray, so they gain no bounce either.
    flat = cls.make_config({"bounces": 1, "visibility": False, "sh_bands": 2,
                            "rays_per_point": 4})
    artifact = cls.precompute(scene, flat, progress=False)
    assert artifact.arrays["matrices"].shape == (scene.n_vertices, 4, 4)


def _masked_psnr(image, ref, scene, mask):
    from prtbench.bench import metrics
    from prtbench.io import imageio

    values = metrics.compute_metrics(imageio.display(image, exposure=scene.exposure),
                                     imageio.display(ref, exposure=scene.exposure), mask=mask)
    return values["psnr_masked"]


def test_one_bounce_matrices_approach_the_one_bounce_reference():
    from prtbench.render.reference import render_reference
    from prtbench.transport.raytrace import geometry_mask

    scene = get_scene("cornell", variant="glossy", subdivisions=8).with_views(1)
    view, light, width, height = scene.trajectory.views[0], get_light("sky"), 64, 48
    mask = geometry_mask(scene, view, width, height)
    ref = render_reference(scene, light, view, width=width, height=height, spp=256, bounces=1)
    cls = METHODS.get("sloan-matrix")
    images, facts = {}, {}
    for bounces in (0, 1):
        config = cls.make_config({"sh_bands": 5, "rays_per_point": 256, "bounces": bounces})
        artifact = load_or_precompute(cls, scene, config, progress=False)
        renderer = cls.renderer(scene, artifact, config, width=width, height=height)
        try:
            images[bounces] = renderer.render(view, light)
            facts[bounces] = renderer.memory_bytes()
        finally:
            renderer.release()
    psnr = {b: _masked_psnr(images[b], ref.image, scene, mask) for b in images}
    # Measured (5 bands, 256 rays, 1676 vertices): 17.3 dB with one bounce vs 13.9 dB without
    # against the one-bounce reference; light gain ×1.198 vs the path tracer's ×1.214.
    # SH-truncated light through the skylight and per-vertex Gouraud shading bound both.
    assert psnr[1] > psnr[0] + 2.0, psnr
    gain = images[1][mask].mean() / images[0][mask].mean()
    direct_ref = render_reference(scene, light, view, width=width, height=height, spp=256,
                                  bounces=0)
    reference_gain = ref.image[mask].mean() / direct_ref.image[mask].mean()
    assert abs(gain - reference_gain) < 0.08, (gain, reference_gain)
    assert facts[1] == 3 * facts[0] == 3 * scene.n_vertices * 5**4 * 4
