"""GL storage buffers of a CPCA form, as ``cpca.glsl`` (prtbench/render/shaders) reads them.

Resident on the GPU: cluster ids (N int32, only with K > 1) at binding 3, weights (N × n′
float32, only with n′ > 0) at binding 4, and the per-frame light projection table P
(K × (1 + n′) × outputs × 3 float32) at binding 5, rewritten every frame from the means and
bases kept on the CPU. :meth:`CpcaBuffers.memory_bytes` counts all of it: the GPU buffers plus
the CPU-side means and bases the projection needs each frame.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

#: Binding points of cpca.glsl (0-2 are the vertex methods' own buffers).
BINDING_CLUSTER, BINDING_WEIGHTS, BINDING_PROJECTED = 3, 4, 5


class CpcaBuffers:
    """The GPU side of a :class:`~prtbench.transport.compress.cpca.Cpca` form.

    Parameters
    ----------
    ctx : moderngl.Context
    model : Cpca
        float32 arrays.
    outputs : int
        vec3 outputs per signal (1 for diffuse radiance, n² for the transferred radiance H).
    """

    def __init__(self, ctx, model, *, outputs: int):
        self.model, self.outputs = model, int(outputs)
        k, n = model.n_clusters, model.pca_vectors
        self.cluster = (ctx.buffer(np.ascontiguousarray(model.cluster, np.int32).tobytes())
                        if k > 1 else None)
        self.weights = (ctx.buffer(np.ascontiguousarray(model.weights, np.float32).tobytes())
                        if n > 0 else None)
        self.projected = ctx.buffer(reserve=k * (1 + n) * self.outputs * 3 * 4)
        self._host_bytes = int(model.means.nbytes + (model.bases.nbytes if n else 0))

    @property
    def defines(self) -> dict[str, int]:
        return {"CPCA_CLUSTERS": self.model.n_clusters, "PCA_VECTORS": self.model.pca_vectors,
                "CPCA_OUTPUTS": self.outputs}

    def bind(self, light: np.ndarray | Callable[[np.ndarray], np.ndarray]) -> None:
        """Project the light per cluster (CPU, :meth:`Cpca.project`) and bind the buffers.

        ``light`` maps signal rows (M, d) to (M, outputs · 3), output-major then RGB.
        """
        self.bind_table(self.model.project(light))

    def bind_table(self, table: np.ndarray) -> None:
        """Upload a projection table computed by the caller and bind the buffers.

        ``table`` is (K, 1 + n′, outputs · 3), e.g. :meth:`Cpca.project_terms` of a sparse
        light.
        """
        self.projected.write(np.ascontiguousarray(table, np.float32).tobytes())
        self.projected.bind_to_storage_buffer(BINDING_PROJECTED)
        if self.cluster is not None:
            self.cluster.bind_to_storage_buffer(BINDING_CLUSTER)
        if self.weights is not None:
            self.weights.bind_to_storage_buffer(BINDING_WEIGHTS)

    def buffers(self) -> list:
        return [b for b in (self.cluster, self.weights, self.projected) if b is not None]

    def memory_bytes(self) -> int:
        return int(sum(b.size for b in self.buffers())) + self._host_bytes

    def release(self) -> None:
        for b in self.buffers():
            b.release()
