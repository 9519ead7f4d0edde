"""prt_shading.glsl against prtbench.transport.sh in float64: zonal Phong coefficients, glossy shading of
transferred radiance, triple product (sparse Γ) and TPFL, in the vertex and fragment stages."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from prtbench.render import gl
from prtbench.render import prt_shading as _triple
from prtbench.transport import sh

PROBE_DIR = Path(__file__).parent / "shaders"
S_VALUES = (0.0, 1.0, 10.0, 100.0, 1000.0, 10000.0)


def _random_cases(bands: int, cases: int, seed: int, s_values=S_VALUES):
    rng = np.random.default_rng(seed)
    nc = bands * bands
    transfer = rng.normal(size=(cases, nc))
    transferred = rng.normal(size=(cases, nc, 3))
    kd = rng.uniform(0.0, 0.6, size=(cases, 3))
    ks = rng.uniform(0.0, 0.4, size=(cases, 3))
    s = np.resize(np.asarray(s_values, float), cases)
    normal = rng.normal(size=(cases, 3))
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    wo = rng.normal(size=(cases, 3))
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    wo *= np.sign(np.sum(wo * normal, axis=1, keepdims=True))  # eye on the front side
    light = rng.normal(size=(nc, 3))
    return dict(T=transfer, H=transferred, kd=kd, ks=ks, s=s, n=normal, wo=wo, L=light)


def _run_probe(bands: int, c: dict, *, in_vertex: bool) -> dict:
    nc = bands * bands
    cases = len(c["T"])
    inputs = np.concatenate([c["T"], c["H"].reshape(cases, -1), c["kd"], c["ks"], c["s"][:, None],
                             c["n"], c["wo"]], axis=1).astype(np.float32)
    assert inputs.shape[1] == 4 * nc + 13
    out_stride = 6 * nc + 3 + bands
    ctx = gl.create_context()
    program = gl.load_program(ctx, "prt_shading_probe.vert", "prt_shading_probe.frag",
                              defines={"SH_BANDS": bands, "CASES": cases,
                                       "PROBE_IN_VERTEX": in_vertex},
                              search_path=[PROBE_DIR])
    buffers = [ctx.buffer(inputs.tobytes()),
               ctx.buffer(reserve=cases * out_stride * 4),
               ctx.buffer(_triple.gamma_buffer_data(bands)),
               ctx.buffer(_triple.tpfl_buffer_data(c["L"], bands))]
    target = gl.RenderTarget(ctx, cases, 1)
    vao = ctx.vertex_array(program, [])
    try:
        buffers[0].bind_to_storage_buffer(0)
        buffers[1].bind_to_storage_buffer(3)
        buffers[2].bind_to_storage_buffer(_triple.GAMMA_BINDING)
        buffers[3].bind_to_uniform_block(_triple.TPFL_BINDING)
        program["light_sh"].write(c["L"].astype(np.float32).tobytes())
        target.use()
        target.clear()
        vao.render(mode=gl.moderngl.POINTS, vertices=cases)
        ctx.finish()
        out = np.frombuffer(buffers[1].read(), np.float32).reshape(cases, out_stride).astype(float)
    finally:
        vao.release()
        target.release()
        for b in buffers:
            b.release()
        program.release()
    return {"tp": out[:, :3 * nc].reshape(cases, nc, 3),
            "tpfl": out[:, 3 * nc:6 * nc].reshape(cases, nc, 3),
            "shade": out[:, 6 * nc:6 * nc + 3],
            "g": out[:, 6 * nc + 3:]}


def _expected_shade(bands: int, c: dict) -> np.ndarray:
    shade = np.empty((len(c["T"]), 3))
    for p in range(len(shade)):
        r = 2 * np.dot(c["n"][p], c["wo"][p]) * c["n"][p] - c["wo"][p]
        zonal = sh.phong_zonal(c["s"][p], bands)
        glossy = [sh.zonal_convolve(c["H"][p, :, ch], zonal, r) for ch in range(3)]
        shade[p] = c["kd"][p] / np.pi * np.sqrt(4 * np.pi) * c["H"][p, 0] + c["ks"][p] * glossy
    return shade


def _rel_err(got: np.ndarray, want: np.ndarray) -> float:
    """Max error per case, relative to that case's largest magnitude."""
    axes = tuple(range(1, want.ndim))
    scale = np.max(np.abs(want), axis=axes, keepdims=True)
    return float(np.max(np.abs(got - want) / scale))


@pytest.mark.parametrize("bands, in_vertex", [(3, True), (5, True), (8, True), (5, False),
                                              (8, False)])
def test_probe_matches_numpy(bands, in_vertex):
    c = _random_cases(bands, 24, seed=bands)
    got = _run_probe(bands, c, in_vertex=in_vertex)
    tp_ref = sh.triple_product(c["T"], c["L"], bands)  # (N, n², 3)
    assert _rel_err(got["tp"], tp_ref) < 1e-4
    assert _rel_err(got["tpfl"], tp_ref) < 1e-4
    # TP (sparse Γ loop) and TPFL (dense M) are the same float32 sum in a different order.
    assert _rel_err(got["tpfl"], got["tp"]) < 1e-5
    assert _rel_err(got["shade"], _expected_shade(bands, c)) < 1e-4


def test_phong_zonal_coefficients_match_for_s_up_to_1e4():
    bands = 8
    c = _random_cases(bands, len(S_VALUES), seed=1)
    got = _run_probe(bands, c, in_vertex=True)["g"]
    for p, s in enumerate(S_VALUES):
        want = sh.phong_zonal(s, bands)
        # Exact zeros (s − l + 2 = 0 at integer s) must stay zero; others agree to 1e-5 relative.
        np.testing.assert_allclose(got[p], want, rtol=1e-5, atol=1e-7, err_msg=f"s={s}")
        assert np.all(np.isfinite(got[p]))


def test_white_light_glossy_furnace_in_shader():
    # L = 1, no occlusion, H = projection of max(n·ω, 0): the diffuse part is exactly kd and
    # the glossy part is ks·(cosine ⋆ Phong lobe)(r), i.e. the SH-truncated value of
    # ks ∫ max(n·ω,0) (s+1)/(2π) max(ω·r,0)^s dω — at normal incidence (r = n) that integral is
    # (s+1)/(s+2) exactly; truncation at n bands loses little for small s.
    bands = 8
    n = np.array([0.0, 0.0, 1.0])
    h = np.zeros((bands * bands, 3))
    cosine = sh.clamped_cosine_zonal(bands)
    for l in range(bands):
        h[l * (l + 1)] = cosine[l] * np.sqrt(4 * np.pi / (2 * l + 1)) * sh.eval_sh(n[None], bands)[0, l * (l + 1)]
    cases = len(S_VALUES)
    c = _random_cases(bands, cases, seed=2)
    c["H"] = np.broadcast_to(h, (cases, bands * bands, 3)).copy()
    c["n"] = np.broadcast_to(n, (cases, 3)).copy()
    c["wo"] = c["n"].copy()
    c["kd"] = np.full((cases, 3), 0.25)
    c["ks"] = np.full((cases, 3), 0.5)
    got = _run_probe(bands, c, in_vertex=True)["shade"]
    np.testing.assert_allclose(got, _expected_shade(bands, c), rtol=1e-4)
    # Low exponents are band-limited enough that 8 bands nearly reproduce the exact integral.
    exact = 0.25 + 0.5 * (S_VALUES[1] + 1) / (S_VALUES[1] + 2)
    assert abs(got[1, 0] - exact) < 5e-3 * exact
