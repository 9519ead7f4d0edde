"""Compressed transfer textures: PCA / VQ / CPCA of the texels (Sloan 2003, texels as signals).

The filled texels (covered plus dilated) of the transfer textures are the N signals x ∈ R^{n²}
that :mod:`prtbench.transport.compress` fits; the artifact keeps only the form (``cpca_*`` arrays) and the
``filled`` mask that says which texel each signal is (C order over (S, R, R)).

Rendering (texture_cpca.glsl): the transfer → H map is linear for a fixed light,
H_k = Σ_i T_i M_ik with M_ik = Σ_j Γ_ijk L_j (TPFL's matrix; TP forms the same H), so per
frame the CPU projects every cluster's mean and basis vectors through M once,
P_c = [m_c; B_c]·M, and the fragment shader forms H = P_c0 + Σ_j w_j P_cj for the texels of
its lookup. Resident on the GPU: an R32I texture array of cluster ids (−1 for empty texels), an
RGBA32F array of the n′ weights (⌈n′/4⌉ layers per texture) and P (binding 5); on the CPU the
means and bases the projection needs. Bilinear filtering cannot blend cluster ids, so the
shader reconstructs H at the four texels of the bilinear footprint and blends those (equal to
bilinear filtering of the reconstructed transfer, because H is linear in T); ``nearest`` reads
one texel. Texture-tp and texture-tpfl therefore render the same images when compressed.
"""

from __future__ import annotations

import numpy as np

from methods.common.atlas.texels import layer_count
from prtbench.api.errors import InvalidInputError
from prtbench.render import prt_shading as _triple
from prtbench.transport.compress import check_request
from prtbench.transport.compress import knobs as compress_knobs

#: Binding of the projection table P (cpca.glsl's CpcaProjected).
BINDING_PROJECTED = 5


def texel_signals(transfer: np.ndarray, filled: np.ndarray) -> np.ndarray:
    """(N, C) values of the filled texels of ``transfer`` (S, R, R, C), C order over (S, R, R)."""
    return transfer.reshape(-1, transfer.shape[-1])[np.flatnonzero(filled.reshape(-1))]


def reconstructed_texture(model, filled: np.ndarray, channels: int) -> np.ndarray:
    """(S, R, R, C) float32 transfer rebuilt from the form (zeros outside ``filled``)."""
    out = np.zeros((filled.size, channels), np.float32)
    out[np.flatnonzero(filled.reshape(-1))] = model.reconstruct()
    return out.reshape(*filled.shape, channels)


def check_form(config, *, sets: int, resolution: int) -> None:
    """Refuse a compression of the texture knobs that cannot be made, before any work."""
    form = compress_knobs.resolve(config)
    if form is None:
        return

    if config.bounces > 0:
        raise InvalidInputError(
            f"compress='{config.compress}' with bounces={config.bounces}; accepted: bounces=0 "
            "with compress (the bounce textures are not compressed)")
    if config.storage != "float32":
        raise InvalidInputError(
            f"storage='{config.storage}' has no effect with compress='{config.compress}' (the "
            "form is stored as float32); accepted: storage=float32")
    # The texel count is known after the atlas; all S·R² texels bound it from above here, and
    # the fit checks the exact count.
    check_request(n_signals=sets * resolution * resolution, dimension=config.sh_bands**2,
                  clusters=form.clusters, pca_vectors=form.pca_vectors,
                  what=f"texels of {sets} texture(s) of {resolution}²")


class CompressedTexels:
    """The GPU side of a compressed transfer texture set.

    Parameters
    ----------
    ctx : moderngl.Context
    model : Cpca
        float32 form of the N filled texels.
    filled : ndarray, shape (S, R, R), bool
    sh_bands : int
    """

    def __init__(self, ctx, model, filled: np.ndarray, *, sh_bands: int):
        self.model, self.sh_bands = model, int(sh_bands)
        n2 = self.sh_bands**2
        if model.dimension != n2:
            raise InvalidInputError(f"compressed texels of dimension {model.dimension}; "
                                    f"expected {n2} for sh_bands={sh_bands}")
        filled = np.asarray(filled, bool)
        if int(filled.sum()) != model.n_signals:
            raise InvalidInputError(f"compressed form holds {model.n_signals} texels; the "
                                    f"artifact's mask has {int(filled.sum())}")
        sets, res = filled.shape[0], filled.shape[1]
        index = np.flatnonzero(filled.reshape(-1))
        cluster = np.full(filled.size, -1, np.int32)
        cluster[index] = model.cluster
        self.cluster = ctx.texture_array((res, res, sets), 1,
                                         cluster.reshape(sets, res, res).tobytes(), dtype="i4")
        self.textures = [self.cluster]
        self.weight_layers = layer_count(model.pca_vectors) if model.pca_vectors else 0
        self.weights = None
        if self.weight_layers:
            padded = np.zeros((filled.size, 4 * self.weight_layers), np.float32)
            padded[index, :model.pca_vectors] = model.weights
            layers = np.ascontiguousarray(padded.reshape(sets, res, res, self.weight_layers, 4)
                                          .transpose(0, 3, 1, 2, 4))
            self.weights = ctx.texture_array((res, res, sets * self.weight_layers), 4,
                                             layers.tobytes(), dtype="f4")
            self.textures.append(self.weights)
        for tex in self.textures:  # texelFetch only: no filtering, no wrap
            tex.filter = (ctx.NEAREST, ctx.NEAREST)
            tex.repeat_x = tex.repeat_y = False
        self.projected = ctx.buffer(reserve=model.n_clusters * (1 + model.pca_vectors) * n2
                                    * 3 * 4)
        self._texture_bytes = int(cluster.nbytes) + (
            int(padded.nbytes) if self.weights is not None else 0)
        self._host_bytes = int(model.means.nbytes
                               + (model.bases.nbytes if model.pca_vectors else 0))

    @property
    def defines(self) -> dict[str, int]:
        return {"CPCA_CLUSTERS": self.model.n_clusters, "PCA_VECTORS": self.model.pca_vectors,
                "CPCA_OUTPUTS": self.sh_bands**2, "CPCA_WEIGHT_LAYERS": self.weight_layers}

    def light_operator(self, light):
        """rows (M, n²) → (M, n²·3): H_k,c = Σ_i T_i M_ik,c with M = tpfl_matrix(L)."""

        matrix = _triple.tpfl_matrix_rgb(light.sh(self.sh_bands), self.sh_bands).astype(
            np.float64)  # (n², n², 3)
        return lambda rows: np.einsum("ri,ikc->rkc", rows, matrix).reshape(len(rows), -1)

    def bind(self, program, light) -> None:
        """Project the light per cluster (CPU, every frame, as for the vertex methods: the
        light may change each frame) and bind textures and P."""
        table = self.model.project(self.light_operator(light))  # (K, 1+n', n²·3)
        self.projected.write(np.ascontiguousarray(table, np.float32).tobytes())
        self.projected.bind_to_storage_buffer(BINDING_PROJECTED)
        self.cluster.use(location=3)
        program["cpca_cluster_ids"].value = 3
        if self.weights is not None:
            self.weights.use(location=4)
            program["cpca_weight_layers"].value = 4

    def memory_bytes(self) -> int:
        """Cluster-id and weight textures, the projection table, the CPU means and bases."""
        return self._texture_bytes + int(self.projected.size) + self._host_bytes

    def resident(self) -> list:
        return [*self.textures, self.projected]
