"""Haar triple products (Ng 2004): the tree algorithm against the per-texel product, analytic
cases, the parent sums, and the cosine-weighted Phong BRDF in Haar."""

from __future__ import annotations

import numpy as np
import pytest

from prtbench.api.errors import InvalidInputError
from prtbench.transport.wavelet import haar
from prtbench.transport.wavelet.triple import (
    SparseRows,
    brute_force,
    decode,
    mean_pyramid,
    parent_means,
    triple_product,
    wavelet_index,
)

N = 8
M = 6 * N * N


def _sparse_haar(rng, points, keep):
    """Haar coefficients of random texel signals, each row truncated to ``keep`` terms."""
    texels = rng.random((points, 6, N, N)) * (rng.random((points, 6, N, N)) < 0.6)
    coeffs = haar.forward(texels).reshape(points, M)
    rows = SparseRows.from_dense(coeffs, keep=keep)
    return rows, rows.dense()


def _light(rng, k):
    coeffs = haar.forward(rng.random((3, 6, N, N)) ** 4).reshape(3, M).T  # peaky, RGB
    out = np.zeros_like(coeffs)
    keep = np.argsort(-np.linalg.norm(coeffs, axis=1))[:k]
    out[keep] = coeffs[keep]
    return out


@pytest.mark.parametrize("k, keep_v, keep_b", [(M, M, M), (50, 40, 30), (6, 100, 10),
                                               (200, 5, M), (1, 1, 1)])
def test_tree_algorithm_equals_the_per_texel_product(k, keep_v, keep_b):
    rng = np.random.default_rng(k + keep_v + keep_b)
    points = 40
    light = _light(rng, k)
    v, v_dense = _sparse_haar(rng, points, keep_v)
    b, b_dense = _sparse_haar(rng, points, keep_b)
    got = triple_product(light, v, b)
    want = brute_force(light, v_dense, b_dense)
    assert np.abs(want).max() > 1e-3  # not a product of zeros
    assert np.allclose(got, want, rtol=0, atol=1e-10), np.abs(got - want).max()


def test_each_case_of_the_tripling_coefficients_is_needed():
    # One wavelet each: L and V on the same finest wavelet, ρ̃ on its grandparent (case 2), and
    # the three types of one node spread over the three signals (case 3).
    light, v, b = np.zeros((M, 1)), np.zeros((1, M)), np.zeros((1, M))
    fine = wavelet_index(2, 2, 3, 1, 2, N)  # face 2, level 2 (2×2-texel support), HH
    coarse = wavelet_index(2, 0, 0, 0, 1, N)  # its level-0 ancestor's HL
    light[fine], v[0, fine], b[0, coarse] = 2.0, 3.0, 5.0
    want = brute_force(light, v, b)[0, 0]
    assert want != 0
    got = triple_product(light, SparseRows.from_dense(v), SparseRows.from_dense(b))[0, 0]
    assert got == pytest.approx(want, abs=1e-12)
    # ρ̄(fine) is HL's value on the quadrant holding the node: (y, x) = (3, 1) at level 2 is
    # (1, 0) at level 1, the lower half (dy = 1) of the level-0 node → sign −1, over side N.
    assert got == pytest.approx(2.0 * 3.0 * 5.0 * -1.0 / N)
    light, v, b = np.zeros((M, 1)), np.zeros((1, M)), np.zeros((1, M))
    node = (4, 1, 1, 0)  # face 4, level 1, node (1, 0): 4×4-texel support
    light[wavelet_index(*node, 0, N)], v[0, wavelet_index(*node, 1, N)] = 1.5, 2.0
    b[0, wavelet_index(*node, 2, N)] = -0.5
    got = triple_product(light, SparseRows.from_dense(v), SparseRows.from_dense(b))[0, 0]
    assert got == pytest.approx(1.5 * 2.0 * -0.5 / 4)  # C = 1/S, S = 4
    assert got == pytest.approx(brute_force(light, v, b)[0, 0], abs=1e-12)


def test_constant_signals():
    # L = α, V = β, ρ̃ = γ on every texel: only the 6 scaling coefficients (α·N each) exist, and
    # the product is 6N²·αβγ.
    alpha, beta, gamma = 0.7, 0.4, 1.3
    light = haar.forward(np.full((1, 6, N, N), alpha)).reshape(1, M).T
    v = SparseRows.from_dense(haar.forward(np.full((2, 6, N, N), beta)).reshape(2, M))
    b = SparseRows.from_dense(haar.forward(np.full((2, 6, N, N), gamma)).reshape(2, M))
    assert v.nnz == 12 and np.allclose(v.values, beta * N)
    assert np.allclose(triple_product(light, v, b), 6 * N * N * alpha * beta * gamma, atol=1e-12)


