"""CPCA (prtbench.transport.compress.cpca): its special cases, monotone error, rendering linearity, bad input."""

from __future__ import annotations

import numpy as np
import pytest
from sklearn.cluster import KMeans
from sklearn.decomposition import PCA

from prtbench.api.errors import InvalidInputError
from prtbench.transport.compress import check_request, fit_cpca, stored_bytes


def _signals(n=600, d=12, clusters=6, rank=3, noise=0.05, seed=1):
    """Signals near ``clusters`` affine ``rank``-subspaces (what transfer looks like locally)."""
    rng = np.random.default_rng(seed)
    centres = rng.normal(scale=3.0, size=(clusters, d))
    frames = rng.normal(size=(clusters, rank, d))
    ids = rng.integers(0, clusters, n)
    coords = rng.normal(size=(n, rank))
    x = centres[ids] + np.einsum("nr,nrd->nd", coords, frames[ids])
    return x + noise * rng.normal(size=(n, d))


def test_one_cluster_is_global_pca():
    x = _signals()
    for n in (1, 3, 7):
        model = fit_cpca(x, clusters=1, pca_vectors=n)
        pca = PCA(n_components=n, svd_solver="full").fit(x)
        want = pca.inverse_transform(pca.transform(x))
        assert np.max(np.abs(model.reconstruct() - want)) < 1e-10
        # The basis spans the same subspace: projectors agree.
        assert np.max(np.abs(model.bases[0].T @ model.bases[0]
                             - pca.components_.T @ pca.components_)) < 1e-10
        assert np.isclose(model.history[-1], np.sum((x - want) ** 2), rtol=1e-10)


def test_no_pca_vectors_is_kmeans_vector_quantisation():
    x = _signals(clusters=5)
    model = fit_cpca(x, clusters=5, pca_vectors=0, seed=3, tolerance=0.0)
    km = KMeans(n_clusters=5, n_init=1, random_state=3, tol=0.0, max_iter=300).fit(x)
    assert np.array_equal(model.cluster, km.labels_)
    assert np.max(np.abs(model.means - km.cluster_centers_)) < 1e-10
    assert np.max(np.abs(model.reconstruct() - km.cluster_centers_[km.labels_])) < 1e-10
    assert np.isclose(model.history[-1], km.inertia_, rtol=1e-9)


def test_no_pca_vectors_iterates_lloyd_from_any_start():
    """From an arbitrary labelling, n′ = 0 CPCA is Lloyd's algorithm: same fixed point as
    scikit-learn's k-means started from the same centres."""
    x = np.random.default_rng(5).uniform(size=(400, 4))
    start = np.random.default_rng(6).integers(0, 5, len(x)).astype(np.int32)
    model = fit_cpca(x, clusters=5, pca_vectors=0, init_labels=start, tolerance=0.0,
                     max_iterations=300)
    centres = np.stack([x[start == k].mean(axis=0) for k in range(5)])
    km = KMeans(n_clusters=5, init=centres, n_init=1, tol=0.0, max_iter=300,
                algorithm="lloyd").fit(x)
    assert np.array_equal(model.cluster, km.labels_)
    assert np.max(np.abs(model.means - km.cluster_centers_)) < 1e-10


def test_full_dimension_is_lossless():
    x = _signals(d=10)
    model = fit_cpca(x, clusters=8, pca_vectors=10)
    assert np.max(np.abs(model.reconstruct() - x)) < 1e-10
    # Including a cluster with fewer members than dimensions (basis completed).
    small = fit_cpca(x[:12], clusters=4, pca_vectors=10)
    assert np.max(np.abs(small.reconstruct() - x[:12])) < 1e-10


@pytest.mark.parametrize("adaptive", [False, True])
def test_error_never_rises_and_iterations_help(adaptive):
    x = _signals(n=1500, d=16, clusters=10, rank=2, noise=0.2, seed=7)
    model = fit_cpca(x, clusters=6, pca_vectors=2, adaptive=adaptive, tolerance=0.0,
                     max_iterations=50, seed=2)
    history = np.asarray(model.history)
    assert len(history) >= 2  # it iterated
    assert np.all(np.diff(history) <= 1e-9 * history[0])
    assert history[-1] < 0.99 * history[0]  # reassign-by-reconstruction beats k-means labels
    assert np.isclose(np.sum((model.reconstruct() - x) ** 2), history[-1], rtol=1e-9)
    # The chunked error (what a compressed artifact records) is the same sum.
    error, energy = model.squared_error(x, chunk=7)
    assert np.isclose(error, history[-1], rtol=1e-9) and np.isclose(energy, np.sum(x**2))
    assert np.allclose(model.reconstruct(slice(5, 40)), model.reconstruct()[5:40], rtol=0,
                       atol=1e-12)


