"""The ``visibility`` switch: visibility off is exactly the unoccluded transfer (issue #12).

The regression gate's "unshadowed render" is the same method with ``visibility=False``; it is a
trivial image only if turning visibility off changes nothing but V (same rays, same estimator),
which these tests pin exactly.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from prtbench.api.method import METHODS, artifact_key
from prtbench.scene.model import Material, Scene, SceneObject, TriangleMesh
from prtbench.scene.registry import get_scene
from prtbench.transport.transfer import compute_transfer

UP = np.array([[0.0, 1.0, 0.0]])
BELOW = np.zeros((1, 3))  # on the plane, under the sphere's centre


def _nothing_near() -> Scene:
    """One tiny triangle far below everything: no ray of the tests can hit it."""
    p = np.array([[-1e-3, -1e3, 0.0], [1e-3, -1e3, 0.0], [0.0, -1e3, 1e-3]])
    mesh = TriangleMesh(p, np.array([[0, 1, 2]]), np.tile([0.0, 1.0, 0.0], (3, 1)))
    return Scene("nothing-near", [SceneObject("speck", mesh, Material())])


def test_unshadowed_transfer_below_the_sphere_is_the_unoccluded_constant():
    scene = get_scene("sphere-over-plane", radius=0.5, height=1.0)
    kw = dict(bands=3, rays_per_point=1024, use_cache=False, progress=False)
    shadowed = compute_transfer(scene, BELOW, UP, **kw)
    unshadowed = compute_transfer(scene, BELOW, UP, visibility=False, **kw)
    # T_0 = π/M Σ_j Y_0 = π / (2√π) = √π / 2 for every M: no ray is blocked. (The local sums
    # are float32 over blocks of 256 rays: measured 1.7e-6 relative here, hence 4e-6.)
    assert unshadowed[0, 0] == pytest.approx(math.sqrt(math.pi) / 2, rel=4e-6)
    # The sphere blocks (r/h)² = 1/4 of the cosine-weighted hemisphere.
    assert shadowed[0, 0] == pytest.approx(0.75 * math.sqrt(math.pi) / 2, abs=0.02)
    # Exactly the transfer of the same point where nothing occludes (same rays, same estimator).
    np.testing.assert_array_equal(unshadowed, compute_transfer(_nothing_near(), BELOW, UP, **kw))


def test_shadowed_and_unshadowed_transfer_are_cached_apart(tmp_path, monkeypatch):
    monkeypatch.setenv("PRTBENCH_CACHE", str(tmp_path))
    scene = get_scene("sphere-over-plane")
    kw = dict(bands=2, rays_per_point=64, progress=False)
    shadowed = compute_transfer(scene, BELOW, UP, **kw)
    unshadowed = compute_transfer(scene, BELOW, UP, visibility=False, **kw)
    assert len(list((tmp_path / "transfer").glob("*.npz"))) == 2
    assert unshadowed[0, 0] > shadowed[0, 0] + 0.1
    np.testing.assert_array_equal(compute_transfer(scene, BELOW, UP, **kw), shadowed)  # a hit


def test_sloan_matrices_without_visibility_are_unoccluded():
    from methods.vertex.glossy import compute_transfer_matrices

    scene = get_scene("sphere-over-plane", radius=0.5, height=1.0)
    m = compute_transfer_matrices(scene, BELOW, UP, bands=2, rays_per_point=512, progress=False,
                                  visibility=False)
    # M_00 = ∫ Y_0² max(n·ω, 0) dω = π / (4π) = 1/4, exactly for this estimator.
    assert m[0, 0, 0] == pytest.approx(0.25, rel=1e-6)
    shadowed = compute_transfer_matrices(scene, BELOW, UP, bands=2, rays_per_point=512,
                                         progress=False)
    assert shadowed[0, 0, 0] == pytest.approx(0.75 * 0.25, abs=0.01)


@pytest.mark.parametrize("name", ["vertex", "vertex-tp", "vertex-tpfl", "sloan-matrix",
                                  "texture-tp", "texture-tpfl", "irradiance-volume", "learnt",
                                  "learnt-sdf"])
def test_visibility_is_a_documented_knob_in_the_cache_key(name):
    cls = METHODS.get(name)
    field = cls.Config.__dataclass_fields__["visibility"]
    assert field.default is True and "unshadowed" in field.metadata["doc"]
    scene = get_scene("sdf-rabbit" if name == "learnt-sdf" else "sphere-over-plane")
    on = cls.make_config({}, profile="smoke")
    off = cls.make_config({"visibility": False}, profile="smoke")
    assert artifact_key(cls, scene, on) != artifact_key(cls, scene, off)


def test_vertex_artifact_without_visibility_is_the_unoccluded_transfer():
    cls = METHODS.get("vertex")
    scene = get_scene("sphere-over-plane", radius=0.5, height=1.0)
    config = cls.make_config({"visibility": False, "bounces": 2}, profile="smoke")
    transfer = cls.precompute(scene, config, progress=False).arrays["transfer"]
    positions, normals, _, _ = scene.merged()
    expected = compute_transfer(_nothing_near(), positions, normals, bands=config.sh_bands,
                                rays_per_point=config.rays_per_point, seed=config.seed,
                                use_cache=False, progress=False)
    np.testing.assert_array_equal(transfer, expected)  # no shadow and no bounce


def test_irradiance_volume_without_visibility_sees_the_whole_sky_at_every_probe():
    cls = METHODS.get("irradiance-volume")
    scene = get_scene("sphere-over-plane")
    config = cls.make_config({"visibility": False, "resolution": 4}, profile="smoke")
    arrays = cls.precompute(scene, config, progress=False).arrays
    np.testing.assert_allclose(arrays["visibility"][:, 0], math.sqrt(4 * math.pi), rtol=1e-6)
    assert arrays["valid"].all() and not arrays["backface_fraction"].any()


def test_learnt_training_data_without_visibility_is_unoccluded():
    from methods.learnt.data import training_samples

    scene = get_scene("sphere-over-plane")
    kw = dict(samples=256, rays_per_point=32, bands=2, seed=0, vertex_margin=1e-3, progress=False)
    off = training_samples(scene, visibility=False, **kw)
    np.testing.assert_allclose(off.transfer[:, 0], math.sqrt(math.pi) / 2, rtol=1e-6)
    on = training_samples(scene, **kw)  # cached apart: the shadowed set still has shadows
    assert on.transfer[:, 0].min() < 0.9 * math.sqrt(math.pi) / 2


def test_learnt_sdf_training_data_without_visibility_is_unoccluded():
    from methods.learnt.sdf import surface_transfer

    scene = get_scene("sdf-rabbit")
    kw = dict(points=128, rays_per_point=16, bands=2, seed=0, backend="numpy", progress=False)
    off = surface_transfer(scene, visibility=False, **kw)
    np.testing.assert_allclose(off["transfer"][:, 0], math.sqrt(math.pi) / 2, rtol=1e-6)
    on = surface_transfer(scene, **kw)
    assert on["transfer"][:, 0].min() < 0.9 * math.sqrt(math.pi) / 2


def test_data_driven_says_why_it_has_no_visibility_knob():
    from prtbench.bench.trivial import visibility_knob

    reason = visibility_knob(METHODS.get("data-driven"))
    assert reason is not None and "shadow" in reason
