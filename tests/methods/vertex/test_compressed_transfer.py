"""The ``compress`` knob of ``vertex`` and ``sloan-matrix`` (PCA / VQ / CPCA, Sloan 2003).

The GL render from the compressed form (per-cluster light projections on the CPU, per-vertex
dot products in the shader) must equal the ordinary render of the reconstructed transfer;
memory is the compressed form; the default leaves the cache key as it was; bad requests are
one-line errors before any work; compressed smoke runs beat the trivial images.
"""

from __future__ import annotations

import numpy as np
import pytest

import methods.vertex.glossy  # noqa: F401  (registers sloan-matrix)
from prtbench.api.cache import content_key
from prtbench.api.config import to_dict
from prtbench.api.errors import PrtbenchError
from prtbench.api.method import METHODS, Artifact, artifact_key, load_or_precompute
from prtbench.scene.registry import get_scene
from prtbench.transport.compress import knobs
from prtbench.transport.lights import get_light
from tests.methods.refusal import assert_run_refused  # noqa: E402

BASE = {"sh_bands": 3, "rays_per_point": 32}


def _scene(method):
    # The glossy variant for the matrices: they see both shadows and a highlight.
    variant = "glossy" if method == "sloan-matrix" else "diffuse"
    return get_scene("sphere-over-plane", variant=variant, sphere_segments=24,
                     plane_subdivisions=12).with_views(1)


def _render(method, scene, artifact, overrides, light="sky"):
    cls = METHODS.get(method)
    config = cls.make_config(overrides, profile="quick")
    renderer = cls.renderer(scene, artifact, config, width=64, height=48)
    try:
        return renderer.render(scene.trajectory.views[0], get_light(light)), renderer.memory_bytes()
    finally:
        renderer.release()


def _compressed(method, scene, **form):
    cls = METHODS.get(method)
    config = cls.make_config({**BASE, **form}, profile="quick")
    cls.validate(scene, config)
    return load_or_precompute(cls, scene, config, progress=False)


@pytest.mark.parametrize("method, form", [
    ("vertex", {"compress": "cpca", "clusters": 8, "pca_vectors": 3}),
    ("vertex", {"compress": "vq", "clusters": 16}),
    ("vertex", {"compress": "pca", "pca_vectors": 4}),
    # RGB interreflected transfer: signals of 3n² floats, one operator per colour channel.
    ("vertex", {"compress": "cpca", "clusters": 8, "pca_vectors": 5, "bounces": 1}),
    ("sloan-matrix", {"compress": "cpca", "clusters": 8, "pca_vectors": 3}),
])
def test_render_from_the_compressed_form_equals_the_reconstructed_transfer(method, form):
    scene = _scene(method)
    artifact = _compressed(method, scene, **form)
    assert not any(k in artifact.arrays for k in ("transfer", "matrices"))  # only the form
    got, memory = _render(method, scene, artifact, {**BASE, **form})
    model = knobs.load_model(artifact.arrays, n_signals=scene.n_vertices)
    rebuilt = model.reconstruct().astype(np.float32)
    key = "matrices" if method == "sloan-matrix" else "transfer"
    if key == "matrices":
        rebuilt = rebuilt.reshape(len(rebuilt), 9, 9)
    elif form.get("bounces"):
        rebuilt = rebuilt.reshape(len(rebuilt), 9, 3)
    plain = {**BASE, **({"bounces": form["bounces"]} if "bounces" in form else {})}
    want, _ = _render(method, scene, Artifact(method, {key: rebuilt}), plain)
    covered = want.max(axis=-1) > 0
    assert covered.sum() > 500
    assert np.max(np.abs(got - want)) <= 2e-5 * np.max(want)
    # Resident: the compressed arrays and the per-frame projection table, nothing else.
    outputs = 9 if method == "sloan-matrix" else 1
    table = model.n_clusters * (1 + model.pca_vectors) * outputs * 3 * 4
    assert memory == model.nbytes + table
    assert memory < scene.n_vertices * model.dimension * 4


