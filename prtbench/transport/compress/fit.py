"""CPCA fitting (Sloan et al. 2003): k-means initialisation, then iterative reassignment and refit.

Fitting (:func:`fit_cpca`): k-means initialisation (scikit-learn) on a random subsample of at
most ``init_samples`` signals, labels for all signals by the nearest centre, then Sloan 2003's
iterative CPCA over **all** signals: per cluster the mean and the top-n′ principal directions
(refit), then every signal moves to the cluster whose mean + subspace reconstructs it best
(reassign), until the squared reconstruction error stops falling. Each step cannot raise the
error (reassignment picks the minimum, the current cluster included; the refit is the optimal
affine n′-subspace of fixed members), so the recorded history is non-increasing. The
reassignment streams the signals in chunks of bounded scratch memory and each cluster is fitted
from its members alone, so memory stays about the input plus one cluster's rows: the fit scales
to the 871k-vertex dragon (the initialisation is the only subsampled step).

Adaptive allocation (``adaptive=True``): the same total of K·n′ basis vectors is spread over
the clusters by the largest eigenvalues of the clusters' scatter matrices (the greedy optimum
for fixed members), so well-described clusters get fewer vectors and rich ones more. Storage
is then padded to the largest per-cluster count n_max (the uniform layout a shader reads);
:attr:`Cpca.nbytes` counts the padded arrays.
"""

from __future__ import annotations

import math

import numpy as np
from tqdm import tqdm

from prtbench.api.errors import InvalidInputError
from prtbench.transport.compress.cpca import Cpca, check_request
from prtbench.transport.parallel import single_threaded_blas

#: Scratch bytes of one chunk of the reassignment's (chunk × K·n′) projections.
_SCRATCH_BYTES = 64 << 20
#: A cluster with at most this many member × dimension values is fitted by a direct SVD of its
#: rows (most accurate); larger ones by the eigendecomposition of their scatter, accumulated in
#: chunks.
_SVD_VALUES = 1 << 23


