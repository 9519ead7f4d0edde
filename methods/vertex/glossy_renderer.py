"""The renderers of the glossy per-vertex methods: transfer vectors shaded by the triple product or
the fixed-light matrix (``vertex_glossy.vert`` with ``prt_shading.glsl``), and Sloan's matrices from
their compressed (CPCA) form.
"""

from __future__ import annotations

import numpy as np

from methods.vertex import SHADER_DIR
from prtbench.api.errors import InvalidInputError
from prtbench.api.method import Artifact
from prtbench.render import gl
from prtbench.render import prt_shading as _triple
from prtbench.render.raster import RasterRenderer
from prtbench.transport.compress import knobs as compress_knobs
from prtbench.transport.compress.buffers import CpcaBuffers

# --- renderer ---------------------------------------------------------------------------------

#: GLSL selector of how the vertex shader forms H (``GLOSSY_MODE`` in vertex_glossy.vert).
MODE_TP, MODE_TPFL, MODE_MATRIX = 0, 1, 2


def material_attributes(scene) -> dict[str, np.ndarray]:
    """Per-vertex ks (V, 3) and shininess (V, 1) float32 in merged order (kd is added by
    :class:`RasterRenderer`)."""
    ks = np.concatenate([np.broadcast_to(np.asarray(o.material.ks, np.float32),
                                         (o.mesh.n_vertices, 3)) for o in scene.objects])
    shininess = np.concatenate([np.full((o.mesh.n_vertices, 1), o.material.shininess, np.float32)
                                for o in scene.objects])
    return {"ks": ks, "shininess": shininess}


def format_size(size: int) -> str:
    """``size`` bytes in KiB, MiB or GiB, for messages."""
    if size >= 2**30:
        return f"{size / 2**30:.2f} GiB"
    return f"{size / 2**20:.1f} MiB" if size >= 2**20 else f"{size / 2**10:.0f} KiB"


def storage_limit_message(key: str, nbytes: int, limit: int, *, rgb: bool, what: str = "") -> str:
    """The one-line refusal of a per-vertex buffer over the GL's shader storage block limit."""
    return (f"{what}{key} buffer of {format_size(nbytes)} exceeds this GL's shader storage "
            f"block limit of {format_size(limit)}; use fewer sh_bands or a coarser mesh"
            + (" (bounces make the matrices RGB: 3× the floats)" if rgb else ""))


class GlossyVertexRenderer(RasterRenderer):
    """Per-vertex H (TP, TPFL or matrix) and Phong shading; interpolated radiance.

    Parameters
    ----------
    scene : Scene
    artifact : Artifact
        ``transfer`` (V, n²) for TP/TPFL or ``matrices`` (V, n², n²) for the matrix mode.
    mode : int
        :data:`MODE_TP`, :data:`MODE_TPFL` or :data:`MODE_MATRIX`.
    sh_bands : int
    width, height : int
    """

    shader_dirs = (SHADER_DIR,)

    def __init__(self, scene, artifact: Artifact, *, mode: int, sh_bands: int, width: int,
                 height: int):
        key = "matrices" if mode == MODE_MATRIX else "transfer"
        data = np.ascontiguousarray(artifact.arrays[key], dtype=np.float32)
        n2 = sh_bands * sh_bands
        expected = (scene.n_vertices, n2, n2) if mode == MODE_MATRIX else (scene.n_vertices, n2)
        # Interreflected matrices (bounces) are RGB: (V, n², n², 3), read as MATRIX_RGB.
        rgb = mode == MODE_MATRIX and data.ndim == 4
        if rgb:
            expected = expected + (3,)
        if data.shape != expected:
            raise InvalidInputError(f"artifact '{key}' has shape {data.shape}; expected {expected} "
                                    f"for scene '{scene.name}' with sh_bands={sh_bands}")
        self.mode, self.sh_bands = mode, sh_bands
        super().__init__(scene, width=width, height=height, vertex_shader="vertex_glossy.vert",
                         fragment_shader="interpolated_radiance.frag",
                         defines={"SH_BANDS": sh_bands, "GLOSSY_MODE": mode,
                                  **({"MATRIX_RGB": 1} if rgb else {})},
                         extra_attributes=material_attributes(scene))

        limit = gl.storage_block_limit(self.ctx)
        if limit and data.nbytes > limit:
            RasterRenderer.release(self)
            raise InvalidInputError(storage_limit_message(key, data.nbytes, limit, rgb=rgb))
        # Vertex-major: transfer[v·n² + i], matrices[v·n⁴ + k·n² + i] or, RGB,
        # matrices[(v·n⁴ + k·n² + i)·3 + c].
        self.data_buffer = self.ctx.buffer(data.tobytes())
        self.triple = _triple.TripleProductBuffers(self.ctx, sh_bands, gamma=mode == MODE_TP)
        self._resident = [self.data_buffer]

    def _bind(self, view, light) -> None:
        self.data_buffer.bind_to_storage_buffer(0)
        if self.mode == MODE_TP:
            self.triple.bind_gamma()
        elif self.mode == MODE_TPFL:
            self.triple.bind_tpfl(light)
        if "light_sh" in self.program:  # TPFL folds the light into M: the uniform is unused
            coeffs = light.sh(self.sh_bands).astype(np.float32)  # (n², 3)
            self.program["light_sh"].write(np.ascontiguousarray(coeffs).tobytes())

    def memory_bytes(self) -> int:
        """Per-vertex transfer data plus the Γ list (TP) or the current TPFL matrix."""
        return int(self.data_buffer.size) + self.triple.memory_bytes()

    def release(self) -> None:
        super().release()
        self.triple.release()


