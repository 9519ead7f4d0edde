"""Compressed wavelet vertex transport: PCA, VQ and CPCA (Sloan 2003) of Ng 2003's Haar rows.

``wavelet-vertex`` with ``compress`` = ``pca`` / ``vq`` / ``cpca`` (DESIGN.md §17).

Signals: each vertex's Haar transport vector, all d = 6·N² coefficients: the stored sparse
transport (truncated to ``keep`` per vertex and quantised to ``storage``, exactly what the
uncompressed method renders from) densified to a (V, d) float32 matrix, zeros where nothing was
kept. The dense form and the fit's float64 working copies are what the fit needs
(:func:`fit_bytes`); a form whose fit would exceed this machine's memory is refused before any
work with a one-line error naming the bytes (plants at N = 32: 9k vertices × 6144 coefficients,
226 MB dense). Only the compressed arrays are cached (``cpca_*``), plus the transport-weighted
selection's weights of the reconstruction (``transport_weight``, 6·N² float32).

Render, each frame (host clock around all of it, as uncompressed wavelet-vertex):

1. the light's Haar transform and its k selected terms — the same selection as uncompressed
   (:meth:`methods.wavelet.relight.Relighter.select`);
2. per cluster, the k selected lighting coefficients projected onto the cluster mean and its
   n′ PCA vectors (:meth:`prtbench.transport.compress.cpca.Cpca.project_terms`: K·(n′+1)·k RGB
   multiply-adds, vectorised numpy on the CPU, gathering only the k selected columns);
3. upload of that (K, 1 + n′, RGB) table and the draw: the vertex shader forms B = kd/π ·
   (P_c0 + Σ_j w_j P_cj) from its cluster id and n′ weights (wavelet_vertex.vert with
   cpca.glsl, as ``vertex``'s CPCA path). The per-vertex sum runs on the GPU because it is the
   part that grows with the mesh (V·n′ multiply-adds) while the table is small (K·(1+n′)·3
   floats), so nothing per vertex crosses the bus each frame.

``selection='transport'`` ranks terms by the mean |T̂| over vertices of the *reconstructed*
transport (what this form renders), computed once from the stored form at precompute.

Resident (``memory_bytes``): cluster ids (K > 1) and weights (n′ > 0) and the per-frame table
on the GPU, the means and bases on the CPU (the projection reads them every frame), and the
selection's per-coefficient weights (area or transport; none for magnitude).

Cache: the artifact key is the config's identity without the compress knobs when they are at
their defaults (uncompressed keys unchanged); a compressed form's key also leaves out the
render-time knobs ``light_terms`` and ``selection`` (its arrays do not depend on them), so it
depends on the transport's precompute knobs and the form alone.
"""

from __future__ import annotations

import numpy as np

from methods.wavelet import SHADER_DIR
from methods.wavelet.relight import Relighter, host_frame_times
from prtbench.api.config import check_memory, format_bytes
from prtbench.api.errors import InvalidInputError
from prtbench.api.method import Artifact, FrameTimes
from prtbench.render.raster import RasterRenderer
from prtbench.transport.compress import check_request
from prtbench.transport.compress import knobs as compress_knobs
from prtbench.transport.compress.buffers import CpcaBuffers
from prtbench.transport.wavelet.sparse import SparseTransport

#: k-means seed of the fit (wavelet-vertex has no seed knob: its transport is deterministic).
COMPRESS_SEED = 0
#: Scratch of the fit beyond the arrays :func:`fit_bytes` counts (k-means, SVD work).
FIT_WORKING_BYTES = 256 << 20
#: Column entries densified at a time (bounds the index scratch).
_DENSIFY_ENTRIES = 1 << 22
#: Vertices reconstructed at a time for the transport weights.
_RECONSTRUCT_ROWS = 4096


def fit_bytes(*, vertices: int, dimension: int, clusters: int, pca_vectors: int) -> int:
    """Peak host bytes of densifying and fitting (before the fit, from the sizes alone).

    The dense float32 signals (V·d·4) and a float64 copy of them (the reassignment's chunks
    and the small clusters' SVDs may hold all rows at once: V·d·8), the float64 form three
    times (the refit beside the previous fit, and the stored float32 copy: 3·K·(1+n′)·d·8),
    the float64 weights (V·n′·8) and :data:`FIT_WORKING_BYTES`.
    """
    v, d, k, n = int(vertices), int(dimension), int(clusters), int(pca_vectors)
    return v * d * 12 + 3 * k * (1 + n) * d * 8 + v * n * 8 + FIT_WORKING_BYTES


def check_compress(scene, config, *, dimension: int) -> None:
    """Refuse, before any work, a form that cannot be made: K outside 1..V, n′ outside 0..d,
    or a fit over this machine's memory (one line naming the bytes)."""

    form = compress_knobs.resolve(config)
    if form is None:
        return
    v = scene.n_vertices
    check_request(n_signals=v, dimension=dimension, clusters=form.clusters,
                  pca_vectors=form.pca_vectors, what=f"vertices of scene '{scene.name}'")
    need = fit_bytes(vertices=v, dimension=dimension, clusters=form.clusters,
                     pca_vectors=form.pca_vectors)
    check_memory(f"method 'wavelet-vertex' compress={form.kind} clusters={form.clusters} "
                 f"pca_vectors={form.pca_vectors} on {v} vertices × {dimension} coefficients "
                 f"(cubemap={config.cubemap}; dense float32 transport {format_bytes(v * dimension * 4)}"
                 f", {need} bytes with the fit's copies)", need,
                 accepted="fewer clusters or pca_vectors, a smaller cubemap or a coarser mesh")


