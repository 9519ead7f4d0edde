"""Vertex PRT (Sloan, Kautz and Snyder 2002): diffuse transfer vectors at mesh vertices.

Precompute: the shadowed transfer T_i(p) = ∫ Y_i V max(n·ω, 0) dω at every vertex (and, with
``bounces`` > 0, Sloan's interreflected transfer, RGB because hit surfaces colour the light).
Render: the vertex shader evaluates B = kd/π · Σ_i T_i L_i per vertex and the rasteriser
interpolates it, so shadows are only as sharp as the mesh is fine: this is the method whose
tessellation dependence motivates transfer textures (PRTT §1).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from methods.common.materials import check_diffuse_constant_kd
from methods.vertex import SHADER_DIR
from prtbench.api import config as config_mod
from prtbench.api.config import knob, seed_knob
from prtbench.api.errors import InvalidInputError
from prtbench.api.method import Artifact, Method, register_method
from prtbench.render.ops import add_counts, raster_counts
from prtbench.render.raster import RasterRenderer
from prtbench.transport.bounce_transfer import compute_bounce_transfer
from prtbench.transport.compress import check_request
from prtbench.transport.compress import knobs as compress_knobs
from prtbench.transport.compress.buffers import CpcaBuffers
from prtbench.transport.transfer import compute_transfer


@dataclass(frozen=True)
class VertexConfig:
    """Knobs of the ``vertex`` method."""

    sh_bands: int = knob(5, "SH bands n (n² transfer coefficients per vertex).", low=1, high=8)
    rays_per_point: int = knob(512, "Visibility rays per vertex (cosine-weighted, stratified).",
                               low=1, high=1 << 20)
    bounces: int = knob(0, "Interreflection bounces baked into the transfer (Sloan 2002 §5).",
                        low=0, high=8)
    seed: int = seed_knob("Seed of the per-vertex random rotations of the ray pattern.")
    visibility: bool = knob(True, "Trace occlusion in the transfer. False: unshadowed transfer "
                                  "(V = 1, and no interreflection since no ray hits anything), the "
                                  "trivial image the regression gate must beat.")
    compress: str = compress_knobs.compress_knob()
    clusters: int | None = compress_knobs.clusters_knob()
    pca_vectors: int | None = compress_knobs.pca_vectors_knob()


def transfer_dimension(config: VertexConfig) -> int:
    """Floats of one vertex's transfer: n², or 3n² (RGB) with interreflection bounces."""
    return config.sh_bands**2 * (3 if config.bounces > 0 and config.visibility else 1)


@register_method("vertex")
class VertexPRT(Method):
    """Sloan 2002 diffuse PRT shaded in the vertex shader."""

    storage = "per-vertex"

    family = "SH PRT"

    verdict_grid = {"sh_bands": [3, 5]}

    Config = VertexConfig
    precompute_version = "1"
    #: Knobs along which accuracy and cost both grow (searched by ``prtbench advise``).
    main_knobs = ("sh_bands",)
    paper = ("Sloan, Kautz and Snyder 2002, Precomputed Radiance Transfer for Real-Time "
             "Rendering in Dynamic, Low-Frequency Lighting Environments (SIGGRAPH 2002): "
             "diffuse transfer vectors")
    profile_overrides = {
        "smoke": {"rays_per_point": 128, "sh_bands": 4},
        "quick": {"rays_per_point": 512},
        "paper": {"rays_per_point": 4096},
    }
    #: Under ``sky`` the smoke render of the 2-triangle ground is no better than its unshadowed
    #: render (18.5 vs 19.3 dB: per-vertex shadows need vertices); the sun's sharp shadows on
    #: a 32×32 ground make shadowing the measured difference (regress gate, issue #12).
    regression_case = {"scene": "plants", "variant": "diffuse", "light": "sun",
                       "scene_params": {"ground_subdivisions": 32}}

    @classmethod
    def cache_identity(cls, config: VertexConfig) -> dict[str, Any]:
        return compress_knobs.cache_identity(super().cache_identity(config))

    @classmethod
    def validate(cls, scene, config: VertexConfig) -> None:
        form = compress_knobs.resolve(config)
        if form is not None:

            check_request(n_signals=scene.n_vertices, dimension=transfer_dimension(config),
                          clusters=form.clusters, pca_vectors=form.pca_vectors,
                          max_bytes=config_mod.memory_budget(), what=f"vertices of scene '{scene.name}'")
        check_diffuse_constant_kd("vertex", scene)

    @classmethod
    def precompute(cls, scene, config: VertexConfig, *, progress: bool = True) -> Artifact:
        positions, normals, _, _ = scene.merged()
        transfer = compute_transfer(scene, positions, normals, bands=config.sh_bands,
                                    rays_per_point=config.rays_per_point, seed=config.seed,
                                    progress=progress, visibility=config.visibility)
        if config.bounces > 0 and config.visibility:
            transfer = compute_bounce_transfer(
                scene, positions, normals, vertex_transfer=transfer, bounces=config.bounces,
                rays_per_point=config.rays_per_point, seed=config.seed + 1, progress=progress)
        transfer = np.asarray(transfer, dtype=np.float32)
        meta = {"vertices": int(len(positions)), "sh_bands": config.sh_bands,
                "channels": 1 if transfer.ndim == 2 else 3}
        form = compress_knobs.resolve(config)
        if form is None:
            return Artifact("vertex", {"transfer": transfer}, meta)
        # Only the compressed form is cached (the transfer itself is cached by its own step).
        arrays, fit = compress_knobs.compress_signals(transfer.reshape(len(transfer), -1), form,
                                                      seed=config.seed, progress=progress)
        return Artifact("vertex", arrays, {**meta, **fit})

    @classmethod
    def renderer(cls, scene, artifact: Artifact, config: VertexConfig, *, width: int,
                 height: int) -> "VertexRenderer":
        if compress_knobs.is_compressed(artifact.arrays):
            return CompressedVertexRenderer(scene, artifact, config, width=width, height=height)
        return VertexRenderer(scene, artifact, config, width=width, height=height)

    @classmethod
    def op_counts(cls, config: VertexConfig, *, scene_vertices: int, scene_triangles: int,
                  covered_pixels: int, width: int, height: int, memory_bytes: int):
        """vertex_prt.vert: per vertex n² SSBO loads (RGB when bounces are baked) and an RGB
        madd each, then kd/π; interpolated_radiance.frag only interpolates the radiance (3 varyings)."""

        coeffs = config.sh_bands**2
        channels = 3 if config.bounces > 0 else 1
        per_vertex = {"madds": 3.0 * coeffs + 3.0, "fetches": float(coeffs * channels),
                      "bytes": 4.0 * coeffs * channels}
        form = compress_knobs.resolve(config)
        frame = {}
        if form is not None:
            # cpca.glsl: an id, n′ weights and 1 + n′ RGB table entries per vertex; the CPU
            # projects the light onto K·(1 + n′) rows of d floats per frame.
            n, k = form.pca_vectors, form.clusters
            fetches = float((k > 1) + n + 3 * (1 + n))
            per_vertex = {"madds": 3.0 * n + 3.0, "fetches": fetches, "bytes": 4.0 * fetches}
            frame = {"madds": 3.0 * k * (1 + n) * transfer_dimension(config)}
        return add_counts(frame,
            raster_counts(vertices=scene_vertices, triangles=scene_triangles,
                          pixels=covered_pixels, varyings=3, vertex_bytes=24),
            {key: value * scene_vertices for key, value in per_vertex.items()})


