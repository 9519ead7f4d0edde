"""Glossy vertex PRT: triple products (PRTT §3) and Sloan 2002 transfer matrices at vertices.

All three methods compute, per vertex in the vertex shader, the transferred incident radiance
H = SH projection of L·V·max(n·ω, 0) and shade it with the one Phong BRDF (DESIGN.md §4) by
``shade_transferred`` of ``prt_shading.glsl``: kd/π·√(4π)·H_0 plus the Phong lobe as a zonal
convolution evaluated along the mirror direction of the eye vector. The rasteriser
interpolates the resulting radiance (Gouraud), so glossy highlights and shadows are only as
sharp as the mesh.

* ``vertex-tp``: transfer vectors T (the diffuse ones of :func:`prtbench.transport.transfer.compute_transfer`)
  and the triple product H_k = Σ_ij Γ_ijk T_i L_j over the sparse Γ list (PRTT §3, "TP").
* ``vertex-tpfl``: the same T; the light is folded into M_ik = Σ_j Γ_ijk L_j once per light on
  the CPU, the shader does H_k = Σ_i T_i M_ik (PRTT §3, "TPFL"). Same images as ``vertex-tp``.
* ``sloan-matrix``: per vertex Sloan's glossy transfer matrix M_ki = ∫ Y_k Y_i V max(n·ω,0) dω
  and H = M·L. Unlike TP it does not truncate V·cos before multiplying by the light, so H is
  the exact projection of L_n·V·cos (L_n: the light's n-band part); it costs n⁴ floats per vertex.
  With ``bounces`` > 0 the matrices gain Sloan 2002 §6's interreflected light (glossy at the
  bounce, :mod:`methods.vertex.bounces`) and become RGB: 3n⁴ floats per vertex.

Materials must be constant per object (kd, ks, s); normal maps need a per-texel method.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from methods.common.materials import validate_constant_materials
from methods.vertex.bounces import bounce_matrices
from methods.vertex.glossy_renderer import (
    MODE_MATRIX,
    MODE_TP,
    MODE_TPFL,
    CompressedMatrixRenderer,
    GlossyVertexRenderer,
    format_size,
    storage_limit_message,
)
from prtbench.api.cache import cached_arrays, content_key
from prtbench.api.config import check_memory, knob, seed_knob
from prtbench.api.errors import InvalidInputError
from prtbench.api.method import Artifact, Method, register_method
from prtbench.render import gl, ops
from prtbench.transport.compress import check_request
from prtbench.transport.compress import knobs as compress_knobs
from prtbench.transport.parallel import map_chunks, single_threaded_blas
from prtbench.transport.ray_pattern import RayPattern
from prtbench.transport.raytrace import Tracer, offset_origins
from prtbench.transport.sh import eval_sh
from prtbench.transport.transfer import check_inputs, compute_transfer, point_chunks, progress_bar

_PROFILES = {
    "smoke": {"rays_per_point": 128, "sh_bands": 4},
    "quick": {"rays_per_point": 512},
    "paper": {"rays_per_point": 4096},
}


@dataclass(frozen=True)
class VertexGlossyConfig:
    """Knobs of ``vertex-tp`` and ``vertex-tpfl``."""

    sh_bands: int = knob(5, "SH bands n (n² transfer coefficients per vertex; Γ has O(n⁵) "
                            "non-zeros).", low=1, high=8)
    rays_per_point: int = knob(512, "Visibility rays per vertex (cosine-weighted, stratified).",
                               low=1, high=1 << 20)
    seed: int = seed_knob("Seed of the per-vertex random rotations of the ray pattern.")
    visibility: bool = knob(True, "Trace occlusion in the transfer. False: unshadowed transfer "
                                  "(V = 1), the trivial image the regression gate must beat.")


@dataclass(frozen=True)
class SloanMatrixConfig:
    """Knobs of ``sloan-matrix``."""

    sh_bands: int = knob(5, "SH bands n (an n² × n² transfer matrix per vertex).", low=1, high=8)
    rays_per_point: int = knob(512, "Visibility rays per vertex (cosine-weighted, stratified).",
                               low=1, high=1 << 20)
    seed: int = seed_knob("Seed of the per-vertex random rotations of the ray pattern.")
    max_bytes: int = knob(2 << 30, "Largest transfer-matrix buffer accepted (V · n⁴ · 4 bytes; "
                                   "with compress, the compressed form's stored bytes).",
                          low=1, high=1 << 40)
    visibility: bool = knob(True, "Trace occlusion in the transfer. False: unshadowed transfer "
                                  "(V = 1, and no interreflection since no ray hits anything), the "
                                  "trivial image the regression gate must beat.")
    bounces: int = knob(0, "Interreflection bounces baked into the matrices (Sloan 2002 §6: "
                           "the light other surfaces reflect, diffuse and Phong lobe); > 0 makes "
                           "them RGB (3n⁴ floats per vertex).", low=0, high=8)
    compress: str = compress_knobs.compress_knob()
    clusters: int | None = compress_knobs.clusters_knob()
    pca_vectors: int | None = compress_knobs.pca_vectors_knob()


# --- precompute -------------------------------------------------------------------------------

def _vertex_transfer(scene, config, *, progress: bool) -> np.ndarray:
    positions, normals, _, _ = scene.merged()
    return np.asarray(compute_transfer(scene, positions, normals, bands=config.sh_bands,
                                       rays_per_point=config.rays_per_point, seed=config.seed,
                                       progress=progress, visibility=config.visibility),
                      dtype=np.float32)


#: Scratch budget (bytes) of the per-ray SH values of one chunk of the matrix precompute.
_MATRIX_SCRATCH_BYTES = 64 << 20


def compute_transfer_matrices(scene, points: np.ndarray, normals: np.ndarray, *, bands: int,
                              rays_per_point: int, seed: int = 0, progress: bool = True,
                              visibility: bool = True) -> np.ndarray:
    """Sloan's shadowed glossy transfer matrices M_ki(p) = ∫ Y_k Y_i V(p, ω) max(n·ω, 0) dω.

    Same rays as :func:`prtbench.transport.transfer.compute_transfer` for the same ``seed`` (its
    :class:`~prtbench.transport.ray_pattern.RayPattern` and origin offset), so the first row is the transfer
    vector over √(4π): M_0i = T_i / √(4π) up to rounding. Estimator: M ≈ π/M_r Σ_j V_j y_j y_jᵀ
    over M_r cosine-weighted directions; M is symmetric.

    Parameters
    ----------
    scene : Scene
        Occluders (all objects).
    points, normals : ndarray, shape (N, 3)
    bands : int
        SH bands n.
    rays_per_point : int
    seed : int
    progress : bool
    visibility : bool
        Trace occlusion (default); ``False`` sets V = 1 (unshadowed matrices, no ray traced).

    Returns
    -------
    ndarray, shape (N, n², n²), float32
    """

    p, n = check_inputs(points, normals, bands, rays_per_point)
    m, n2 = int(rays_per_point), bands * bands
    tracer = Tracer.from_scene(scene)
    pattern = RayPattern(len(p), m, seed)
    origins_all = offset_origins(p, n, diagonal=tracer.diagonal).astype(np.float32)
    out = np.zeros((len(p), n2, n2), dtype=np.float32)
    chunk_points = max(1, _MATRIX_SCRATCH_BYTES // (8 * m * n2))
    # Small products: OpenBLAS's helper threads only contend with each other (20× slower).
    def chunk(sl: slice) -> np.ndarray:
        frames = pattern.frames(n[sl], sl)
        dirs = pattern.world_directions(frames, sl)  # (c, M, 3) float32
        origins = np.repeat(origins_all[sl], m, axis=0)
        visible = (~tracer.occluded(origins, dirs.reshape(-1, 3)).reshape(-1, m) if visibility
                   else np.ones((sl.stop - sl.start, m), dtype=bool))
        y = eval_sh(dirs.reshape(-1, 3).astype(np.float64), bands).reshape(-1, m, n2)
        weighted = y * (visible[..., None] * (np.pi / m))
        # One (n² × M)·(M × n²) BLAS product per point.
        return np.stack([w.T @ yp for w, yp in zip(weighted, y)]).astype(np.float32)

    # Chunks on the precompute threads (prtbench.transport.parallel.map_chunks): fixed boundaries and
    # per-point rays, so every thread count gives the same bits.
    chunks = point_chunks(len(p), m, chunk_points)
    with progress_bar(len(p), f"transfer matrices {scene.name}", progress) as bar, \
            single_threaded_blas():
        for values, sl in zip(map_chunks(chunk, chunks), chunks):
            out[sl] = values
            bar.update(sl.stop - sl.start)
    return out


def matrix_bytes(n_vertices: int, bands: int, *, channels: int = 1) -> int:
    """Bytes of the float32 (V, n², n²) transfer-matrix buffer (× 3 channels with bounces)."""
    return int(n_vertices) * bands**4 * 4 * int(channels)


def matrix_channels(config) -> int:
    """3 when ``config`` bakes interreflection (RGB matrices), else 1."""
    return 3 if getattr(config, "bounces", 0) > 0 and config.visibility else 1


# --- methods ----------------------------------------------------------------------------------

class _GlossyVertexMethod(Method):
    """Shared validation and renderer construction of the glossy vertex methods."""

    storage = "per-vertex"

    family = "SH PRT"

    profile_overrides = _PROFILES
    #: As for ``vertex``: a subdivided ground under the sun, where shadows are what is measured.
    regression_case = {"variant": "glossy", "light": "sun",
                       "scene_params": {"ground_subdivisions": 32}}
    #: Knobs along which accuracy and cost both grow (searched by ``prtbench advise``).
    main_knobs = ("sh_bands",)
    #: On a diffuse scene these render what ``vertex`` renders, at a higher cost.
    glossy_only = True
    _mode: int

    @classmethod
    def validate(cls, scene, config) -> None:
        validate_constant_materials(cls.name, scene)

    @classmethod
    def renderer(cls, scene, artifact: Artifact, config, *, width: int,
                 height: int) -> "GlossyVertexRenderer":
        if compress_knobs.is_compressed(artifact.arrays):
            return CompressedMatrixRenderer(scene, artifact, sh_bands=config.sh_bands,
                                            width=width, height=height)
        return GlossyVertexRenderer(scene, artifact, mode=cls._mode, sh_bands=config.sh_bands,
                                    width=width, height=height)

    @classmethod
    def op_counts(cls, config, *, scene_vertices: int, scene_triangles: int,
                  covered_pixels: int, width: int, height: int, memory_bytes: int):
        """vertex_glossy.vert per vertex: H from n² SSBO loads by the triple product over the Γ
        list (vertex-tp), the n² × n² TPFL matrix (vertex-tpfl) or n⁴ loads of the transfer
        matrix and an RGB madd each (sloan-matrix); then Phong shading of H towards the eye
        (shade_transferred). The fragment stage interpolates the radiance (3 varyings)."""

        n = config.sh_bands
        form = compress_knobs.resolve(config) if cls._mode == MODE_MATRIX else None
        cpu = {}
        if form is not None:
            # cpca.glsl: per vertex an id, n′ weights and (1 + n′)·n² RGB table entries, n′·n²
            # RGB madds; per frame the CPU projects K·(1 + n′) matrices onto the light.
            k, m = form.clusters, form.pca_vectors
            fetches = float((k > 1) + m + 3 * (1 + m) * n * n)
            product = {"madds": 3.0 * m * n * n, "fetches": fetches, "bytes": 4.0 * fetches}
            cpu = {"madds": 3.0 * k * (1 + m) * n**4}
        elif cls._mode == MODE_MATRIX:
            # RGB matrices (bounces) load three floats per (k, i), one madd each.
            c = matrix_channels(config)
            product = {"madds": 3.0 * n**4, "fetches": float(c * n**4), "bytes": 4.0 * c * n**4}
        else:
            loads = {"madds": 0.0, "fetches": float(n * n), "bytes": 4.0 * n * n}
            product = (ops.triple_product_counts(n) if cls._mode == MODE_TP
                       else {"madds": ops.tpfl_product_madds(n)})
            product = ops.add_counts(loads, product)
        shade = {"madds": ops.shade_transferred_madds(n) + 3 + 2 * ops.TRANSCENDENTAL_MADDS}
        per_vertex = ops.add_counts(product, shade)
        frame = {"bytes": ops.gamma_bytes(n) if cls._mode == MODE_TP else 0.0}
        return ops.add_counts(cpu,
            ops.raster_counts(vertices=scene_vertices, triangles=scene_triangles,
                               pixels=covered_pixels, varyings=3, vertex_bytes=52),
            ops.scaled(per_vertex, scene_vertices), frame)


class _TransferVectorMethod(_GlossyVertexMethod):
    Config = VertexGlossyConfig
    precompute_version = "1"

    @classmethod
    def precompute(cls, scene, config: VertexGlossyConfig, *, progress: bool = True) -> Artifact:
        transfer = _vertex_transfer(scene, config, progress=progress)
        return Artifact(cls.name, {"transfer": transfer},
                        {"vertices": int(len(transfer)), "sh_bands": config.sh_bands})


@register_method("vertex-tp")
class VertexTP(_TransferVectorMethod):
    """Transfer vectors at vertices, glossy shading via the SH triple product (Γ list)."""

    paper = ("Sirikonda, KT and Narayanan 2022, PRTT (precomputed radiance transfer "
             "textures), §3 triple product (TP), at vertices")
    _mode = MODE_TP


@register_method("vertex-tpfl")
class VertexTPFL(_TransferVectorMethod):
    """Transfer vectors at vertices, glossy shading via the fixed-light triple-product matrix."""

    paper = ("Sirikonda, KT and Narayanan 2022, PRTT (precomputed radiance transfer "
             "textures), §3 fixed-light triple product (TPFL), at vertices")
    light_dependence = "fixed-light"
    light_dependence_why = "folds the light into the TPFL matrix M_ik = Σ_j Γ_ijk L_j once per light"
    _mode = MODE_TPFL


@register_method("sloan-matrix")
class SloanMatrix(_GlossyVertexMethod):
    """Sloan 2002 glossy transfer matrices at vertices (n² × n² per vertex), H = M·L."""

    Config = SloanMatrixConfig
    precompute_version = "1"
    paper = ("Sloan, Kautz and Snyder 2002, Precomputed Radiance Transfer for Real-Time "
             "Rendering in Dynamic, Low-Frequency Lighting Environments (SIGGRAPH 2002): "
             "glossy transfer matrices")
    _mode = MODE_MATRIX
    #: The CPCA form of the matrices (Sloan 2003) is regressed as ``sloan-matrix:cpca``.
    regression_variants = {"cpca": {"compress": "cpca", "clusters": 16, "pca_vectors": 4}}

    @classmethod
    def cache_identity(cls, config: SloanMatrixConfig) -> dict:
        identity = compress_knobs.cache_identity(super().cache_identity(config))
        if identity.get("bounces") == 0:
            identity.pop("bounces")  # the knob's default keeps the existing cache keys
        return identity

    @classmethod
    def validate(cls, scene, config: SloanMatrixConfig) -> None:
        super().validate(scene, config)
        channels = matrix_channels(config)
        size = matrix_bytes(scene.n_vertices, config.sh_bands, channels=channels)
        form = compress_knobs.resolve(config)
        if form is not None and channels > 1:
            raise InvalidInputError(
                f"method 'sloan-matrix' bounces={config.bounces} with compress="
                f"{config.compress}: the compressed forms hold grey matrices only; accepted: "
                "bounces=0 with compress, or compress=none with bounces")
        if form is not None:

            # The matrices are computed in host memory before they are compressed; only the
            # compressed form is kept (and limited by max_bytes).
            check_memory(f"method 'sloan-matrix' sh_bands={config.sh_bands} on "
                         f"{scene.n_vertices} vertices (uncompressed matrices before compress)",
                         2 * size, accepted="fewer sh_bands or a coarser mesh")
            check_request(n_signals=scene.n_vertices, dimension=config.sh_bands**4,
                          clusters=form.clusters, pca_vectors=form.pca_vectors,
                          max_bytes=config.max_bytes, what=f"vertices of scene '{scene.name}'")
            return
        if size > config.max_bytes:
            # The limit is stated in vertices (what the buffer grows with); the scene's
            # triangles are named too, since that is the count an asset tool shows.
            limit = config.max_bytes // matrix_bytes(1, config.sh_bands, channels=channels)
            fit = max((b for b in range(1, config.sh_bands) if
                       matrix_bytes(scene.n_vertices, b, channels=channels) <= config.max_bytes),
                      default=None)
            floats = f"{channels} × " if channels > 1 else ""
            hint = f"use sh_bands={fit} or fewer, a coarser mesh" if fit else "use a coarser mesh"
            raise InvalidInputError(
                f"scene '{scene.name}' has {scene.n_triangles} triangles / {scene.n_vertices} "
                f"vertices, over sloan-matrix's limit of {limit} vertices at "
                f"sh_bands={config.sh_bands} (max_bytes={format_size(config.max_bytes)} of "
                f"transfer matrices, V × {floats}{config.sh_bands**4} floats; this scene needs "
                f"{format_size(size)}); {hint}, or raise max_bytes")
        # The renderer uploads the matrices as one shader storage block: refuse here, before
        # the precompute (45 min at 10⁶ triangles on 2 cores), what it would refuse anyway.

        try:
            limit = gl.storage_block_limit()
        except gl.GLUnavailableError:  # no GL here: the renderer checks where it runs
            limit = 0
        if limit and size > limit:
            raise InvalidInputError(storage_limit_message(
                "matrices", size, limit, rgb=channels > 1,
                what=f"scene '{scene.name}' ({scene.n_vertices} vertices, sh_bands="
                     f"{config.sh_bands}): its "))

    @classmethod
    def precompute(cls, scene, config: SloanMatrixConfig, *, progress: bool = True) -> Artifact:
        positions, normals, _, _ = scene.merged()
        form = compress_knobs.resolve(config)
        meta = {"vertices": int(len(positions)), "sh_bands": config.sh_bands}

        def compute() -> dict[str, np.ndarray]:
            matrices = compute_transfer_matrices(
                scene, positions, normals, bands=config.sh_bands,
                rays_per_point=config.rays_per_point, seed=config.seed, progress=progress,
                visibility=config.visibility)
            if matrix_channels(config) > 1:

                matrices = bounce_matrices(scene, matrices, bounces=config.bounces,
                                           rays_per_point=config.rays_per_point,
                                           seed=config.seed, progress=progress)
            return {"matrices": matrices}

        if matrix_channels(config) > 1:
            meta["bounces"] = config.bounces

        if form is None:
            return Artifact(cls.name, compute(), meta)
        # Compressed forms share one cached matrix precompute (credited to their precompute
        # time), and only the compressed form is stored in the artifact.

        key = content_key("sloan-matrices", cls.precompute_version, scene.content_hash(),
                          config.sh_bands, config.rays_per_point, config.seed, config.visibility)
        matrices = cached_arrays("transfer-matrices", key, compute)["matrices"]
        arrays, fit = compress_knobs.compress_signals(
            matrices.reshape(len(matrices), -1), form, seed=config.seed,
            max_bytes=config.max_bytes, progress=progress)
        return Artifact(cls.name, arrays, {**meta, **fit})


