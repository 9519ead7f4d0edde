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

Fitting: :func:`prtbench.transport.compress.fit.fit_cpca`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from prtbench.api.errors import InvalidInputError


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

    def project_terms(self, terms: np.ndarray, values: np.ndarray) -> np.ndarray:
        """:meth:`project` for a light operator with only ``terms`` rows non-zero.

        A sparse light (e.g. Ng 2003's k selected wavelet coefficients) meets only k of the d
        columns of every mean and basis vector: P_k = [m_k; B_k][:, terms] · values costs
        K·(1 + n′)·k multiply-adds and gathers no other column (no (K, 1 + n′, d) copy).

        Parameters
        ----------
        terms : ndarray, shape (k,), int
            Signal dimensions the light is non-zero on.
        values : ndarray, shape (k, out)
            The operator's rows at ``terms``.

        Returns
        -------
        ndarray, shape (K, 1 + n, out), float64
            As :meth:`project`.
        """
        terms = np.asarray(terms, dtype=np.int64)
        values = np.asarray(values, dtype=np.float64)
        out = np.empty((self.n_clusters, 1 + self.pca_vectors, values.shape[1]))
        out[:, 0] = self.means[:, terms] @ values
        if self.pca_vectors:
            out[:, 1:] = self.bases[:, :, terms] @ values
        return out

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
