"""Wavelet transport of points (rays on a cubemap, Haar, truncation) and its sparse storage."""

from __future__ import annotations

import math

import numpy as np
import pytest

from prtbench.api.errors import InvalidInputError
from prtbench.scene.registry import get_scene
from prtbench.transport.wavelet import cubemap, haar, sparse
from prtbench.transport.wavelet.sparse import SparseTransport
from prtbench.transport.wavelet.transport import (
    compute_wavelet_transport,
    keep_count,
    row_counts,
    truncate,
)


def _texel_transport(transport: SparseTransport, n: int) -> np.ndarray:
    """(P, 6, N, N) texel-domain transport (inverse Haar of the dense rows)."""
    return haar.inverse(transport.dense().reshape(-1, 6, n, n))


def test_unoccluded_transport_is_solid_angle_times_cosine():
    scene = get_scene("plane")
    n = 16
    normal = np.array([0.6, 0.8, 0.0])
    transport, stats = compute_wavelet_transport(scene, np.zeros((1, 3)), normal[None], n=n,
                                                 texel_samples=4, visibility=False,
                                                 progress=False)
    assert stats["rays"] == 0
    t = _texel_transport(transport, n)[0]
    assert abs(t.sum() - math.pi) < 2e-3 * math.pi  # ∫ max(n·ω, 0) dω = π
    cos = cubemap.texel_directions(n) @ normal
    # Independent check of a few texels cut by nothing: adaptive quadrature of the cosine over
    # the texel's face rectangle with the area element da db / (1 + a² + b²)^{3/2}.
    from scipy.integrate import dblquad

    frames = cubemap.FACE_FRAMES
    for f, i, j in [(0, 8, 8), (0, 2, 13), (2, 5, 11), (2, 15, 0), (4, 7, 15), (1, 3, 3)]:
        if cos[f, i, j] <= 4.0 / n:
            continue
        def integrand(b, a, f=f):
            d = a * frames[f, 0] + b * frames[f, 1] + frames[f, 2]
            return max(float(d @ normal), 0.0) / float(d @ d) ** 2  # cos/r · 1/r³
        a0, b0 = 2.0 * j / n - 1.0, 2.0 * i / n - 1.0
        exact, _ = dblquad(integrand, a0, a0 + 2.0 / n, b0, b0 + 2.0 / n, epsabs=1e-12)
        assert abs(t[f, i, j] / exact - 1.0) < 2e-3, (f, i, j, t[f, i, j], exact)
    assert np.all(np.abs(t[cos < -4.0 / n]) < 1e-7 * t.max())  # float32 storage rounding
    # The lower hemisphere is exact zeros and is not stored.
    assert transport.nnz < 0.75 * 6 * n * n


def test_occluded_fraction_below_the_sphere_is_analytic():
    # Cosine-weighted unoccluded fraction directly below a sphere of radius r at height h:
    # 1 − (r/h)² (DESIGN.md §13).
    scene = get_scene("sphere-over-plane", radius=0.5, height=1.0)
    n = 32
    transport, stats = compute_wavelet_transport(scene, np.zeros((1, 3)), np.array([[0, 1.0, 0]]),
                                                 n=n, texel_samples=2, progress=False)
    assert stats["rays"] > 0.45 * stats["candidate_rays"]
    fraction = _texel_transport(transport, n)[0].sum() / math.pi
    assert abs(fraction - 0.75) < 0.01, fraction


def test_truncation_keeps_the_largest_coefficients_and_quantisation_error_is_bounded():
    scene = get_scene("sphere-over-plane", plane_subdivisions=2)
    positions, normals, _, _ = scene.merged()
    pts, nrm = positions[::97], normals[::97]
    n = 8
    full, _ = compute_wavelet_transport(scene, pts, nrm, n=n, keep=1.0, progress=False)
    dense = full.dense()
    k = 40
    kept, _ = compute_wavelet_transport(scene, pts, nrm, n=n, keep=k, progress=False)
    d = kept.dense()
    assert np.all((d != 0).sum(axis=1) <= k)
    for row_full, row in zip(dense, d):
        threshold = np.sort(np.abs(row_full))[-k]
        assert np.all(np.abs(row_full[row != 0]) >= threshold)
        assert np.array_equal(row[row != 0], row_full[row != 0])
    half, _ = compute_wavelet_transport(scene, pts, nrm, n=n, storage="float16", progress=False)
    assert np.all(np.abs(half.dense() - dense) <= np.abs(dense) * 2.0**-11 + 1e-7)
    assert half.values.nbytes * 2 == full.values.nbytes
    q, _ = compute_wavelet_transport(scene, pts, nrm, n=n, storage="int8", progress=False)
    step = np.abs(dense).max(axis=1, keepdims=True) / 127.0
    assert np.all(np.abs(q.dense() - dense) <= 0.5 * step * (1 + 1e-5))
    assert q.nbytes == (q.indptr.nbytes + q.rows.nbytes + q.nnz + 4 * len(pts))