def test_adaptive_allocation_keeps_the_budget_and_lowers_the_error():
    x = _signals(n=1200, d=16, clusters=4, rank=1, noise=0.02, seed=11)
    # Two rich clusters (rank 5) beside the four rank-1 ones.
    rng = np.random.default_rng(12)
    rich = rng.normal(size=(400, 5)) @ rng.normal(size=(5, 16)) + 20.0
    x = np.concatenate([x, rich, rich[::-1] * -1.0])
    uniform = fit_cpca(x, clusters=6, pca_vectors=2, seed=4, tolerance=0.0)
    adaptive = fit_cpca(x, clusters=6, pca_vectors=2, adaptive=True, seed=4, tolerance=0.0)
    assert int(adaptive.counts.sum()) == 12
    assert adaptive.counts.max() > 2 and adaptive.counts.min() < 2
    assert adaptive.history[-1] < 0.5 * uniform.history[-1]
    assert adaptive.nbytes > uniform.nbytes  # padded to the largest count: stated, counted


def test_rendering_from_the_compressed_form_equals_the_reconstructed_transfer():
    x = _signals(d=9)
    model = fit_cpca(x, clusters=7, pca_vectors=3)
    light = np.random.default_rng(3).normal(size=(9, 3))
    want = model.reconstruct() @ light
    got = model.apply(model.project(light))
    assert np.max(np.abs(got - want)) < 1e-10 * np.max(np.abs(want))
    # A structured (callable) operator gives the same table as its matrix.
    assert np.allclose(model.project(lambda rows: rows @ light), model.project(light), atol=0)
    # And VQ / PCA special cases render the same way.
    for k, n in ((7, 0), (1, 4)):
        m = fit_cpca(x, clusters=k, pca_vectors=n)
        assert np.allclose(m.apply(m.project(light)), m.reconstruct() @ light, rtol=0,
                           atol=1e-10)


def test_bytes_come_from_the_stored_arrays():
    x = _signals(n=300, d=12)
    model = fit_cpca(x, clusters=4, pca_vectors=3).astype(np.float32)
    assert model.nbytes == (4 * 12 + 4 * 3 * 12 + 300 * 3) * 4 + 300 * 4
    assert model.nbytes == stored_bytes(n_signals=300, dimension=12, clusters=4, pca_vectors=3)
    vq = fit_cpca(x, clusters=4, pca_vectors=0).astype(np.float32)
    assert set(vq.stored_arrays()) == {"means", "cluster"} and vq.nbytes == 4 * 12 * 4 + 300 * 4
    pca = fit_cpca(x, clusters=1, pca_vectors=2).astype(np.float32)
    assert set(pca.stored_arrays()) == {"means", "bases", "weights"}


def test_large_clusters_use_the_streamed_scatter(monkeypatch):
    """Clusters past the direct-SVD size are fitted from their chunked scatter matrix, with the
    same subspace as the SVD path."""
    from prtbench.transport.compress import fit as cpca

    x = _signals(n=800, d=12)
    direct = fit_cpca(x, clusters=3, pca_vectors=4, seed=1)
    monkeypatch.setattr(cpca, "_SVD_VALUES", 100)  # forces chunks of 8 rows too
    streamed = fit_cpca(x, clusters=3, pca_vectors=4, seed=1)
    assert np.array_equal(direct.cluster, streamed.cluster)
    assert np.max(np.abs(direct.reconstruct() - streamed.reconstruct())) < 1e-8


def test_kmeans_initialisation_subsamples_large_inputs():
    x = _signals(n=3000, d=8, clusters=4, rank=1, noise=0.01)
    model = fit_cpca(x, clusters=4, pca_vectors=1, init_samples=500, seed=0)
    full = fit_cpca(x, clusters=4, pca_vectors=1, seed=0)
    assert model.n_signals == 3000 and len(np.unique(model.cluster)) == 4
    # The clusters are found from the subsample: the error is the noise floor, as from all.
    assert np.sqrt(model.history[-1] / x.size) < 0.02
    assert model.history[-1] <= 1.05 * full.history[-1]


@pytest.mark.parametrize("kwargs, match", [
    ({"clusters": 301, "pca_vectors": 1}, r"clusters=301 for 300 vertices; accepted: 1 to 300"),
    ({"clusters": 0, "pca_vectors": 1}, r"clusters=0 for 300 vertices; accepted: 1 to 300"),
    ({"clusters": 4, "pca_vectors": 13}, r"pca_vectors=13 for signals of dimension 12; "
                                         r"accepted: 0 to 12"),
    ({"clusters": 4, "pca_vectors": 3, "max_bytes": 1000},
     r"would store 5568 bytes, over the limit of 1000 bytes"),
])
def test_bad_requests_are_one_line_errors(kwargs, match):
    x = _signals(n=300, d=12)
    with pytest.raises(InvalidInputError, match=match) as info:
        fit_cpca(x, what="vertices", **kwargs)
    assert "\n" not in str(info.value)
    with pytest.raises(InvalidInputError, match=match):
        check_request(n_signals=300, dimension=12, what="vertices", **kwargs)


def test_non_finite_signals_are_refused():
    x = _signals(n=50, d=4)
    x[3, 1] = np.nan
    with pytest.raises(InvalidInputError, match="non-finite"):
        fit_cpca(x, clusters=2, pca_vectors=1)