def test_one_factor_the_scaling_function_gives_the_double_product():
    # ρ̃ = γ on face 3 only (its scaling coefficient alone): Σ L V ρ̃ = γ Σ_face3 L V, which by
    # Parseval is γ times the dot product of face 3's coefficients.
    rng = np.random.default_rng(3)
    light = _light(rng, M)
    v, v_dense = _sparse_haar(rng, 5, M)
    gamma = 0.8
    b_dense = np.zeros((5, M))
    b_dense[:, 3 * N * N] = gamma * N  # the scaling function is 1/N per texel
    got = triple_product(light, v, SparseRows.from_dense(b_dense))
    face = slice(3 * N * N, 4 * N * N)
    assert np.allclose(got, gamma * v_dense[:, face] @ light[face], atol=1e-12)


def test_mean_pyramid_ends_in_the_texels_and_parent_means_match_it():
    rng = np.random.default_rng(7)
    texels = rng.random((6, N, N))
    coeffs = haar.forward(texels)
    means = mean_pyramid(coeffs)
    assert np.allclose(means[:, 0, 0], texels.mean(axis=(1, 2)), atol=1e-14)
    # The finest wavelets' slots hold the mean of their 2×2 blocks.
    blocks = texels.reshape(6, N // 2, 2, N // 2, 2).mean(axis=(2, 4))
    assert np.allclose(means[:, N // 2:, N // 2:], blocks, atol=1e-14)
    assert np.allclose(means[:, :N // 2, N // 2:], blocks, atol=1e-14)
    wavelets = np.setdiff1d(np.arange(M), np.arange(6) * N * N)
    rows = SparseRows.from_dense(coeffs.reshape(1, M))
    got = parent_means(rows, np.zeros(len(wavelets), np.int64), wavelets)
    assert np.allclose(got, means.reshape(M)[wavelets], atol=1e-13)
    with pytest.raises(InvalidInputError, match="wavelet coefficients"):
        parent_means(rows, np.zeros(1, np.int64), np.zeros(1, np.int64))


def test_decode_inverts_wavelet_index():
    face, level, y, x, kind = decode(np.arange(M), N)
    wav = kind >= 0
    assert wav.sum() == M - 6 and set(level[wav]) == {0, 1, 2}
    assert np.array_equal(wavelet_index(face[wav], level[wav], y[wav], x[wav], kind[wav], N),
                          np.arange(M)[wav])


def test_bad_shapes_are_one_line_errors():
    v = SparseRows.from_dense(np.ones((2, M)))
    with pytest.raises(InvalidInputError, match="accepted: \\(M, C\\)"):
        triple_product(np.ones((M - 1, 3)), v, v)
    with pytest.raises(InvalidInputError, match="6·N²"):
        triple_product(np.ones((10, 1)), SparseRows.from_dense(np.ones((2, 10))),
                       SparseRows.from_dense(np.ones((2, 10))))


# --- the cosine-weighted Phong BRDF in Haar (prtbench.transport.wavelet.brdf) ---------------------------

def _unit(rng, count):
    v = rng.normal(size=(count, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def test_brdf_factors_integrate_to_their_closed_forms():
    from prtbench.transport.wavelet import brdf

    rng = np.random.default_rng(11)
    normals = _unit(rng, 6)
    # ∫ max(n·ω, 0)/π dω = 1; with r = n, ∫ (s+1)/(2π) (r·ω)^s (n·ω) dω = (s+1)/(s+2).
    d = brdf.factor_texels(normals, n=16, samples=4)
    assert np.allclose(d.sum(axis=1), 1.0, atol=2e-3), d.sum(axis=1)
    for s in (0.0, 8.0, 64.0):
        g = brdf.factor_texels(normals, n=32, reflections=normals, shininess=s, samples=2)
        assert np.allclose(g.sum(axis=1), (s + 1) / (s + 2), rtol=5e-3), (s, g.sum(axis=1))
    assert np.all(d >= 0) and np.all(g >= 0)
    # A mirror direction at 60° from the normal loses the lobe's part below the horizon.
    view = np.array([[np.sin(np.radians(60)), 0.0, np.cos(np.radians(60))]])
    r = brdf.reflect(view, np.array([[0.0, 0.0, 1.0]]))
    assert np.allclose(r, [[-view[0, 0], 0.0, view[0, 2]]])
    tilted = brdf.factor_texels(np.array([[0.0, 0.0, 1.0]]), n=32, reflections=r, shininess=8.0,
                                samples=2).sum()
    assert 0.4 < tilted < (9 / 10) * 0.6  # ≈ cos 60° · (s+1)/(s+2), less the clipped part
    # The lobe is zero behind its mirror plane at every s: with r = -n it never meets the upper
    # hemisphere, so the factor is 0, s = 0 included (0^0 = 1 made it 1/2 there).
    for s in (0.0, 1.0):
        away = brdf.factor_texels(normals, n=16, reflections=-normals, shininess=s, samples=2)
        assert np.abs(away).max() == 0.0, (s, away.sum(axis=1))
    with pytest.raises(InvalidInputError, match="shininess"):
        brdf.factor_texels(normals, n=8, reflections=normals, shininess=-1.0)


def test_brdf_projection_keeps_the_largest_coefficients():
    from prtbench.transport.wavelet import brdf

    rng = np.random.default_rng(5)
    normals, views = _unit(rng, 20), _unit(rng, 20)
    r = brdf.reflect(views, normals)
    texels = brdf.factor_texels(normals, n=N, reflections=r, shininess=32.0)
    full = haar.forward(texels.reshape(-1, 6, N, N)).reshape(-1, M)
    p, c, v = brdf.project(normals, n=N, keep=M, reflections=r, shininess=32.0)
    rows = SparseRows.from_entries(p, c, v, n_points=20, n_coeffs=M).dense()
    assert np.allclose(rows, full, atol=1e-6)
    p, c, v = brdf.project(normals, n=N, keep=10, reflections=r, shininess=32.0)
    kept = SparseRows.from_entries(p, c, v, n_points=20, n_coeffs=M).dense()
    tenth = -np.sort(-np.abs(full), axis=1)[:, 9]
    assert np.all((kept != 0).sum(axis=1) <= 10)
    assert np.all(np.abs(full)[kept == 0].reshape(-1) <= np.repeat(tenth, M - 10) + 1e-6)
    with pytest.raises(InvalidInputError, match="brdf_keep=0"):
        brdf.project(normals, n=N, keep=0)


def test_visibility_only_transport_is_the_visible_fraction():
    from prtbench.scene.registry import get_scene
    from prtbench.transport.wavelet.cubemap import texel_solid_angles
    from prtbench.transport.wavelet.transport import compute_wavelet_transport

    scene = get_scene("plane")  # nothing occludes its up-facing points
    points, normals = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.5]]), np.array([[0.0, 1.0, 0.0]] * 2)
    transport, _ = compute_wavelet_transport(scene, points, normals, n=N, texel_samples=4,
                                             cosine=False, progress=False)
    texel_v = haar.inverse(transport.dense().reshape(2, 6, N, N)).reshape(2, M)
    assert texel_v.min() > -1e-6 and texel_v.max() < 1 + 1e-6
    # Visible fraction × solid angle sums to the upper hemisphere's 2π (the +Y face and half of
    # the four side faces), to the 4×4 subsample rule at the horizon.
    assert np.allclose(texel_v @ texel_solid_angles(N).reshape(M), 2 * np.pi, rtol=1e-3)
    assert np.allclose(texel_v.reshape(2, 6, N, N)[:, 2], 1.0, atol=1e-6)  # +Y face
    assert np.allclose(texel_v.reshape(2, 6, N, N)[:, 3], 0.0, atol=1e-6)  # −Y face


def test_brdf_table_looks_up_the_entry_of_the_bins_centres():
    from prtbench.transport.wavelet import brdf
    from prtbench.transport.wavelet.cubemap import texel_directions

    t = 4
    centres = texel_directions(t).reshape(-1, 3)
    rng = np.random.default_rng(2)
    pick_n, pick_r = rng.choice(len(centres), 12), rng.choice(len(centres), 12)
    # Vertex normals and mirror directions a little off their bins' centres.
    normals = centres[pick_n] + 0.01 * rng.normal(size=(12, 3))
    reflections = centres[pick_r] + 0.01 * rng.normal(size=(12, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    reflections /= np.linalg.norm(reflections, axis=1, keepdims=True)
    table, slots = brdf.BrdfTable.build(normals, t=t, n=N, keep=20, shininess=16.0)
    assert len(table.indptr) - 1 == len(np.unique(pick_n)) * 6 * t * t  # present normal bins
    got = SparseRows.from_entries(*table.gather(slots, reflections), n_points=12,
                                  n_coeffs=M).dense()
    want = SparseRows.from_entries(*brdf.project(centres[pick_n], n=N, keep=20,
                                                 reflections=centres[pick_r], shininess=16.0),
                                   n_points=12, n_coeffs=M).dense()
    assert np.abs(want).max() > 0
    assert np.allclose(got, want, atol=1e-7)
    assert np.all(np.diff(SparseRows.from_entries(*table.gather(slots, reflections),
                                                  n_points=12, n_coeffs=M).keys) > 0)