def test_relight_is_the_sparse_product_of_the_selected_columns():
    rng = np.random.default_rng(0)
    p, m = 50, 96
    dense = rng.normal(size=(p, m)) * (rng.random((p, m)) < 0.3)
    rows, cols = np.nonzero(dense)
    sparse = SparseTransport.from_entries(rows, cols, dense[rows, cols], n_points=p, n_coeffs=m,
                                          storage="float32")
    assert sparse.rows.dtype == np.uint16 and sparse.nnz == len(rows)
    assert sparse.nbytes == (m + 1) * 8 + sparse.nnz * (2 + 4)
    light = rng.normal(size=(m, 3))
    terms = np.array([0, 5, 17, 40, 95])
    expected = dense[:, terms] @ light[terms]
    assert np.allclose(sparse.relight(light, terms), expected, rtol=1e-5, atol=1e-5)
    assert np.allclose(sparse.relight(light, np.arange(m)), dense @ light, rtol=1e-5, atol=1e-5)
    assert np.allclose(sparse.column_mean_abs(), np.abs(dense).mean(axis=0), rtol=1e-6)


def test_keep_fraction_or_count():
    assert keep_count(1.0, 6144) == 6144 and keep_count(0.25, 6144) == 1536
    assert keep_count(64, 6144) == 64 and keep_count(1e-9, 6144) == 1
    for bad in (0, -1, 6145, 2.5):
        with pytest.raises(InvalidInputError, match="keep="):
            keep_count(bad, 6144)


def _old_truncation(c: np.ndarray, k: int) -> np.ndarray:
    """The kept-entry mask of the original formula: partition every row, drop zeros."""
    keep = np.zeros(c.shape, dtype=bool)
    if k < c.shape[1]:
        idx = np.argpartition(-np.abs(c), k - 1, axis=1)[:, :k]
        np.put_along_axis(keep, idx, True, axis=1)
    else:
        keep[:] = True
    return keep & (c != 0)


def test_truncate_keeps_what_partitioning_every_row_kept_even_with_ties():
    rng = np.random.default_rng(3)
    m, k = 96, 20
    c = rng.normal(size=(60, m)).astype(np.float32)
    c[rng.random(c.shape) < 0.5] = 0                      # about 48 nonzeros: partitioned
    c[:10, 15:] = 0                                      # <= k nonzeros: all of them kept
    c[10:20] = np.round(c[10:20], 1)                     # many equal magnitudes at the cut
    c[20:25] = np.where(c[20:25] != 0, np.float32(0.5), 0)  # all nonzeros equal
    c[25:30] = -np.abs(c[25:30])
    for kk in (1, k, 47, m):
        kept = truncate(c, kk)
        np.testing.assert_array_equal(kept, _old_truncation(c, kk))
        assert np.all(kept.sum(axis=1) == np.minimum(kk, (c != 0).sum(axis=1)))
        # float64 rows (cut on the values, not on integer keys), and every row over k.
        np.testing.assert_array_equal(truncate(c.astype(np.float64), kk), kept)
        np.testing.assert_array_equal(truncate(c[10:], kk), _old_truncation(c[10:], kk))
    assert ((c[10:] != 0).sum(axis=1) > k).all()


def test_truncated_transport_is_the_partition_of_the_full_one():
    # Axis-aligned normals on a plane make symmetric transports full of equal magnitudes.
    scene = get_scene("sphere-over-plane", plane_subdivisions=3)
    positions, normals, _, _ = scene.merged()
    n, k = 8, 70
    full, _ = compute_wavelet_transport(scene, positions, normals, n=n, keep=1.0,
                                        progress=False)
    c = full.dense().astype(np.float32)  # float32 storage holds the coefficients exactly
    kept, _ = compute_wavelet_transport(scene, positions, normals, n=n, keep=k, progress=False)
    expect = np.where(_old_truncation(c, k), c, 0)
    assert (expect != 0).sum() > 0.3 * k * len(c)
    np.testing.assert_array_equal(kept.dense(), expect)


