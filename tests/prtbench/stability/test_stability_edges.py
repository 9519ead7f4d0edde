"""The stability matrix's method edges (issue #15): the catalogue gets the 10⁶-triangle mesh,
CPCA extremes, probes inside geometry, |∇d| ≪ 1 and wavelet k = 1 / all; the case scenes do
what the cases say; derived knobs are resolved from the scene and the moderate artifact."""

from __future__ import annotations

import numpy as np
import pytest

from prtbench.api.method import METHODS
from prtbench.stability import edges
from prtbench.stability.case import Case
from prtbench.stability.cases import method_cases


def _cases(method: str, profile: str = "quick") -> dict[str, Case]:
    return {c.name: c for c in method_cases(METHODS.get(method), profile=profile)}


def test_per_vertex_methods_get_the_large_mesh_at_its_real_size_in_quick():
    per_vertex = [m for m in METHODS.names() if METHODS.get(m).storage == "per-vertex"]
    assert {"vertex", "sloan-matrix", "wavelet-vertex", "wavelet-tp"} <= set(per_vertex)
    for method in per_vertex:
        case = _cases(method)["mesh=1e6-triangles"]
        segments = case.scene_params["sphere_segments"]
        assert case.scene == "sphere-over-plane" and edges.sphere_triangles(segments) >= 1_000_000
        assert case.timeout_factor > 1.0
        smoke = _cases(method, "smoke")["mesh=1e5-triangles-smoke-size"]
        assert "quick measures 1e6" in smoke.note
    for method in ("texture-tp", "irradiance-volume", "learnt", "data-driven"):
        assert not any(name.startswith("mesh=") for name in _cases(method))


def test_the_sphere_triangle_formula_is_the_builders():
    from prtbench.scene.registry import get_scene

    scene = get_scene("sphere-over-plane", sphere_segments=40, plane_size=4.0)
    sphere = next(o for o in scene.objects if o.name != "ground")
    assert sphere.mesh.n_triangles == edges.sphere_triangles(40)


def test_cpca_extremes_for_the_methods_that_compress():
    for method in ("vertex", "sloan-matrix"):
        cases = _cases(method)
        assert cases["compress=cpca clusters=signals"].derived == {"clusters": "signals"}
        assert cases["compress=cpca pca_vectors=0"].overrides == {"compress": "cpca",
                                                                 "pca_vectors": 0}
        assert cases["compress=cpca pca_vectors=d"].derived == {"pca_vectors": "dimension"}
    # texture-tp compresses too, but its signals are texels: no per-vertex N and d for it.
    assert not any(name.startswith("compress=") for name in _cases("texture-tp"))
    assert not any(name.startswith("compress=") for name in _cases("irradiance-volume"))


def test_wavelet_k_is_one_and_every_coefficient_of_the_cubemap():
    for method in ("wavelet-vertex", "wavelet-texture"):
        for profile in ("smoke", "quick"):
            cls = METHODS.get(method)
            n = cls.make_config(profile=profile).cubemap
            cases = _cases(method, profile)
            assert cases["light_terms=1"].overrides == {"light_terms": 1}
            assert cases["light_terms=all"].overrides == {"light_terms": 6 * n * n}
            assert cases["keep=1"].overrides == {"keep": 1.0}


def test_probe_and_sdf_edges_go_to_the_methods_they_concern():
    volume = _cases("irradiance-volume")
    assert volume["geometry=solid-block"].geometry == "solid-block"
    assert volume["geometry=solid-block invalid_backface_fraction=1"].overrides == {
        "invalid_backface_fraction": 1.0}
    assert _cases("learnt-sdf")["sdf-gradient=0.01"].distance_factor == 0.01
    assert "geometry=solid-block" not in _cases("vertex")
    assert "sdf-gradient=0.01" not in _cases("vertex")