class VertexRenderer(RasterRenderer):
    """Per-vertex SH dot product; transfer vectors live in a shader storage buffer."""

    shader_dirs = (SHADER_DIR,)

    def __init__(self, scene, artifact: Artifact, config: VertexConfig, *, width: int, height: int):
        transfer = artifact.arrays["transfer"]
        channels = 1 if transfer.ndim == 2 else 3
        self.sh_bands = config.sh_bands
        super().__init__(scene, width=width, height=height, vertex_shader="vertex_prt.vert",
                         fragment_shader="interpolated_radiance.frag",
                         defines={"SH_COEFFS": config.sh_bands**2, "TRANSFER_CHANNELS": channels})
        # (V, n²[, 3]) float32, vertex-major: the shader reads transfer[v * n² * C + i * C + c].
        self.transfer_buffer = self.ctx.buffer(np.ascontiguousarray(transfer, np.float32).tobytes())
        self._resident = [self.transfer_buffer]
        self._resident_bytes = int(self.transfer_buffer.size)

    def _bind(self, view, light) -> None:
        self.transfer_buffer.bind_to_storage_buffer(0)
        coeffs = light.sh(self.sh_bands).astype(np.float32)  # (n², 3)
        self.program["light_sh"].write(np.ascontiguousarray(coeffs).tobytes())

    def memory_bytes(self) -> int:
        return self._resident_bytes


class CompressedVertexRenderer(RasterRenderer):
    """Vertex PRT from a PCA / VQ / CPCA form (Sloan 2003): per frame the CPU projects the
    light's SH onto each cluster's mean and basis; the vertex shader (vertex_prt.vert with
    cpca.glsl) adds the n′ weighted table entries of its cluster. Resident: cluster ids,
    weights and the K × (1 + n′) RGB table on the GPU, means and bases on the CPU."""

    shader_dirs = (SHADER_DIR,)

    def __init__(self, scene, artifact: Artifact, config: VertexConfig, *, width: int,
                 height: int):

        self.model = compress_knobs.load_model(artifact.arrays, n_signals=scene.n_vertices)
        self.sh_bands = config.sh_bands
        self.channels = transfer_dimension(config) // config.sh_bands**2
        if self.model.dimension != transfer_dimension(config):
            raise InvalidInputError(f"compressed transfer of dimension {self.model.dimension}; "
                                    f"expected {transfer_dimension(config)} for sh_bands="
                                    f"{config.sh_bands}, bounces={config.bounces}")
        super().__init__(scene, width=width, height=height, vertex_shader="vertex_prt.vert",
                         fragment_shader="interpolated_radiance.frag",
                         defines={"SH_COEFFS": config.sh_bands**2,
                                  "TRANSFER_CHANNELS": self.channels, "CPCA_CLUSTERS":
                                  self.model.n_clusters, "PCA_VECTORS": self.model.pca_vectors,
                                  "CPCA_OUTPUTS": 1})
        self.cpca = CpcaBuffers(self.ctx, self.model, outputs=1)
        self._resident = self.cpca.buffers()

    def light_operator(self, light):
        """rows (M, d) -> (M, 3): Σ_i T_i L_i (mono) or Σ_i T_ic L_ic (RGB transfer)."""
        coeffs = light.sh(self.sh_bands).astype(np.float64)  # (n², 3)
        if self.channels == 1:
            return coeffs
        return lambda rows: np.einsum("mic,ic->mc", rows.reshape(len(rows), -1, 3), coeffs)

    def _bind(self, view, light) -> None:
        self.cpca.bind(self.light_operator(light))

    def memory_bytes(self) -> int:
        return self.cpca.memory_bytes()
