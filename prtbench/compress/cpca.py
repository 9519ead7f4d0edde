"""Clustered principal component analysis of stored transfer (Sloan et al. 2003).

A set of N signals x_i ∈ R^d (transfer vectors, flattened transfer matrices, texels) is split
into K clusters; each cluster k keeps its mean m_k and n′ orthonormal basis vectors B_k
(n′ × d), each signal its cluster id c(i) and n′ weights w_i = B_c (x_i − m_c), so that

    x_i ≈ m_c + B_cᵀ w_i.

Special cases: K = 1 is global PCA (one SVD), n′ = 0 is vector quantisation (k-means, each
signal replaced by its cluster mean), n′ = d is lossless. Because rendering is linear in the
transfer (y_i = x_i · A for a light operator A, d × out), the light is projected once per
cluster onto the mean and the basis, P_k = [m_k; B_k] · A, and each signal needs only the n′-term
dot product y_i = P_c0 + Σ_j w_ij P_cj: Sloan's CPCA rendering (:meth:`Cpca.project`,
:meth:`Cpca.apply`).

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
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..errors import InvalidInputError

#: Scratch bytes of one chunk of the reassignment's (chunk × K·n′) projections.
_SCRATCH_BYTES = 64 << 20
#: A cluster with at most this many member × dimension values is fitted by a direct SVD of its
#: rows (most accurate); larger ones by the eigendecomposition of their scatter, accumulated in
#: chunks.
_SVD_VALUES = 1 << 23


@dataclass(frozen=True)
class Cpca:
    """A fitted clustered-PCA representation.

    Attributes
    ----------
    means : ndarray, shape (K, d)
        Cluster means m_k.
    bases : ndarray, shape (K, n, d)
        Orthonormal basis rows B_k; rows beyond ``counts[k]`` are zero (adaptive allocation).
    counts : ndarray, shape (K,), int32
        Basis vectors used by each cluster (all n unless adaptive).
    cluster : ndarray, shape (N,), int32
        Cluster id of each signal.
    weights : ndarray, shape (N, n)
        w_i = B_c (x_i − m_c).
    history : tuple of float
        Total squared reconstruction error Σ_i ‖x_i − x̂_i‖² after the initialisation and after
        each CPCA iteration (float64, non-increasing).
    """

    means: np.ndarray
    bases: np.ndarray
    counts: np.ndarray
    cluster: np.ndarray
    weights: np.ndarray
    history: tuple[float, ...] = field(default=())

    @property
    def n_clusters(self) -> int:
        return int(self.means.shape[0])

    @property
    def pca_vectors(self) -> int:
        """Basis vectors stored per cluster (n_max when adaptive)."""
        return int(self.bases.shape[1])

    @property
    def dimension(self) -> int:
        return int(self.means.shape[1])

    @property
    def n_signals(self) -> int:
        return int(self.cluster.shape[0])

    def stored_arrays(self) -> dict[str, np.ndarray]:
        """The arrays this form keeps: cluster ids only with K > 1, weights only with n > 0,
        per-cluster counts only when they differ (adaptive)."""
        out = {"means": self.means}
        if self.pca_vectors:
            out["bases"] = self.bases
            out["weights"] = self.weights
        if self.n_clusters > 1:
            out["cluster"] = self.cluster
        if np.any(self.counts != self.pca_vectors):
            out["counts"] = self.counts
        return out

    @property
    def nbytes(self) -> int:
        """Bytes of :meth:`stored_arrays` (real arrays, their dtypes)."""
        return int(sum(a.nbytes for a in self.stored_arrays().values()))

    def astype(self, dtype) -> "Cpca":
        """A copy with float arrays in ``dtype`` (e.g. float32 for storage)."""
        return Cpca(self.means.astype(dtype), self.bases.astype(dtype), self.counts,
                    self.cluster, self.weights.astype(dtype), self.history)

    def reconstruct(self, rows: slice | None = None) -> np.ndarray:
        """x̂_i = m_c + B_cᵀ w_i, shape (N, d) (or the signals of ``rows``), in the float dtype
        of the model."""
        cluster = self.cluster if rows is None else self.cluster[rows]
        weights = self.weights if rows is None else self.weights[rows]
        out = self.means[cluster].copy()
        for k in np.unique(cluster) if self.pca_vectors else ():
            members = np.flatnonzero(cluster == k)
            out[members] += weights[members] @ self.bases[k]
        return out

    def squared_error(self, signals: np.ndarray, *, chunk: int = 1 << 14) -> tuple[float, float]:
        """(Σ ‖x_i − x̂_i‖², Σ ‖x_i‖²) in float64, over chunks of ``chunk`` signals."""
        error = energy = 0.0
        for start in range(0, self.n_signals, chunk):
            sl = slice(start, start + chunk)
            x = np.asarray(signals[sl], np.float64)
            error += float(np.sum((self.reconstruct(sl).astype(np.float64) - x) ** 2))
            energy += float(np.sum(x**2))
        return error, energy

    def project(self, light: np.ndarray | Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
        """Per-cluster projection of a linear light operator: P_k = [m_k; B_k] · A.

        Parameters
        ----------
        light : ndarray, shape (d, out), or callable
            The operator A, or a function mapping rows (M, d) to (M, out) linearly (used
            where A is structured, e.g. a transfer matrix times the light's SH vector).

        Returns
        -------
        ndarray, shape (K, 1 + n, out)
            Row 0 is the mean's output, rows 1.. the basis vectors'.
        """
        rows = np.concatenate([self.means[:, None, :], self.bases], axis=1)  # (K, 1+n, d)
        flat = rows.reshape(-1, self.dimension)
        out = flat @ light if isinstance(light, np.ndarray) else np.asarray(light(flat))
        return out.reshape(self.n_clusters, 1 + self.pca_vectors, -1)

    def apply(self, projected: np.ndarray) -> np.ndarray:
        """Per-signal output y_i = P_c0 + Σ_j w_ij P_cj, shape (N, out).

        Parameters
        ----------
        projected : ndarray, shape (K, 1 + n, out)
            :meth:`project`'s result.
        """
        table = projected[self.cluster]  # (N, 1+n, out)
        return table[:, 0] + np.einsum("nj,njo->no", self.weights, table[:, 1:])


def stored_bytes(*, n_signals: int, dimension: int, clusters: int, pca_vectors: int,
                 float_bytes: int = 4) -> int:
    """Bytes :attr:`Cpca.nbytes` will report for a uniform allocation (before fitting).

    Means K·d, bases K·n′·d and weights N·n′ floats, cluster ids N int32 when K > 1.
    """
    floats = clusters * dimension + clusters * pca_vectors * dimension + n_signals * pca_vectors
    return int(floats * float_bytes + (4 * n_signals if clusters > 1 else 0))


def check_request(*, n_signals: int, dimension: int, clusters: int, pca_vectors: int,
                  max_bytes: int | None = None, float_bytes: int = 4, what: str = "signals",
                  ) -> int:
    """Refuse a compression that cannot be made, before any work; returns its stored bytes.

    Raises
    ------
    InvalidInputError
        ``clusters`` outside 1..N, ``pca_vectors`` outside 0..d, or stored bytes over
        ``max_bytes`` (the message names both byte counts).
    """
    if not 1 <= clusters <= n_signals:
        raise InvalidInputError(f"clusters={clusters} for {n_signals} {what}; accepted: 1 to "
                                f"{n_signals} (at most one cluster per signal)")
    if not 0 <= pca_vectors <= dimension:
        raise InvalidInputError(f"pca_vectors={pca_vectors} for signals of dimension {dimension}; "
                                f"accepted: 0 to {dimension}")
    size = stored_bytes(n_signals=n_signals, dimension=dimension, clusters=clusters,
                        pca_vectors=pca_vectors, float_bytes=float_bytes)
    if max_bytes is not None and size > max_bytes:
        raise InvalidInputError(
            f"the compression of {n_signals} {what} (dimension {dimension}) with "
            f"clusters={clusters}, pca_vectors={pca_vectors} would store {size} bytes, over the "
            f"limit of {max_bytes} bytes; accepted: fewer clusters or pca_vectors, or a higher "
            "limit")
    return size


# --- fitting ----------------------------------------------------------------------------------

def _cluster_spectrum(x: np.ndarray, rows: np.ndarray, keep: int) -> tuple[np.ndarray, np.ndarray,
                                                                            np.ndarray]:
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
    if small:
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


def _complete_basis(basis: np.ndarray, valid: int) -> np.ndarray:
    """``basis`` whose first ``valid`` rows are orthonormal, completed to orthonormal rows."""
    keep, d = basis.shape
    q, _ = np.linalg.qr(np.concatenate([basis[:valid].T, np.eye(d)], axis=1))
    # q's first `valid` columns span the valid rows (up to sign); take the rest as completion.
    out = basis.copy()
    out[valid:] = q[:, valid:keep].T
    return out


def _refit(x: np.ndarray, labels: np.ndarray, *, clusters: int, pca_vectors: int,
           adaptive: bool, previous: Cpca | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
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
            means[k], bases[k], values[k] = _cluster_spectrum(x, rows, keep)
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
             ) -> Cpca:
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

    Returns
    -------
    Cpca
        float64 arrays (:meth:`Cpca.astype` for storage).
    """
    x = np.asarray(signals)
    if x.ndim != 2 or x.shape[0] == 0 or x.shape[1] == 0:
        raise InvalidInputError(f"signals of shape {x.shape}; accepted: (N, d) with N, d ≥ 1")
    if not np.isfinite(x).all():
        raise InvalidInputError(f"{what} to compress hold non-finite values; accepted: finite")
    n_signals, d = x.shape
    check_request(n_signals=n_signals, dimension=d, clusters=clusters, pca_vectors=pca_vectors,
                  max_bytes=max_bytes, what=what)
    from ..parallel import single_threaded_blas

    # The products are many and mid-sized: OpenBLAS's helper threads mostly contend (a 20×
    # slowdown measured on the 2-core machine under load).
    with single_threaded_blas():
        return _fit(x, clusters=clusters, pca_vectors=pca_vectors, adaptive=adaptive,
                    max_iterations=max_iterations, tolerance=tolerance, seed=seed,
                    init_samples=init_samples, init_labels=init_labels, progress=progress)


def _fit(x: np.ndarray, *, clusters: int, pca_vectors: int, adaptive: bool, max_iterations: int,
         tolerance: float, seed: int, init_samples: int, init_labels: np.ndarray | None,
         progress: bool) -> Cpca:
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
                                  adaptive=adaptive, previous=None)
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
                                          adaptive=adaptive, previous=model)
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
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, leave=False)


def rmse(model: Cpca, signals: np.ndarray) -> float:
    """Root-mean-square of x − x̂ over all N·d values (the final history entry, normalised)."""
    return math.sqrt(model.history[-1] / np.asarray(signals).size) if model.history else float(
        np.sqrt(np.mean((model.reconstruct() - signals) ** 2)))