class CompressedMatrixRenderer(RasterRenderer):
    """``sloan-matrix`` from a PCA / VQ / CPCA form of the flattened n² × n² matrices (the
    lecture's CPCA for changing view, Sloan 2003).

    Per frame the CPU projects the light's SH onto every cluster's mean and basis matrices,
    P_kj = M_kj · L (n² RGB vectors each); the vertex shader (vertex_glossy.vert, GLOSSY_MODE 2
    with cpca.glsl) forms H = P_c0 + Σ_j w_j P_cj and shades it like the uncompressed matrix.
    Resident: cluster ids, weights and the K × (1 + n′) × n² RGB table on the GPU, means and
    bases on the CPU (:class:`~prtbench.transport.compress.buffers.CpcaBuffers`).
    """

    shader_dirs = (SHADER_DIR,)

    def __init__(self, scene, artifact: Artifact, *, sh_bands: int, width: int, height: int):
        self.model = compress_knobs.load_model(artifact.arrays, n_signals=scene.n_vertices)
        self.sh_bands = sh_bands
        n2 = sh_bands * sh_bands
        if self.model.dimension != n2 * n2:
            raise InvalidInputError(f"compressed matrices of dimension {self.model.dimension}; "
                                    f"expected {n2 * n2} for sh_bands={sh_bands}")
        super().__init__(scene, width=width, height=height, vertex_shader="vertex_glossy.vert",
                         fragment_shader="interpolated_radiance.frag",
                         defines={"SH_BANDS": sh_bands, "GLOSSY_MODE": MODE_MATRIX,
                                  "CPCA_CLUSTERS": self.model.n_clusters,
                                  "PCA_VECTORS": self.model.pca_vectors, "CPCA_OUTPUTS": n2},
                         extra_attributes=material_attributes(scene))
        self.cpca = CpcaBuffers(self.ctx, self.model, outputs=n2)
        self._resident = self.cpca.buffers()

    def light_operator(self, light):
        """rows (M, n⁴) -> (M, n²·3): each row as a matrix M_ki times the light's L_i (RGB)."""
        coeffs = light.sh(self.sh_bands).astype(np.float64)  # (n², 3)
        n2 = self.sh_bands**2
        return lambda rows: (rows.reshape(len(rows), n2, n2) @ coeffs).reshape(len(rows), -1)

    def _bind(self, view, light) -> None:
        self.cpca.bind(self.light_operator(light))

    def memory_bytes(self) -> int:
        return self.cpca.memory_bytes()