def test_float16_storage_rounds_exactly_like_numpy():
    rng = np.random.default_rng(5)
    bits = rng.integers(0, 2**32, 200_000, dtype=np.uint64).astype(np.uint32)
    k = np.arange(1030, dtype=np.float64)
    edges = np.concatenate([(k + 0.5) * 2.0**-24, k * 2.0**-24, (k + 0.5) * 2.0**-14,
                            [2.0**-14, 2.0**-25, 3 * 2.0**-26, 65504, 65519.9, 65520, 1e-45,
                             np.inf, np.nan]])
    small = (rng.random(200_000) * 2.0**-12).astype(np.float32)
    for x in (bits.view(np.float32), edges.astype(np.float32), -edges.astype(np.float32),
              small, -small, small.reshape(400, 500)):
        with np.errstate(over="ignore"):
            expect = x.astype(np.float16)
            got = sparse.as_float16(x)
        assert got.dtype == np.float16 and got.shape == x.shape
        assert got.tobytes() == expect.tobytes()
    assert sparse.as_float16(np.array([2.0**-20])).tobytes() == np.float16(2.0**-20).tobytes()


@pytest.mark.parametrize("storage", ["float32", "float16", "int8"])
def test_sparse_build_matches_a_sort_by_coefficient_then_point(storage):
    rng = np.random.default_rng(7)
    p, m = 300, 64
    dense = (rng.normal(size=(p, m)) * 1e-3 * (rng.random((p, m)) < 0.2)).astype(np.float32)
    dense[17] = 0  # a point with no entries
    rows, cols = np.nonzero(dense)
    for order in (np.arange(len(rows)), rng.permutation(len(rows))):
        built = SparseTransport.from_entries(rows[order], cols[order], dense[rows, cols][order],
                                             n_points=p, n_coeffs=m, storage=storage)
        by_coeff = np.lexsort((rows, cols))
        values = dense[rows, cols][by_coeff]
        np.testing.assert_array_equal(built.rows, rows[by_coeff].astype(np.uint16))
        np.testing.assert_array_equal(built.indptr,
                                      np.concatenate([[0], np.cumsum(np.bincount(cols,
                                                                                 minlength=m))]))
        if storage == "int8":
            peak = np.abs(dense).max(axis=1).astype(np.float64)
            scale = (np.where(peak > 0, peak, 1.0) / 127.0).astype(np.float32)
            np.testing.assert_array_equal(built.scale, scale)
            q = np.clip(np.rint(values / scale[rows[by_coeff]]), -127, 127).astype(np.int8)
            np.testing.assert_array_equal(built.values, q)
        else:
            assert built.values.tobytes() == values.astype(storage).tobytes()
        # Point by point (the transport's own chunks), any order within a point: the same build.
        shuffled = np.lexsort((rng.random(len(rows)), rows))
        from_rows = SparseTransport.from_rows(np.bincount(rows, minlength=p), cols[shuffled],
                                              dense[rows, cols][shuffled], n_coeffs=m,
                                              storage=storage)
        for a, b in zip(from_rows.arrays().values(), built.arrays().values()):
            assert a.dtype == b.dtype and a.tobytes() == b.tobytes()


@pytest.mark.parametrize("shape", [(7, 6 * 4 * 4), (3, 6 * 32 * 32), (5, 13), (0, 24)])
def test_row_counts_equal_count_nonzero_on_rows_of_any_length(shape):
    """The word-sum count is exact, full rows and empty rows included (13: the fallback)."""
    rng = np.random.default_rng(3)
    mask = rng.random(shape) < 0.4
    if shape[0]:
        mask[0] = True  # a full row: every byte of every word is 1
        mask[-1] = False
    expected = np.count_nonzero(mask, axis=1)
    assert np.array_equal(row_counts(mask), expected)
    assert np.array_equal(row_counts(mask[:, ::-1]), expected)  # not C-contiguous: fallback
