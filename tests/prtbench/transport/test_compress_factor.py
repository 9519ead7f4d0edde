"""In-out factorization of the Phong BRDF (prtbench/compress/factor.py): rank, truncation error,
the diffuse special case, the lecture's critique (error against the Phong exponent), lookups."""

from __future__ import annotations

import numpy as np
import pytest

from prtbench.api.errors import InvalidInputError
from prtbench.transport.compress import factor
from prtbench.transport.compress.factor import HemisphereGrid, factor_brdf, phong_cosine_matrix

KD, KS = (0.35, 0.25, 0.15), (0.45, 0.45, 0.45)
SMALL = dict(out_grid=HemisphereGrid(3, 12), in_grid=HemisphereGrid(6, 24))
MEDIUM = dict(out_grid=HemisphereGrid(8, 32), in_grid=HemisphereGrid(16, 64))


def test_grid_solid_angles_cover_the_hemisphere_and_centres_are_texel_centres():
    grid = HemisphereGrid(5, 20)
    assert grid.solid_angles().sum() == pytest.approx(2 * np.pi, rel=1e-12)
    d = grid.directions()
    assert np.allclose(np.linalg.norm(d, axis=1), 1.0) and d[:, 2].min() > 0
    row, col = factor.local_angles_to_texture(d, grid)
    assert np.allclose(row, np.repeat(np.arange(5), 20), atol=1e-9)
    assert np.allclose(col, np.tile(np.arange(20), 5), atol=1e-9)


def test_sampled_matrix_is_the_design_brdf_times_the_cosine():
    from prtbench.render.mitsuba_bsdf import brdf

    grid_o, grid_i = HemisphereGrid(2, 8), HemisphereGrid(3, 12)
    rho = phong_cosine_matrix(KD, KS, 20.0, out_grid=grid_o, in_grid=grid_i)
    wo, wi = grid_o.directions(), grid_i.directions()
    want = brdf(np.array(KD), np.array(KS), 20.0, np.array([0.0, 0.0, 1.0]), wi[None, :, :],
                wo[:, None, :]) * wi[None, :, 2:3]  # (o, i, 3)
    assert np.allclose(rho, np.transpose(want, (0, 2, 1)), rtol=1e-12, atol=1e-14)
    # At s = 0 the lobe is the hemisphere about the mirror direction, as the reference's, not a
    # constant (0^0 = 1): the sampled BRDF then varies with the outgoing direction (rank > 1).
    flat = phong_cosine_matrix((0.0,) * 3, KS, 0.0, **SMALL)[:, 0, :]
    mirror = SMALL["out_grid"].directions() * np.array([-1.0, -1.0, 1.0])
    behind = mirror @ SMALL["in_grid"].directions().T <= 0
    assert behind.any() and np.all(flat[behind] == 0.0) and np.all(flat[~behind] > 0.0)
    assert np.linalg.matrix_rank(flat) > 1


def test_error_falls_with_terms_and_full_rank_reproduces_the_samples():
    probe = factor_brdf(KD, KS, 20.0, terms=1, **SMALL)
    errors = [probe.relative_error(j) for j in range(1, 9)]
    assert all(a > b for a, b in zip(errors, errors[1:])), errors
    assert errors[0] > 0.3  # one term is a poor glossy BRDF: the comparison above can fail
    full = factor_brdf(KD, KS, 20.0, terms=probe.rank, **SMALL)
    rho = phong_cosine_matrix(KD, KS, 20.0, **SMALL)
    assert full.relative_error() == 0.0
    assert np.max(np.abs(full.reconstruct() - rho)) < 1e-12 * rho.max()
    # Truncated reconstructions carry exactly the error the singular values predict.
    for j in (1, 4):
        part = factor_brdf(KD, KS, 20.0, terms=j, **SMALL)
        w = np.sqrt(SMALL["out_grid"].solid_angles())[:, None, None] * np.sqrt(
            SMALL["in_grid"].solid_angles())[None, None, :]
        got = np.linalg.norm((part.reconstruct() - rho) * w) / np.linalg.norm(rho * w)
        assert got == pytest.approx(part.relative_error(), rel=1e-9)