def _cluster_spectrum(x: np.ndarray, rows: np.ndarray, keep: int, spectrum: str = "svd",
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(mean (d,), principal directions (keep, d), their eigenvalues (keep,)) of x[rows]."""
    d = x.shape[1]
    small = len(rows) * d <= _SVD_VALUES
    step = max(1, _SVD_VALUES // d)
    if small:
        members = x[rows].astype(np.float64)
        mean = members.mean(axis=0)
    else:  # never a float64 copy of a large cluster: chunks of its rows
        mean = sum(x[rows[i:i + step]].sum(axis=0, dtype=np.float64)
                   for i in range(0, len(rows), step)) / len(rows)
    if keep == 0:
        return mean, np.zeros((0, d)), np.zeros(0)
    if small and spectrum == "gram" and keep < len(rows) < d:
        values, vectors = _gram_spectrum(members - mean, keep)
    elif small:
        _, s, vt = np.linalg.svd(members - mean, full_matrices=False)
        values = s**2
        vectors = vt
    else:  # scatter accumulated over chunks of members (bounded scratch)
        scatter = np.zeros((d, d))
        for start in range(0, len(rows), step):
            part = x[rows[start:start + step]].astype(np.float64) - mean
            scatter += part.T @ part
        values, vectors = np.linalg.eigh(scatter)
        values, vectors = values[::-1].clip(min=0.0), vectors[:, ::-1].T
    out = np.zeros((keep, d))
    out_values = np.zeros(keep)
    take = min(keep, len(vectors))
    out[:take], out_values[:take] = vectors[:take], values[:take]
    if take < keep:  # fewer members than vectors: complete an orthonormal basis
        out = _complete_basis(out, take)
    return mean, out, out_values


def _gram_spectrum(centred: np.ndarray, keep: int) -> tuple[np.ndarray, np.ndarray]:
    """The top ``keep`` eigenpairs of centredᵀ·centred from the m × m Gram matrix (m < d).

    For wide clusters (fewer members m than dimensions d, e.g. 6·N² wavelet coefficients) the
    Gram matrix G = A·Aᵀ costs m²·d in one BLAS-3 product and its top eigenvectors u_i
    (LAPACK's subset eigensolver) give the principal directions v_i = Aᵀ u_i / s_i: the same
    subspace as the SVD, several times faster than a full SVD of A. Directions whose
    eigenvalue is at rounding level of the largest (s_i² < 1e-12 · s_1²) are dropped (the
    caller completes the basis); the rest are re-orthonormalised (QR, signs kept).
    """
    from scipy.linalg import eigh

    m = centred.shape[0]
    gram = centred @ centred.T
    values, u = eigh(gram, subset_by_index=[m - keep, m - 1])
    values, u = values[::-1].clip(min=0.0), u[:, ::-1]
    valid = values > 1e-12 * max(float(values[0]), np.finfo(float).tiny)
    values, u = values[valid], u[:, valid]
    vectors = (u.T @ centred) / np.sqrt(values)[:, None]
    q, r = np.linalg.qr(vectors.T)
    return values, (q * np.sign(np.diag(r))).T


def _complete_basis(basis: np.ndarray, valid: int) -> np.ndarray:
    """``basis`` whose first ``valid`` rows are orthonormal, completed to orthonormal rows."""
    keep, d = basis.shape
    # Householder QR of [valid rows, e_1, e_2, ...]: q's first `valid` columns span the valid
    # rows (up to sign), the next ones complete them. Column j of q depends only on the first
    # j columns, so only the first `keep` are factored: O(d·keep²), not O(d³) per cluster
    # (a cluster of one signal with d = 6·32² wavelet coefficients took seconds).
    q, _ = np.linalg.qr(np.concatenate([basis[:valid].T, np.eye(d, keep - valid)], axis=1))
    out = basis.copy()
    out[valid:] = q[:, valid:keep].T
    return out


def _refit(x: np.ndarray, labels: np.ndarray, *, clusters: int, pca_vectors: int,
           adaptive: bool, previous: Cpca | None, spectrum: str = "svd",
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(means, bases, counts) for fixed ``labels``; an empty cluster keeps its previous fit."""
    d = x.shape[1]
    order = np.argsort(labels, kind="stable")
    bounds = np.searchsorted(labels[order], np.arange(clusters + 1))
    budget = clusters * pca_vectors
    keep = min(d, budget) if adaptive else pca_vectors
    means, bases, values = np.zeros((clusters, d)), np.zeros((clusters, keep, d)), np.zeros(
        (clusters, keep))
    for k in range(clusters):
        rows = order[bounds[k]:bounds[k + 1]]
        if len(rows):
            means[k], bases[k], values[k] = _cluster_spectrum(x, rows, keep, spectrum)
        elif previous is not None:
            means[k] = previous.means[k]
            n_prev = min(keep, previous.pca_vectors)
            bases[k, :n_prev] = previous.bases[k, :n_prev]
            bases[k] = _complete_basis(bases[k], n_prev) if n_prev < keep else bases[k]
            values[k] = 0.0
    if not adaptive:
        return means, bases, np.full(clusters, pca_vectors, np.int32)
    # The budget's largest eigenvalues over all clusters (each cluster's are sorted, so this
    # takes a prefix of every cluster's spectrum); ties broken by cluster order, stably.
    flat = np.argsort(-values.reshape(-1), kind="stable")[:budget]
    counts = np.bincount(flat // keep, minlength=clusters).astype(np.int32)
    width = int(counts.max()) if budget else 0
    padded = np.zeros((clusters, width, d))
    for k in range(clusters):
        padded[k, :counts[k]] = bases[k, :counts[k]]
    return means, padded, counts


def _assess(x: np.ndarray, means: np.ndarray, bases: np.ndarray, labels: np.ndarray
            ) -> tuple[float, np.ndarray]:
    """(total squared error of ``labels`` under the model, best cluster of every signal).

    Error of x under cluster k: ‖x − m_k‖² − ‖B_k (x − m_k)‖² (B_k orthonormal rows). A
    signal keeps its cluster unless another is strictly better (no swaps on rounding ties).
    """
    clusters, width, d = bases.shape
    flat = bases.reshape(clusters * width, d)
    basis_of_mean = np.einsum("knd,kd->kn", bases, means)  # (K, n)
    mean_sq = np.einsum("kd,kd->k", means, means)
    chunk = max(1, _SCRATCH_BYTES // (8 * max(1, clusters * (width + 1))))
    total, best = 0.0, labels.copy()
    for start in range(0, len(x), chunk):
        part = x[start:start + chunk].astype(np.float64)
        err = (np.einsum("nd,nd->n", part, part)[:, None] - 2.0 * part @ means.T
               + mean_sq[None, :])
        if width:
            proj = (part @ flat.T).reshape(len(part), clusters, width) - basis_of_mean[None]
            err -= np.einsum("nkj,nkj->nk", proj, proj)
        err = np.maximum(err, 0.0)
        rows = np.arange(len(part))
        current = err[rows, labels[start:start + chunk]]
        total += float(current.sum())
        choice = err.argmin(axis=1)
        better = err[rows, choice] < current * (1.0 - 1e-12)
        best[start:start + chunk] = np.where(better, choice, labels[start:start + chunk])
    return total, best


def _kmeans_labels(x: np.ndarray, clusters: int, *, seed: int, init_samples: int) -> np.ndarray:
    """k-means (scikit-learn, fitted on at most ``init_samples`` signals) labels of all signals."""
    from sklearn.cluster import KMeans

    rng = np.random.default_rng(seed)
    sample = (x if len(x) <= init_samples
              else x[np.sort(rng.choice(len(x), init_samples, replace=False))])
    km = KMeans(n_clusters=clusters, n_init=1, random_state=seed, tol=0.0, max_iter=300)
    km.fit(sample.astype(np.float64))
    if sample is x:
        return km.labels_.astype(np.int32)
    centres = km.cluster_centers_
    labels = np.empty(len(x), np.int32)
    step = max(1, _SCRATCH_BYTES // (8 * clusters))
    centre_sq = np.einsum("kd,kd->k", centres, centres)
    for start in range(0, len(x), step):
        part = x[start:start + step].astype(np.float64)
        labels[start:start + step] = (centre_sq[None] - 2.0 * part @ centres.T).argmin(axis=1)
    return labels


def fit_cpca(signals: np.ndarray, *, clusters: int, pca_vectors: int, adaptive: bool = False,
             max_iterations: int = 20, tolerance: float = 1e-4, seed: int = 0,
             init_samples: int = 32768, init_labels: np.ndarray | None = None,
             max_bytes: int | None = None, what: str = "signals", progress: bool = False,
             spectrum: str = "svd") -> Cpca:
    """Fit CPCA to ``signals`` (Sloan 2003), float64 throughout.

    Parameters
    ----------
    signals : ndarray, shape (N, d)
        Finite values.
    clusters : int
        K, 1 to N.
    pca_vectors : int
        n′, 0 to d (with ``adaptive``, the average per cluster).
    adaptive : bool
        Spread the K·n′ basis vectors over clusters by eigenvalue (module docstring).
    max_iterations : int
        Reassign/refit rounds after the initial fit.
    tolerance : float
        Stop when an iteration lowers the error by at most this fraction (0: only when no
        signal changes cluster).
    seed : int
        k-means initialisation and its subsample.
    init_samples : int
        Largest subsample the k-means initialisation is fitted on.
    init_labels : ndarray, shape (N,), optional
        Initial cluster ids instead of k-means.
    max_bytes : int, optional
        Refuse (before fitting) a form storing more float32 bytes than this.
    what : str
        What the signals are, for error messages ("vertices").
    progress : bool
        A progress bar over the iterations.
    spectrum : {"svd", "gram"}
        How a cluster with fewer members than dimensions finds its principal directions: the
        SVD of its rows (default), or the top eigenvectors of their Gram matrix
        (:func:`_gram_spectrum`: the same subspace, several times faster for wide signals such
        as wavelet transport rows).

    Returns
    -------
    Cpca
        float64 arrays (:meth:`Cpca.astype` for storage).
    """
    if spectrum not in ("svd", "gram"):
        raise InvalidInputError(f"spectrum '{spectrum}'; accepted: svd, gram")
    x = np.asarray(signals)
    if x.ndim != 2 or x.shape[0] == 0 or x.shape[1] == 0:
        raise InvalidInputError(f"signals of shape {x.shape}; accepted: (N, d) with N, d ≥ 1")
    if not np.isfinite(x).all():
        raise InvalidInputError(f"{what} to compress hold non-finite values; accepted: finite")
    n_signals, d = x.shape
    check_request(n_signals=n_signals, dimension=d, clusters=clusters, pca_vectors=pca_vectors,
                  max_bytes=max_bytes, what=what)

    # The products are many and mid-sized: OpenBLAS's helper threads mostly contend (a 20×
    # slowdown measured on the 2-core machine under load).
    with single_threaded_blas():
        return _fit(x, clusters=clusters, pca_vectors=pca_vectors, adaptive=adaptive,
                    max_iterations=max_iterations, tolerance=tolerance, seed=seed,
                    init_samples=init_samples, init_labels=init_labels, progress=progress,
                    spectrum=spectrum)


def _fit(x: np.ndarray, *, clusters: int, pca_vectors: int, adaptive: bool, max_iterations: int,
         tolerance: float, seed: int, init_samples: int, init_labels: np.ndarray | None,
         progress: bool, spectrum: str = "svd") -> Cpca:
    n_signals = x.shape[0]
    if init_labels is not None:
        labels = np.asarray(init_labels, np.int32)
        if labels.shape != (n_signals,) or labels.min() < 0 or labels.max() >= clusters:
            raise InvalidInputError(f"init_labels of shape {labels.shape}; accepted: ({n_signals},) "
                                    f"ids in 0..{clusters - 1}")
    elif clusters == 1:
        labels = np.zeros(n_signals, np.int32)
    else:
        labels = _kmeans_labels(x, clusters, seed=seed, init_samples=init_samples)
    model = None
    means, bases, counts = _refit(x, labels, clusters=clusters, pca_vectors=pca_vectors,
                                  adaptive=adaptive, previous=None, spectrum=spectrum)
    error, best = _assess(x, means, bases, labels)
    history = [error]
    bar = _bar(max_iterations, f"CPCA K={clusters} n'={pca_vectors}", progress)
    try:
        for _ in range(max_iterations if clusters > 1 else 0):
            if np.array_equal(best, labels):
                break
            labels = best
            model = Cpca(means, bases, counts, labels, np.zeros((0, bases.shape[1])))
            means, bases, counts = _refit(x, labels, clusters=clusters, pca_vectors=pca_vectors,
                                          adaptive=adaptive, previous=model, spectrum=spectrum)
            error, best = _assess(x, means, bases, labels)
            history.append(error)
            if bar is not None:
                bar.update(1)
                bar.set_postfix(rmse=f"{math.sqrt(error / x.size):.3g}")
            if history[-2] - error <= tolerance * history[-2]:
                break
    finally:
        if bar is not None:
            bar.close()
    weights = np.empty((n_signals, bases.shape[1]))
    step = max(1, _SVD_VALUES // x.shape[1])
    for k in range(clusters):
        rows = np.flatnonzero(labels == k)
        for i in range(0, len(rows), step):
            part = rows[i:i + step]
            weights[part] = (x[part].astype(np.float64) - means[k]) @ bases[k].T
    return Cpca(means, bases, counts, labels.astype(np.int32), weights, tuple(history))


def _bar(total: int, desc: str, enabled: bool):
    if not enabled:
        return None

    return tqdm(total=total, desc=desc, leave=False)


def rmse(model: Cpca, signals: np.ndarray) -> float:
    """Root-mean-square of x − x̂ over all N·d values (the final history entry, normalised)."""
    return math.sqrt(model.history[-1] / np.asarray(signals).size) if model.history else float(
        np.sqrt(np.mean((model.reconstruct() - signals) ** 2)))