def test_solid_block_is_a_closed_box_on_the_ground_holding_probes():
    import trimesh

    from prtbench.scene.registry import get_scene
    from prtbench.stability.scenes import case_scene

    base = get_scene("sphere-over-plane", sphere_segments=16, plane_size=4.0).with_views(1)
    scene = case_scene(base, Case("geometry=solid-block", "scene", geometry="solid-block"))
    block = scene.objects[-1].mesh
    assert scene.objects[-1].name == "solid-block" and len(scene.objects) == len(base.objects) + 1
    tm = trimesh.Trimesh(block.positions, block.faces, process=True)
    assert tm.is_watertight and tm.volume > 0  # closed, faces outward
    lo, hi = block.positions.min(0), block.positions.max(0)
    assert lo[1] == pytest.approx(0.0, abs=1e-6)  # stands on the y = 0 ground
    blo, bhi = base.bounds()
    assert hi[1] == pytest.approx((bhi[1] - 0.0) / 3.0, rel=1e-5)
    assert (hi - lo)[0] == pytest.approx(0.5 * (bhi - blo)[0], rel=1e-5)
    # Flat normals: every vertex normal is one of the six axis directions.
    assert np.allclose(np.abs(block.normals).max(1), 1.0, atol=1e-6)


def test_distance_scale_keeps_the_surface_and_divides_the_gradient_in_numpy_and_glsl():
    from prtbench.render.sdf_gl import evaluate_gl
    from prtbench.scene.model import Material, Scene, SceneObject
    from prtbench.scene.registry import get_scene
    from prtbench.stability.scenes import case_scene
    from prtbench.transport import sdf

    surface = sdf.SdfSurface(sdf.Sphere(0.5, material=0).translate(0.0, 1.0, 0.0),
                             ((-1.0, 0.0, -1.0), (1.0, 2.0, 1.0)), (Material(name="m0"),))
    mesh_scene = get_scene("sphere-over-plane", sphere_segments=16, plane_size=4.0)
    base = Scene("sdf-test", [SceneObject(o.name, o.mesh, o.material) for o in mesh_scene.objects],
                 trajectory=mesh_scene.trajectory, sdf=surface)
    scaled = case_scene(base, Case("sdf-gradient=0.01", "scene", distance_factor=0.01))
    rng = np.random.default_rng(3)
    points = rng.uniform(-1.0, 2.0, size=(500, 3))
    d, d2 = surface.root.evaluate(points), scaled.sdf.root.evaluate(points)
    assert np.allclose(d2, 0.01 * d, rtol=1e-12, atol=0)
    g = np.linalg.norm(scaled.sdf.root.gradient(points, step=1e-4), axis=1)
    assert np.allclose(g, 0.01, rtol=1e-3)
    assert scaled.content_hash() != base.content_hash()
    assert [o.mesh.n_triangles for o in scaled.objects] == [o.mesh.n_triangles
                                                          for o in base.objects]
    gl_d, _, _ = evaluate_gl(scaled.sdf, points)
    assert np.allclose(gl_d, d2, atol=1e-6)
    with pytest.raises(Exception, match="accepted: SDF scenes"):
        case_scene(mesh_scene, Case("sdf-gradient=0.01", "scene", distance_factor=0.01))


def test_derived_knobs_are_the_vertex_count_and_the_transfer_dimension(tmp_path):
    from prtbench.bench.runner import prepare
    from prtbench.stability.cases import base_case
    from prtbench.stability.run import case_job, derive_overrides
    from prtbench.stability.scenes import case_scene

    base = {**base_case(METHODS.get("vertex")),
            "scene_params": {"sphere_segments": 16, "plane_size": 4.0}}
    case = Case("x", "storage", overrides={"compress": "cpca"})
    prepared = prepare(case_job("vertex", case, profile="smoke", base=base), store=False)
    scene = case_scene(prepared.scene, case)
    got = derive_overrides(prepared, scene, {"clusters": "signals", "pca_vectors": "dimension"})
    bands = prepared.config.sh_bands
    assert got["clusters"] == scene.n_vertices
    assert got["pca_vectors"] in (bands * bands, 3 * bands * bands)
