"""The ``compress`` / ``clusters`` / ``pca_vectors`` knobs of stored-transfer methods.

A method adds the three fields with :func:`compress_knob`, :func:`clusters_knob` and
:func:`pca_vectors_knob`, resolves them with :func:`resolve` (which refuses a knob that its
``compress`` form does not use, rather than ignoring it), fits with :func:`compress_signals`
and keeps only the compressed arrays in its artifact (``cpca_*``), which
:func:`load_model` turns back into a :class:`~prtbench.transport.compress.cpca.Cpca`.

Forms: ``none`` (the stored transfer as it is), ``pca`` (K = 1), ``vq`` (n′ = 0, k-means) and
``cpca`` (K clusters × n′ vectors). The fit's schedule is fixed (:data:`MAX_ITERATIONS`,
:data:`TOLERANCE`); the method's ``seed`` seeds the k-means initialisation.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from prtbench.api.config import knob
from prtbench.api.errors import InvalidInputError
from prtbench.transport.compress.cpca import Cpca
from prtbench.transport.compress.fit import fit_cpca

COMPRESS_FORMS = ("none", "pca", "vq", "cpca")
#: Defaults of the knobs a form uses when they are left unset (None).
DEFAULT_CLUSTERS = {"vq": 256, "cpca": 64}
DEFAULT_PCA_VECTORS = {"pca": 8, "cpca": 8}
KNOB_NAMES = ("compress", "clusters", "pca_vectors")
MAX_ITERATIONS = 20
TOLERANCE = 1e-4
PREFIX = "cpca_"


def compress_knob() -> Any:
    return knob("none", "Compression of the stored transfer (Sloan 2003): none, pca (one "
                        "cluster, global PCA), vq (k-means vector quantisation: cluster means "
                        "only) or cpca (clustered PCA). The compressed form is what is cached and "
                        "resident; the light is projected per cluster on the CPU each frame.",
                choices=COMPRESS_FORMS)


def clusters_knob() -> Any:
    return knob(None, "Clusters K of compress=vq/cpca (unset: 256 for vq, 64 for cpca); must "
                      "stay unset otherwise.", low=1, high=1 << 20)


def pca_vectors_knob() -> Any:
    return knob(None, "PCA vectors n′ per cluster of compress=pca/cpca (unset: 8); must stay "
                      "unset otherwise.", low=0, high=1 << 16)


@dataclass(frozen=True)
class Form:
    """A resolved compression: ``kind`` and its K and n′."""

    kind: str
    clusters: int
    pca_vectors: int


def resolve(config: Any) -> Form | None:
    """The compression ``config`` asks for, or None for ``compress='none'``.

    Raises
    ------
    InvalidInputError
        A knob set that the form does not use (``clusters`` with none/pca, ``pca_vectors`` with
        none/vq), so a misspelt intent is never silently ignored.
    """
    kind, clusters, vectors = config.compress, config.clusters, config.pca_vectors
    uses = {"none": (), "pca": ("pca_vectors",), "vq": ("clusters",),
            "cpca": ("clusters", "pca_vectors")}[kind]
    for name, value in (("clusters", clusters), ("pca_vectors", vectors)):
        if value is not None and name not in uses:
            fix = {"none": "set compress to pca, vq or cpca",
                   "pca": "use compress=cpca for several clusters",
                   "vq": "use compress=cpca for PCA vectors per cluster"}[kind]
            raise InvalidInputError(f"{name}={value} has no effect with compress='{kind}'; "
                                    f"accepted: {name} unset, or {fix}")
    if kind == "none":
        return None
    k = 1 if kind == "pca" else (clusters if clusters is not None else DEFAULT_CLUSTERS[kind])
    n = 0 if kind == "vq" else (vectors if vectors is not None else DEFAULT_PCA_VECTORS[kind])
    return Form(kind, int(k), int(n))


def cache_identity(values: Mapping[str, Any]) -> dict[str, Any]:
    """A config dict without the compress knobs when they are all unset/``none``: adding the
    knobs leaves every uncompressed artifact's cache key as it was."""
    out = dict(values)
    if out.get("compress") == "none" and out.get("clusters") is None and out.get(
            "pca_vectors") is None:
        for name in KNOB_NAMES:
            out.pop(name, None)
    return out


def compress_signals(signals: np.ndarray, form: Form, *, seed: int, what: str = "vertices",
                     max_bytes: int | None = None, progress: bool = False,
                     spectrum: str = "svd") -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """Fit ``form`` to ``signals`` (N, d); (artifact arrays, meta).

    Arrays: ``cpca_means`` (K, d), ``cpca_bases`` (K, n′, d), ``cpca_weights`` (N, n′) float32,
    ``cpca_cluster`` (N,) int32 — only those the form stores (:meth:`Cpca.stored_arrays`).
    Meta: the form, the fit's error history, the transfer RMSE over all N·d values of the
    float32 form, the compressed and uncompressed bytes, the fit's wall time. ``spectrum``:
    :func:`prtbench.transport.compress.fit.fit_cpca`'s.
    """

    start = time.perf_counter()
    x = np.asarray(signals).reshape(len(signals), -1)
    model = fit_cpca(x, clusters=form.clusters, pca_vectors=form.pca_vectors, seed=seed,
                     max_iterations=MAX_ITERATIONS, tolerance=TOLERANCE, max_bytes=max_bytes,
                     what=what, progress=progress, spectrum=spectrum).astype(np.float32)
    fit_s = time.perf_counter() - start
    stored = model.stored_arrays()
    arrays = {PREFIX + name: value for name, value in stored.items()}
    error, energy = model.squared_error(x)  # of the stored float32 form, chunked
    meta = {"compress": form.kind, "clusters": form.clusters, "pca_vectors": form.pca_vectors,
            "iterations": len(model.history) - 1,
            "error_history": [float(e) for e in model.history],
            "transfer_rmse": float(np.sqrt(error / x.size)),
            "transfer_rms": float(np.sqrt(energy / x.size)),
            "compressed_bytes": model.nbytes, "uncompressed_bytes": int(x.size * 4),
            "fit_s": fit_s}
    return arrays, meta


def is_compressed(arrays: Mapping[str, np.ndarray]) -> bool:
    return PREFIX + "means" in arrays


def load_model(arrays: Mapping[str, np.ndarray], *, n_signals: int):
    """The :class:`~prtbench.transport.compress.cpca.Cpca` of an artifact's ``cpca_*`` arrays."""

    means = np.asarray(arrays[PREFIX + "means"], np.float32)
    clusters, d = means.shape
    bases = np.asarray(arrays.get(PREFIX + "bases", np.zeros((clusters, 0, d))), np.float32)
    weights = np.asarray(arrays.get(PREFIX + "weights", np.zeros((n_signals, 0))), np.float32)
    cluster = np.asarray(arrays.get(PREFIX + "cluster", np.zeros(n_signals)), np.int32)
    counts = np.asarray(arrays.get(PREFIX + "counts", np.full(clusters, bases.shape[1])),
                        np.int32)
    if cluster.shape != (n_signals,) or weights.shape[0] != n_signals:
        raise InvalidInputError(f"compressed artifact holds {cluster.shape[0]} signals; expected "
                                f"{n_signals} (one per vertex of the scene)")
    return Cpca(means, bases, counts, cluster, weights)
