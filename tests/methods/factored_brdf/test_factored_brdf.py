"""``factored-brdf`` (Wang 2004 / Sloan 2004 in-out factored Phong BRDF, J transfer vectors per
vertex): the diffuse case is ``vertex``, the error against the unfactored ``sloan-matrix`` falls
with J, convergence towards the path reference, memory, bad input."""

from __future__ import annotations

import numpy as np
import pytest

import methods.factored_brdf.method as factored  # noqa: F401  (registers factored-brdf)
import methods.vertex.diffuse  # noqa: F401
import methods.vertex.glossy  # noqa: F401
from prtbench.api.errors import InvalidInputError, PrtbenchError
from prtbench.api.method import METHODS, load_or_precompute
from prtbench.scene.registry import get_scene
from prtbench.transport.lights import get_light
from tests.methods.refusal import assert_run_refused  # noqa: E402


def _scene(variant: str, **params):
    return get_scene("sphere-over-plane", variant=variant, sphere_segments=16,
                     plane_subdivisions=8, **params).with_views(1)


def _render(method, scene, *, light="sky", width=64, height=48, **overrides):
    cls = METHODS.get(method)
    config = cls.make_config(overrides, profile="quick")
    cls.validate(scene, config)
    artifact = load_or_precompute(cls, scene, config, progress=False)
    renderer = cls.renderer(scene, artifact, config, width=width, height=height)
    try:
        return (renderer.render(scene.trajectory.views[0], get_light(light)),
                renderer.memory_bytes(), artifact)
    finally:
        renderer.release()


def test_one_term_on_a_diffuse_scene_renders_what_vertex_renders():
    scene = _scene("diffuse")
    got, memory, artifact = _render("factored-brdf", scene, terms=1, sh_bands=3,
                                    rays_per_point=32, brdf_resolution=4)
    want, _, _ = _render("vertex", scene, sh_bands=3, rays_per_point=32)
    covered = want.max(axis=-1) > 0
    assert covered.sum() > 500
    assert np.max(np.abs(got - want)) < 1e-4 * want.max()
    materials = len(artifact.meta["materials"])
    assert materials == 2  # sphere and plane
    assert artifact.meta["material_ranks"] == [1, 1]
    assert artifact.meta["factor_error"] == [0.0, 0.0]
    # Resident: V × 1 × 9 transfer floats and one 4 × 16 RGB table per material.
    assert memory == scene.n_vertices * 9 * 4 + materials * 4 * 16 * 3 * 4


def test_term_transfer_with_unit_weight_is_the_diffuse_transfer():
    from prtbench.transport.compress.factor import HemisphereGrid
    from prtbench.transport.transfer import compute_transfer

    scene = _scene("glossy")
    positions, normals, _, _ = scene.merged()
    grid = HemisphereGrid(4, 16)
    incoming = np.stack([np.ones((4, 16)), 2.0 * np.ones((4, 16))])[None]  # (1, 2, 4, 16)
    got = factored.factored_transfer(scene, positions, normals, incoming=incoming,
                                     material_of_point=np.zeros(len(positions), int),
                                     in_grid=grid, bands=3, rays_per_point=64, progress=False)
    want = compute_transfer(scene, positions, normals, bands=3, rays_per_point=64,
                            progress=False, use_cache=False)
    assert np.allclose(got[:, 0], want, atol=1e-5)
    assert np.allclose(got[:, 1], 2.0 * want, atol=2e-5)


def test_error_against_the_unfactored_sloan_matrix_falls_with_terms():
    # Same bands and rays: the matrix is the unfactored glossy transfer. Measured mean relative
    # difference 0.106 / 0.068 / 0.053 at J = 1 / 4 / 8 (the rest is the matrix's own band
    # truncation of the lobe, which the factored form does not have).
    scene = _scene("glossy")
    matrix, matrix_memory, _ = _render("sloan-matrix", scene, sh_bands=3, rays_per_point=32)
    covered = matrix.max(axis=-1) > 0
    error, memory = {}, {}
    for j in (1, 4, 8):
        image, memory[j], _ = _render("factored-brdf", scene, terms=j, sh_bands=3,
                                      rays_per_point=32, brdf_resolution=6)
        error[j] = np.abs(image - matrix)[covered].mean() / matrix[covered].mean()
    assert error[1] > error[4] > error[8], error
    assert error[8] < 0.08 and error[1] > 0.09, error
    assert memory[1] < memory[4] < memory[8]
    # J·n² floats per vertex instead of n⁴: below the matrices while J < n².
    assert memory[4] < matrix_memory


def test_extreme_exponents_stay_finite_and_a_constant_lobe_is_one_term():
    from prtbench.scene.model import Material, Scene, SceneObject

    base = _scene("glossy")

    def scene(s):
        objects = [SceneObject(o.name, o.mesh, Material(kd=(0.2,) * 3, ks=(0.8,) * 3,
                                                          shininess=s)) for o in base.objects]
        return Scene("extreme", objects, trajectory=base.trajectory, exposure=1.0)

    for s, terms in ((0.0, 1), (1e4, 1), (1.0, 3)):
        image, _, _ = _render("factored-brdf", scene(s), light="sun", terms=terms, sh_bands=2,
                              rays_per_point=16, brdf_resolution=3)
        assert np.all(np.isfinite(image)) and image.max() > 0
    # s = 0 is the hemisphere about the mirror direction (the reference's lobe), not a constant
    # (0^0 = 1 made it rank 1 and refused here): its second term is real and changes the image.
    one, _, _ = _render("factored-brdf", scene(0.0), terms=1, sh_bands=2, rays_per_point=16,
                        brdf_resolution=3)
    two, _, _ = _render("factored-brdf", scene(0.0), terms=2, sh_bands=2, rays_per_point=16,
                        brdf_resolution=3)
    assert np.all(np.isfinite(two)) and np.abs(two - one).max() > 1e-3 * one.max()


@pytest.mark.parametrize("sets, match", [
    (["terms=2"], r"terms=2 on scene 'plants', whose materials are all diffuse .* rank 1; "
                  r"accepted: terms=1"),
    (["terms=9"], r"terms.*9"),
    (["brdf_resolution=1"], r"brdf_resolution"),
])
def test_bad_requests_are_one_line_errors_before_any_work(sets, match, tmp_path, capsys):
    assert_run_refused(["--method", "factored-brdf", "--scene", "plants", "--profile", "smoke",
                        "--variant", "diffuse"], sets, match=match, tmp_path=tmp_path,
                       capsys=capsys)


def test_textured_materials_are_refused_and_unknown_knobs_too():
    from prtbench.scene.model import Material, Scene, SceneObject, Texture

    cls = METHODS.get("factored-brdf")
    base = _scene("glossy")
    textured = Scene("textured", [SceneObject(o.name, o.mesh, Material(
        kd=Texture(np.full((4, 4, 3), 0.5, np.float32)))) for o in base.objects],
        trajectory=base.trajectory, exposure=1.0)
    with pytest.raises(InvalidInputError, match="textured"):
        cls.validate(textured, cls.make_config({}))
    with pytest.raises(PrtbenchError, match="compress"):
        cls.make_config({"compress": "cpca"})


def test_smoke_run_beats_the_trivial_images():
    from prtbench.bench.regress import case_job, gate
    from prtbench.bench.submit import run

    job = case_job("factored-brdf")  # plants glossy, 32×32 ground, sun; smoke
    summary = run(job, store=False, progress=False, echo=False).summary
    assert summary.memory_bytes > 0
    # Flat, half-bright and the unshadowed (visibility=False) image of its own precompute.
    assert not gate(job, summary.mean_metrics())
