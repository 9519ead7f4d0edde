"""AO and bent normals: AO and b from the 2-band transfer, equality with ``vertex`` at 3 bands on
an unoccluded convex object, the white furnace, occlusion under a sphere, memory, storage,
bad input, and smoke runs through the runner that beat the trivial images."""

from __future__ import annotations

import numpy as np
import pytest

import methods.ao_bent_normal.method as abn  # registers both methods
from prtbench.api.errors import InvalidInputError
from prtbench.api.method import METHODS, load_or_precompute
from prtbench.scene.model import Material, Scene, SceneObject, Trajectory, View
from prtbench.scene.registry import get_scene
from prtbench.transport.lights import get_light
from prtbench.transport.raytrace import geometry_mask
from prtbench.transport.sh import eval_sh


def _render(name, scene, *, light="sky", width=96, height=72, **overrides):
    cls = METHODS.get(name)
    config = cls.make_config(overrides, profile="quick")
    artifact = load_or_precompute(cls, scene, config, progress=False)
    renderer = cls.renderer(scene, artifact, config, width=width, height=height)
    try:
        image = renderer.render(scene.trajectory.views[0], get_light(light))
        return image, renderer.memory_breakdown(), renderer.memory_bytes(), artifact
    finally:
        renderer.release()


def _sphere_scene(kd=0.5):
    base = get_scene("sphere-over-plane", radius=0.5, height=1.0)
    sphere = max(base.objects, key=lambda o: o.mesh.n_vertices)  # the sphere, not the plane
    view = View(eye=(0.0, 1.0, 3.0), target=(0.0, 1.0, 0.0), fov_y=40.0)
    return Scene("lone-sphere", [SceneObject("sphere", sphere.mesh, Material(kd=(kd, kd, kd)))],
                 trajectory=Trajectory((view,)), exposure=1.0)


# --- the bake ---------------------------------------------------------------------------------

def test_ao_and_bent_normal_from_the_transfer_of_a_visible_cone():
    # Transfer of V = 1 on a set of directions around d, cosine about n = +z: by Monte Carlo.
    rng = np.random.default_rng(0)
    u = rng.random((200000, 2))
    local = np.stack([np.sqrt(u[:, 0]) * np.cos(2 * np.pi * u[:, 1]),
                      np.sqrt(u[:, 0]) * np.sin(2 * np.pi * u[:, 1]),
                      np.sqrt(1 - u[:, 0])], axis=1)  # cosine-weighted about +z
    d = np.array([0.6, 0.0, 0.8])
    visible = local @ d > 0.7
    transfer = np.pi * (eval_sh(local, 2) * visible[:, None]).mean(axis=0)
    out = abn.ao_bent_from_transfer(transfer[None], np.array([[0.0, 0.0, 1.0]]))[0]
    assert out[3] == pytest.approx(visible.mean(), rel=1e-6)
    expected = local[visible].mean(axis=0)
    assert np.allclose(out[:3], expected / np.linalg.norm(expected), atol=1e-5)


def test_fully_blocked_points_have_zero_ao_and_keep_their_normal():
    out = abn.ao_bent_from_transfer(np.zeros((2, 4)), np.array([[0.0, 2.0, 0.0], [1.0, 0, 0]]))
    assert np.array_equal(out[:, 3], [0.0, 0.0])
    assert np.allclose(out[:, :3], [[0, 1, 0], [1, 0, 0]])


def test_texel_storage_round_trips_within_8_bits():
    rng = np.random.default_rng(1)
    b = rng.normal(size=(64, 3))
    values = np.concatenate([b / np.linalg.norm(b, axis=1, keepdims=True), rng.random((64, 1))], 1)
    stored = abn.texel_storage(values, "rgba8")
    assert stored.dtype == np.uint8
    decoded = np.concatenate([stored[:, :3] / 255.0 * 2 - 1, stored[:, 3:] / 255.0], 1)
    assert np.abs(decoded - values).max() <= 1.0 / 255.0 + 1e-9
    assert abn.texel_storage(values, "rgba16f").dtype == np.float16


# --- exactness --------------------------------------------------------------------------------

@pytest.mark.parametrize("light", ["sky", "sun"])
def test_unoccluded_convex_object_equals_vertex_at_3_bands(light):
    # AO = 1 and b = n up to the ray pattern's mean, so kd/π·E(n) = kd/π·Σ_{i<9} T_i L_i.
    scene = _sphere_scene()
    ao, parts, memory, artifact = _render("ao-bent-normal", scene, light=light,
                                          rays_per_point=512)
    vertex, *_ = _render("vertex", scene, light=light, sh_bands=3, rays_per_point=512)
    covered = geometry_mask(scene, scene.trajectory.views[0], 96, 72)
    assert covered.sum() > 500
    assert np.allclose(artifact.arrays["ao_bent"][:, 3], 1.0, atol=1e-6)
    # Measured: max 0.0014 of 0.72 (sky) and 0.54 (sun): the T_2m's sampling noise.
    assert np.abs(ao - vertex)[covered].max() < 0.004 * vertex[covered].max()
    assert parts["gpu: AO and bent normal per vertex (float32 RGBA)"] == scene.n_vertices * 16
    assert memory == scene.n_vertices * 16  # the method's own data; the mesh is the scene's