def dense_rows(transport: SparseTransport) -> np.ndarray:
    """(P, M) float32 dense transport: the stored (truncated, dequantised) entries, 0 elsewhere.

    Densified a block of columns at a time, so the index scratch stays bounded.
    """
    out = np.zeros((transport.n_points, transport.n_coeffs), np.float32)
    indptr = transport.indptr
    col = 0
    while col < transport.n_coeffs:
        end = int(np.searchsorted(indptr, indptr[col] + _DENSIFY_ENTRIES, side="right")) - 1
        end = min(max(end, col + 1), transport.n_coeffs)
        lo, hi = int(indptr[col]), int(indptr[end])
        rows = transport.rows[lo:hi].astype(np.int64)
        values = transport.values[lo:hi].astype(np.float32)
        if transport.scale is not None:
            values *= transport.scale[rows]
        cols = np.repeat(np.arange(col, end), np.diff(indptr[col:end + 1]))
        out[rows, cols] = values
        col = end
    return out


def reconstructed_weights(model) -> np.ndarray:
    """(d,) float32 mean over signals of |x̂_i| (the ``transport`` selection's weights of the
    form's reconstruction), accumulated in float64 over blocks of rows."""
    total = np.zeros(model.dimension)
    for start in range(0, model.n_signals, _RECONSTRUCT_ROWS):
        rows = slice(start, start + _RECONSTRUCT_ROWS)
        total += np.abs(model.reconstruct(rows)).sum(axis=0, dtype=np.float64)
    return (total / max(model.n_signals, 1)).astype(np.float32)


def compress_transport(transport: SparseTransport, form, *, what: str, progress: bool = False,
                       ) -> tuple[dict[str, np.ndarray], dict]:
    """Fit ``form`` to the densified transport; (artifact arrays, meta).

    Arrays: ``cpca_*`` (:func:`prtbench.transport.compress.knobs.compress_signals`) and
    ``transport_weight`` (:func:`reconstructed_weights`). Meta: the fit's (error history,
    transfer RMSE against the dense transport, compressed and dense float32 bytes, fit time).
    """
    dense = dense_rows(transport)
    # Clusters of these wide signals (d = 6·N² beside a few hundred members) take their
    # principal directions from the Gram matrix: the SVD's subspace, several times faster.
    arrays, meta = compress_knobs.compress_signals(dense, form, seed=COMPRESS_SEED, what=what,
                                                   progress=progress, spectrum="gram")
    del dense
    model = compress_knobs.load_model(arrays, n_signals=transport.n_points)
    arrays["transport_weight"] = reconstructed_weights(model)
    return arrays, meta


class CompressedWaveletVertexRenderer(RasterRenderer):
    """Wavelet vertex PRT from a PCA / VQ / CPCA form: per frame the CPU selects the light's k
    Haar terms and projects them per cluster; the vertex shader adds its n′ weighted entries."""

    shader_dirs = (SHADER_DIR,)

    def __init__(self, scene, artifact: Artifact, config, *, width: int, height: int):
        self.config = config
        self.model = compress_knobs.load_model(artifact.arrays, n_signals=scene.n_vertices)
        m = 6 * config.cubemap**2
        if self.model.dimension != m:
            raise InvalidInputError(f"compressed transport of dimension {self.model.dimension}; "
                                    f"expected {m} (6·N²) for cubemap={config.cubemap}")
        super().__init__(scene, width=width, height=height, vertex_shader="wavelet_vertex.vert",
                         fragment_shader="interpolated_radiance.frag",
                         defines={"CPCA_CLUSTERS": self.model.n_clusters,
                                  "PCA_VECTORS": self.model.pca_vectors, "CPCA_OUTPUTS": 1})
        self.cpca = CpcaBuffers(self.ctx, self.model, outputs=1)
        self._resident = self.cpca.buffers()
        weight = artifact.arrays["transport_weight"] if config.selection == "transport" else None
        self.relight = Relighter(None, config, transport_weight=weight)

    @property
    def last_terms(self) -> np.ndarray | None:
        """Lighting terms selected in the last frame (inspection and tests)."""
        return self.relight.last_terms

    def projection(self, light) -> np.ndarray:
        """(K, 1 + n′, 3) float64: this frame's k selected lighting terms projected onto every
        cluster's mean (row 0) and PCA vectors (rows 1..n′)."""
        coeffs, terms = self.relight.select(light)
        return self.model.project_terms(terms, coeffs[terms])

    def _bind(self, view, light) -> None:
        self.cpca.bind_table(self.projection(light))

    def frame_time(self, view, light, *, warmup: int, frames: int) -> FrameTimes:
        """Host clock around whole frames (Haar, selection, projection, upload, draw, finish)."""
        self.relight.light_cube(light)  # per light, outside the frame
        return host_frame_times(self.ctx, lambda: self._draw(view, light), warmup=warmup,
                                frames=frames, renderer=self.renderer_string)

    def memory_bytes(self) -> int:
        """The CPCA buffers (ids, weights, table) + CPU means and bases + selection weights."""
        return int(self.cpca.memory_bytes() + self.relight.nbytes)