@pytest.mark.parametrize("method", ["vertex", "sloan-matrix"])
def test_lossless_form_renders_the_uncompressed_image(method):
    scene = _scene(method)
    d = 9 if method == "vertex" else 81
    lossless = _compressed(method, scene, compress="cpca", clusters=4, pca_vectors=d)
    got, _ = _render(method, scene, lossless, {**BASE, "compress": "cpca", "clusters": 4,
                                                "pca_vectors": d})
    plain = _compressed(method, scene)
    want, _ = _render(method, scene, plain, BASE)
    assert np.max(np.abs(got - want)) <= 1e-4 * np.max(want)
    # And a lossy VQ form is visibly different (the comparison above can fail).
    vq = _compressed(method, scene, compress="vq", clusters=4)
    coarse, _ = _render(method, scene, vq, {**BASE, "compress": "vq", "clusters": 4})
    assert np.max(np.abs(coarse - want)) > 0.02 * np.max(want)


@pytest.mark.parametrize("method", ["vertex", "sloan-matrix"])
def test_default_keeps_the_uncompressed_cache_key(method):
    cls = METHODS.get(method)
    scene = _scene(method)
    config = cls.make_config(BASE, profile="quick")
    # sloan-matrix's later `bounces` knob leaves the key at its default 0 too (the same keys
    # as before it existed), so the key before both knobs lacks it.
    before = {k: v for k, v in to_dict(config).items()
              if k not in knobs.KNOB_NAMES
              and not (method == "sloan-matrix" and k == "bounces" and v == 0)}
    assert artifact_key(cls, scene, config) == content_key(
        cls.name, cls.precompute_version, scene.content_hash(), before)
    compressed = cls.make_config({**BASE, "compress": "cpca"}, profile="quick")
    assert artifact_key(cls, scene, compressed) != artifact_key(cls, scene, config)


def test_errors_shrink_as_the_form_grows():
    scene = _scene("vertex")
    rmse = {(k, n): _compressed("vertex", scene, compress="cpca", clusters=k,
                                pca_vectors=n).meta["transfer_rmse"]
            for k, n in ((1, 1), (1, 4), (8, 1), (8, 4))}
    assert rmse[(1, 4)] < rmse[(1, 1)] and rmse[(8, 4)] < rmse[(8, 1)]
    assert rmse[(8, 1)] < rmse[(1, 1)] and rmse[(8, 4)] < rmse[(1, 4)]


@pytest.mark.parametrize("method, sets, match", [
    ("vertex", ["compress=cpca", "clusters=100000"], "clusters=100000 for .* vertices"),
    ("vertex", ["compress=pca", "pca_vectors=17"], "pca_vectors=17 for signals of dimension 16"),
    ("vertex", ["clusters=8"], "clusters=8 has no effect with compress='none'"),
    ("vertex", ["compress=vq", "pca_vectors=2"], "pca_vectors=2 has no effect with compress='vq'"),
    ("vertex", ["compress=zip"], "accepted: none, pca, vq, cpca"),
    ("sloan-matrix", ["compress=cpca", "clusters=64", "pca_vectors=8", "max_bytes=100000"],
     r"would store \d+ bytes, over the limit of 100000 bytes"),
])
def test_bad_requests_are_one_line_errors_before_any_work(method, sets, match, tmp_path,
                                                          capsys):
    assert_run_refused(["--method", method, "--scene", "plants", "--profile", "smoke",
                        "--variant", "glossy" if method == "sloan-matrix" else "diffuse"],
                       sets, match=match, tmp_path=tmp_path, capsys=capsys)


def test_compress_on_a_method_without_stored_transfer_is_refused():
    with pytest.raises(PrtbenchError, match="unknown config key .* 'compress'"):
        METHODS.get("irradiance-volume").make_config({"compress": "cpca"})


@pytest.mark.parametrize("method, form", [
    ("vertex", {"compress": "cpca", "clusters": 16, "pca_vectors": 4}),
    # ~30 s; regress gates sloan-matrix:cpca in make test
    pytest.param("sloan-matrix", {"compress": "cpca", "clusters": 16, "pca_vectors": 4},
                 marks=pytest.mark.slow),
])
def test_compressed_smoke_run_beats_the_trivial_images(method, form):
    from prtbench.bench.regress import case_job, gate
    from prtbench.bench.submit import run

    job = case_job(method, overrides=form)  # its regression case, smoke profile
    summary = run(job, store=False, progress=False, echo=False).summary
    assert summary.config["compress"] == "cpca"
    # Flat, half-bright and the same compression of the unshadowed transfer.
    assert not gate(job, summary.mean_metrics()), method