@pytest.mark.parametrize("name", ["ao-bent-normal", "ao-bent-normal-texture"])
def test_white_furnace_is_the_albedo(name):
    image, *_ = _render(name, _sphere_scene(0.5), light="white")
    covered = image[..., 0] > 0
    assert covered.sum() > 500
    # rgba8 stores AO = 1 exactly (255); the bent normal's 8 bits do not matter under white light.
    assert np.allclose(image[covered], 0.5, atol=2e-3)
    assert np.all(image[~covered] == 0)


def test_texture_form_matches_the_vertex_form_on_the_sphere():
    scene = _sphere_scene()
    vertex, *_ = _render("ao-bent-normal", scene, light="sun")
    for fmt, per_texel in (("rgba8", 4), ("rgba16f", 8)):
        texture, parts, memory, artifact = _render("ao-bent-normal-texture", scene, light="sun",
                                                   texel_format=fmt, texture_resolution=256)
        covered = vertex[..., 0] > 0
        # Measured 0.0045 (rgba8) of 0.54: the 8-bit bent normal and Gouraud vs per pixel.
        assert np.abs(texture - vertex)[covered].max() < 0.015, fmt
        name = f"gpu: AO and bent normal texture ({fmt.upper()})"
        assert memory == parts[name] == 256 * 256 * per_texel
        assert artifact.meta["texture_resolution"] == 256


def test_occlusion_under_a_sphere_darkens_and_bends_away():
    scene = get_scene("sphere-over-plane", plane_subdivisions=32)
    cls = METHODS.get("ao-bent-normal")
    artifact = load_or_precompute(cls, scene, cls.make_config({"rays_per_point": 256}),
                                  progress=False)
    ground = next(o for o in scene.objects if o.name == "ground")
    offset = sum(o.mesh.n_vertices for o in scene.objects[:scene.objects.index(ground)])
    values = artifact.arrays["ao_bent"][offset:offset + ground.mesh.n_vertices]
    p = ground.mesh.positions
    radial = np.linalg.norm(p[:, [0, 2]], axis=1)
    near, far = radial < 0.3, radial > 1.6
    assert values[near, 3].mean() < values[far, 3].mean() - 0.1
    # Near the contact point, b leans away from the sphere (outwards in x–z).
    ring = (radial > 0.3) & (radial < 0.8)
    outward = np.sum(values[ring][:, [0, 2]] * p[ring][:, [0, 2]], axis=1)
    assert np.mean(outward > 0) > 0.9


# --- bad input and the runner -----------------------------------------------------------------

@pytest.mark.parametrize("name", ["ao-bent-normal", "ao-bent-normal-texture"])
def test_glossy_scene_is_refused_in_one_line(name):
    from prtbench.bench.job import Job
    from prtbench.bench.runner import prepare

    with pytest.raises(InvalidInputError) as info:
        prepare(Job(method=name, scene="sphere-over-plane", variant="glossy", profile="smoke"),
                store=False)
    assert "glossy" in str(info.value) and "\n" not in str(info.value)


def test_bad_texel_format_is_refused():
    with pytest.raises(InvalidInputError, match="texel_format"):
        METHODS.get("ao-bent-normal-texture").make_config({"texel_format": "bc5"})


@pytest.mark.slow  # 8-20 s each; `prtbench regress` gates the same cases
@pytest.mark.parametrize("name", ["ao-bent-normal", "ao-bent-normal-texture"])
def test_smoke_run_through_the_runner_beats_the_trivial_images(name):
    from prtbench.bench.regress import case_job, trivial_results
    from prtbench.bench.submit import run
    from prtbench.bench.trivial import gate_failures

    job = case_job(name)
    summary = run(job, store=False, progress=False, echo=False).summary
    metrics = summary.mean_metrics()
    trivial, _ = trivial_results(job)
    assert not gate_failures(metrics, trivial)  # flat, half and the unshadowed render
    # Measured: 20.8 / 21.0 dB against the flat image's 17.2.
    assert metrics["psnr_masked"] >= trivial["flat"]["psnr_masked"] + 3.0
    assert summary.memory_bytes > 0


def test_op_counts_grow_with_the_covered_pixels():
    for name in ("ao-bent-normal", "ao-bent-normal-texture"):
        cls = METHODS.get(name)
        config = cls.make_config(profile="smoke")
        few, many = (cls.op_counts(config, scene_vertices=1000, scene_triangles=2000,
                                   covered_pixels=p, width=64, height=64, memory_bytes=1)
                     for p in (10, 1000))
        assert all(many[k] >= few[k] > 0 for k in ("madds", "bytes"))