def test_a_diffuse_material_is_exactly_one_term():
    f = factor_brdf(KD, (0.0, 0.0, 0.0), 50.0, terms=1, **MEDIUM)
    assert f.rank == 1 and f.relative_error() == 0.0
    rho = phong_cosine_matrix(KD, (0.0, 0.0, 0.0), 50.0, **MEDIUM)
    assert np.max(np.abs(f.reconstruct() - rho)) < 1e-12 * rho.max()
    # g ∝ kd everywhere, h̃ constant: the diffuse transfer vector times kd/π.
    assert np.allclose(f.incoming, f.incoming.flat[0], rtol=1e-10)
    g = f.outgoing[0] * f.incoming.flat[0]
    assert np.allclose(g, np.asarray(KD)[:, None, None] / np.pi, rtol=1e-10)
    with pytest.raises(InvalidInputError, match=r"terms=2 .* has rank 1; accepted: terms 1 to 1"):
        factor_brdf(KD, (0.0, 0.0, 0.0), 50.0, terms=2, **MEDIUM)
    # A scene mixing materials keeps min(J, rank) terms of each.
    capped = factor_brdf(KD, (0.0, 0.0, 0.0), 50.0, terms=5, at_most=True, **MEDIUM)
    assert capped.terms == 1 and np.allclose(capped.outgoing, f.outgoing)


def test_error_at_fixed_terms_grows_with_the_phong_exponent():
    # The lecture's critique of factored BRDFs: "only less glossy materials". At J = 4 on
    # factored-brdf's default grids (12 × 48 out, 24 × 96 in; kd 0.3, ks 0.5) the error is
    # 0.06, 0.45, 0.80, 0.94 for s = 1, 10, 50, 200; this coarser grid shows the same trend.
    errors = [factor_brdf(KD, KS, s, terms=4, **MEDIUM).relative_error() for s in (1, 10, 50, 200)]
    assert all(a < b for a, b in zip(errors, errors[1:])), errors
    assert errors[0] < 0.15 and errors[-1] > 0.8, errors


def test_gram_path_agrees_with_the_dense_svd(monkeypatch):
    dense = factor_brdf(KD, KS, 10.0, terms=3, **SMALL)
    monkeypatch.setattr(factor, "_DENSE_SVD_VALUES", 0)
    gram = factor_brdf(KD, KS, 10.0, terms=3, **SMALL)
    assert gram.rank == dense.rank
    assert np.allclose(gram.singular_values[:3], dense.singular_values[:3], rtol=1e-9)
    assert np.allclose(gram.reconstruct(), dense.reconstruct(), atol=1e-9)


def test_bilinear_lookup_reads_texel_centres_wraps_phi_and_clamps_theta():
    grid = HemisphereGrid(4, 8)
    rng = np.random.default_rng(1)
    table = rng.random((2, 4, 8))
    got = factor.bilinear_lookup(table, grid.directions(), grid)
    assert np.allclose(got, table.reshape(2, -1).T, atol=1e-12)
    # φ = 0 lies halfway between the last and the first column; below the horizon: last row.
    theta = (1 + 0.5) * (np.pi / 2) / 4
    d = np.array([[np.sin(theta), 0.0, np.cos(theta)], [1.0, 0.0, -0.5]])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    got = factor.bilinear_lookup(table, d, grid)
    assert np.allclose(got[0], 0.5 * (table[:, 1, 0] + table[:, 1, 7]))
    assert np.allclose(got[1], 0.5 * (table[:, 3, 0] + table[:, 3, 7]))


def test_factors_do_not_depend_on_the_blas_thread_count():
    # The Phong lobe's equal singular-value pairs leave the singular vectors free to rotate
    # within a pair; multi-threaded OpenBLAS picks another rotation than one thread (U and V
    # differ by ~0.1 on this grid), so a 2-worker sweep (one BLAS thread each) and a serial
    # run would store different factors. factor_brdf runs the SVD on one thread.
    from prtbench.transport.parallel import _openblas_threads

    threads = _openblas_threads()
    if threads is None:
        pytest.skip("numpy is not linked against its bundled OpenBLAS")
    get, put = threads
    before = get()
    tables = []
    try:
        for count in (1, 2):
            put(count)
            f = factor_brdf(KD, KS, 20.0, terms=8, **MEDIUM)
            tables.append((f.outgoing, f.incoming))
            assert get() == count  # restored afterwards
    finally:
        put(before)
    np.testing.assert_array_equal(tables[0][0], tables[1][0])
    np.testing.assert_array_equal(tables[0][1], tables[1][1])
