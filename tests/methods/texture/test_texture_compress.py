"""The ``compress`` knob of ``texture-tp`` and ``texture-tpfl`` (texels as signals, Sloan 2003).

The GL render from the compressed form (per-cluster light projections on the CPU, cluster-id
and weight textures read per fragment) must equal the ordinary render of the reconstructed
transfer texture, with nearest and with bilinear lookups; memory is what is resident; the
default keeps the cache key; bad requests are one-line errors; a compressed smoke run beats
the trivial images.
"""

from __future__ import annotations

import numpy as np
import pytest

import methods.texture  # noqa: F401  (registers texture-tp, texture-tpfl)
from methods.texture.compressed import reconstructed_texture
from prtbench.api.cache import content_key
from prtbench.api.config import to_dict
from prtbench.api.method import METHODS, Artifact, artifact_key, load_or_precompute
from prtbench.scene.registry import get_scene
from prtbench.transport.compress import knobs
from prtbench.transport.lights import get_light
from tests.methods.refusal import assert_run_refused  # noqa: E402

BASE = {"sh_bands": 3, "rays_per_point": 16, "texture_resolution": 64, "padding": 1}


@pytest.fixture(scope="module")
def scene():
    return get_scene("sphere-over-plane", variant="glossy", sphere_segments=16,
                     plane_subdivisions=4).with_views(1)


def _artifact(method, scene, overrides):
    cls = METHODS.get(method)
    config = cls.make_config(overrides, profile="quick")
    cls.validate(scene, config)
    return load_or_precompute(cls, scene, config, progress=False)


def _render(method, scene, artifact, overrides):
    cls = METHODS.get(method)
    renderer = cls.renderer(scene, artifact, cls.make_config(overrides, profile="quick"),
                            width=64, height=48)
    try:
        return renderer.render(scene.trajectory.views[0], get_light("sky")), renderer.memory_bytes()
    finally:
        renderer.release()


def _reconstructed(artifact, channels):
    filled = artifact.arrays["filled"].astype(bool)
    model = knobs.load_model(artifact.arrays, n_signals=int(filled.sum()))
    arrays = {k: v for k, v in artifact.arrays.items() if not k.startswith(knobs.PREFIX)}
    arrays["transfer"] = reconstructed_texture(model, filled, channels)
    return Artifact(artifact.method, arrays, artifact.meta), model


@pytest.mark.parametrize("method", ["texture-tpfl", "texture-tp"])
@pytest.mark.parametrize("filtering", ["nearest", "bilinear"])
@pytest.mark.parametrize("form", [{"compress": "cpca", "clusters": 8, "pca_vectors": 3},
                                  {"compress": "vq", "clusters": 16},
                                  {"compress": "pca", "pca_vectors": 5}])
def test_render_from_the_compressed_form_equals_the_reconstructed_texture(scene, method,
                                                                           filtering, form):
    plain = {**BASE, "filtering": filtering}
    artifact = _artifact(method, scene, {**plain, **form})
    assert "transfer" not in artifact.arrays  # only the form is stored
    got, memory = _render(method, scene, artifact, {**plain, **form})
    rebuilt, model = _reconstructed(artifact, 9)
    want, _ = _render(method, scene, rebuilt, plain)
    covered = want.max(axis=-1) > 0
    assert covered.sum() > 1000
    assert np.max(np.abs(got - want)) <= 2e-5 * np.max(want)
    # Resident: ids (int32) and weights (RGBA layers) for all S·R² texels, the per-frame table
    # K × (1 + n′) × n² RGB, and the means and bases the CPU projects.
    texels = 64 * 64
    weights = texels * 16 * -(-model.pca_vectors // 4)
    table = model.n_clusters * (1 + model.pca_vectors) * 9 * 3 * 4
    host = model.means.nbytes + (model.bases.nbytes if model.pca_vectors else 0)
    assert memory == texels * 4 + weights + table + host
    _, uncompressed = _render(method, scene, _artifact(method, scene, plain), plain)
    assert memory < uncompressed


def test_lossless_form_renders_the_uncompressed_image_and_vq_does_not(scene):
    lossless = {"compress": "cpca", "clusters": 4, "pca_vectors": 9}
    got, _ = _render("texture-tpfl", scene, _artifact("texture-tpfl", scene, {**BASE, **lossless}),
                     {**BASE, **lossless})
    want, _ = _render("texture-tpfl", scene, _artifact("texture-tpfl", scene, BASE), BASE)
    assert np.max(np.abs(got - want)) <= 1e-4 * np.max(want)
    vq = {"compress": "vq", "clusters": 4}
    coarse, _ = _render("texture-tpfl", scene, _artifact("texture-tpfl", scene, {**BASE, **vq}),
                        {**BASE, **vq})
    assert np.max(np.abs(coarse - want)) > 0.02 * np.max(want)


def test_default_keeps_the_uncompressed_cache_key(scene):
    cls = METHODS.get("texture-tpfl")
    config = cls.make_config(BASE, profile="quick")
    before = {k: v for k, v in to_dict(config).items() if k not in knobs.KNOB_NAMES}
    assert artifact_key(cls, scene, config) == content_key(
        cls.name, cls.precompute_version, scene.content_hash(), before)
    compressed = cls.make_config({**BASE, "compress": "cpca"}, profile="quick")
    assert artifact_key(cls, scene, compressed) != artifact_key(cls, scene, config)


@pytest.mark.parametrize("sets, match", [
    (["compress=cpca", "clusters=100000"], r"clusters=100000 for 16384 texels"),
    (["compress=pca", "pca_vectors=17"], r"pca_vectors=17 for signals of dimension 16"),
    (["compress=vq", "bounces=1"], r"compress='vq' with bounces=1; accepted: bounces=0"),
    (["compress=pca", "storage=float16"], r"storage='float16' has no effect with compress"),
    (["clusters=8"], r"clusters=8 has no effect with compress='none'"),
])
def test_bad_requests_are_one_line_errors_before_any_work(sets, match, tmp_path, capsys):
    assert_run_refused(["--method", "texture-tp", "--scene", "plants", "--profile", "smoke"],
                       sets, match=match, tmp_path=tmp_path, capsys=capsys)


def test_compressed_ops_count_the_taps_and_the_projection():
    cls = METHODS.get("texture-tpfl")
    facts = dict(scene_vertices=10_000, scene_triangles=20_000, covered_pixels=40_000,
                 width=320, height=240, memory_bytes=1 << 20)

    def ops(**knobs_):
        counts = cls.op_counts(cls.make_config(knobs_, profile="quick"), **facts)
        return counts["madds"], counts["fetches"]

    small, large = ops(compress="cpca", clusters=8, pca_vectors=2), ops(compress="cpca",
                                                                         clusters=8,
                                                                         pca_vectors=8)
    assert small[0] < large[0] and small[1] < large[1]
    nearest = ops(compress="cpca", clusters=8, pca_vectors=8, filtering="nearest")
    assert nearest[1] < large[1]


def test_compressed_smoke_run_beats_the_trivial_images():
    from prtbench.bench.regress import case_job, gate
    from prtbench.bench.submit import run

    job = case_job("texture-tpfl:cpca")  # its regression variant, smoke profile
    summary = run(job, store=False, progress=False, echo=False).summary
    assert summary.config["compress"] == "cpca"
    assert not gate(job, summary.mean_metrics())
