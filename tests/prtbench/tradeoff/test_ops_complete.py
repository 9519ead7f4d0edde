"""Every registered method has an operation-count model, and the wavelet methods' counts
follow the work their frames do.

A method whose ``op_counts`` is missing (NotImplemented) or NaN drops out of ``pareto --cost
ops`` and ``advise --cost ops`` silently: the first test fails naming it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from methods.wavelet import counts
from prtbench.api import config as config_mod
from prtbench.api.method import METHODS, load_or_precompute
from prtbench.render.ops import OPS_WEIGHTS
from prtbench.scene.registry import get_scene
from prtbench.tradeoff import cost
from prtbench.transport.lights import get_light
from prtbench.transport.wavelet.sparse import SparseTransport

#: Facts of a plausible stored row at the quick profile (wavelet-image's quick resolution).
FACTS = dict(scene_vertices=10_000, scene_triangles=20_000, covered_pixels=40_000, width=320,
             height=240, memory_bytes=1 << 20)
WAVELET = ("wavelet-vertex", "wavelet-texture", "wavelet-tp", "wavelet-image")


def _counts(method: str, knobs: dict | None = None, **facts) -> dict:
    cls = METHODS.get(method)
    return cls.op_counts(cls.make_config(knobs or {}, profile="quick"), **{**FACTS, **facts})


def _ops(method: str, knobs: dict | None = None, **facts) -> float:
    found = _counts(method, knobs, **facts)
    return sum(OPS_WEIGHTS[key] * found[key] for key in OPS_WEIGHTS)


@pytest.mark.parametrize("method", METHODS.names())
def test_every_registered_method_counts_a_frame(method):
    found = _counts(method)
    assert found is not NotImplemented, f"method '{method}' declares no op_counts"
    missing = [key for key in OPS_WEIGHTS if key not in found]
    assert not missing, f"method '{method}': op_counts lacks {missing}"
    values = {key: float(found[key]) for key in OPS_WEIGHTS}
    bad = {key: v for key, v in values.items() if not (math.isfinite(v) and v >= 0)}
    assert not bad, f"method '{method}': op_counts gives {bad}"
    assert values["madds"] > 0, f"method '{method}': no multiply-adds in a frame"
    # The path the fronts take: a stored row's config and facts through the cost module.
    cls = METHODS.get(method)
    row = {"method": method, **FACTS,
           "config": config_mod.to_dict(cls.make_config({}, profile="quick"))}
    assert cost.cost_unavailable_reason(row, "ops") is None
    assert cost.cost_value(row, "ops") > 0


def _increasing(method: str, knob: str, values, base: dict | None = None) -> list[float]:
    series = [_ops(method, {**(base or {}), knob: v}) for v in values]
    assert all(a < b for a, b in zip(series, series[1:])), (method, knob, series)
    return series


@pytest.mark.parametrize("method", WAVELET)
def test_wavelet_counts_grow_with_light_terms_and_cubemap(method):
    # The selection's partial sort and the sparse product over the k columns grow with k.
    _increasing(method, "light_terms", [1, 16, 64, 256, 1024])
    for key in ("madds", "fetches", "bytes"):
        series = [_counts(method, {"light_terms": k})[key] for k in (16, 64, 256)]
        assert series[0] < series[1] < series[2], (method, key, series)
    # The light's Haar transform and the selection run over all 6N² coefficients.
    _increasing(method, "cubemap", [8, 16, 32, 64], base={"light_terms": 64})


@pytest.mark.parametrize("method", WAVELET)
def test_kept_coefficients_bound_the_product(method):
    # Beyond keep·6N² terms a point has nothing more to give: more kept, more work.
    base = {"light_terms": 1024, "cubemap": 32}
    _increasing(method, "keep", [0.02, 0.05, 0.1], base=base)
    low = [_ops(method, {"light_terms": 16, "cubemap": 32, "keep": f}) for f in (0.25, 0.5)]
    if method == "wavelet-tp":
        # The triple products search every stored visibility entry, lit or not.
        assert low[0] < low[1]
    else:
        # Below it, a point gives each of the k columns at most one entry, whatever it keeps.
        assert low[0] == pytest.approx(low[1])


def test_wavelet_texture_grows_with_texture_resolution():
    # Every texel is relit and uploaded each frame (the texel bound is the whole texture).
    series = _increasing("wavelet-texture", "texture_resolution", [64, 128, 256, 512])
    assert series[-1] > 10 * series[0]


def test_wavelet_tp_costs_more_than_wavelet_vertex_at_equal_terms():
    # Per vertex the triple products binary-search the stored visibility among the BRDF's
    # entries and project (or look up) the glossy BRDF, against k gathered entries.
    for cubemap in (8, 16, 32):
        for k in (16, 100, 384):
            knobs = {"cubemap": cubemap, "light_terms": k}
            vertex = _ops("wavelet-vertex", knobs)
            assert _ops("wavelet-tp", knobs) > vertex
            assert _ops("wavelet-tp", {**knobs, "brdf_table": 4}) > vertex


def test_wavelet_tp_brdf_knobs():
    _increasing("wavelet-tp", "brdf_keep", [16, 64, 256])
    _increasing("wavelet-tp", "brdf_samples", [1, 2, 4])
    # The table replaces the per-frame projection by a gather: cheaper, and the projection's
    # subsamples no longer count.
    assert _ops("wavelet-tp", {"brdf_table": 8}) < _ops("wavelet-tp")
    assert (_ops("wavelet-tp", {"brdf_table": 8, "brdf_samples": 4})
            == pytest.approx(_ops("wavelet-tp", {"brdf_table": 8})))


def test_wavelet_image_sh_lighting_uses_every_term():
    sh = [_ops("wavelet-image", {"lighting": "sh", "light_terms": k}) for k in (5, 500)]
    assert sh[0] == pytest.approx(sh[1])  # light_terms is not read with lighting='sh'
    # Every term of the SH light's cubemap, ranked by magnitude: the work of k = 6N² terms.
    m = 6 * 32**2
    assert sh[0] == pytest.approx(_ops("wavelet-image", {"light_terms": m,
                                                         "selection": "magnitude"}))
    assert sh[0] > _ops("wavelet-image", {"light_terms": 100})


def test_compressed_wavelet_vertex_grows_with_its_form():
    base = {"compress": "cpca"}
    _increasing("wavelet-vertex", "pca_vectors", [1, 4, 16], base={**base, "clusters": 16})
    _increasing("wavelet-vertex", "clusters", [1, 16, 64], base={**base, "pca_vectors": 4})
    _increasing("wavelet-vertex", "light_terms", [16, 64, 256],
                base={**base, "clusters": 16, "pca_vectors": 4})


def test_quickselect_count_and_haar_count():
    # Knuth's expected comparisons: 2m for the extreme ranks, the most (2 + 2 ln 2)·m at the
    # median; nothing when every coefficient is kept.
    m = 6144
    assert counts.quickselect_comparisons(m, 1) == pytest.approx(2 * m, rel=2e-3)
    assert counts.quickselect_comparisons(m, m // 2) == pytest.approx((2 + 2 * math.log(2)) * m)
    assert counts.quickselect_comparisons(m, m) == 0
    # Haar: 3 passes over s² values per level s = N … 2, i.e. 3·(N² − 1)·4/3 = 4·(N² − 1).
    for n in (1, 2, 8, 32):
        assert counts.haar_counts(signals=1, n=n, value_bytes=8)["madds"] == 4 * (n * n - 1)


def test_entry_bound_holds_on_a_real_transport():
    # The product's count is the bound P·min(k, kept): the entries the selected columns
    # really hold (exact zeros below the horizon are not stored) never exceed it.
    from methods.wavelet.relight import Relighter

    scene = get_scene("sphere-over-plane", plane_subdivisions=4)
    cls = METHODS.get("wavelet-vertex")
    config = cls.make_config({"cubemap": 8, "keep": 0.1}, profile="quick")
    transport = SparseTransport.from_arrays(load_or_precompute(cls, scene, config,
                                                               progress=False).arrays)
    m = counts.coefficients(8)
    kept = counts.kept_per_point(config.keep, m)
    per_column = np.diff(transport.indptr)
    for k in (6, 40, 200):
        for selection in ("area", "magnitude"):
            relight = Relighter(transport, cls.make_config(
                {"cubemap": 8, "keep": 0.1, "light_terms": k, "selection": selection}))
            _, terms = relight.select(get_light("sky"))
            touched = int(per_column[terms].sum())
            bound = transport.n_points * counts.entries_per_point(k, kept)
            assert 0 < touched <= bound, (k, selection, touched, bound)
