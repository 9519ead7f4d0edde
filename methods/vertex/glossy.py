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

from methods.vertex import SHADER_DIR
from prtbench.api.config import knob, seed_knob
from prtbench.api.errors import InvalidInputError
from prtbench.api.method import Artifact, Method, register_method
from prtbench.render import prt_shading as _triple
from prtbench.render.raster import RasterRenderer
from prtbench.transport.compress import knobs as compress_knobs

#: GLSL selector of how the vertex shader forms H (``GLOSSY_MODE`` in vertex_glossy.vert).
MODE_TP, MODE_TPFL, MODE_MATRIX = 0, 1, 2

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


def _validate_materials(method: str, scene) -> None:
    for obj in scene.objects:
        material = obj.material
        if material.is_textured:
            raise InvalidInputError(
                f"method '{method}' takes constant kd, ks and shininess per object; '{obj.name}' "
                f"in scene '{scene.name}' is textured; use a transfer-texture method")
        if material.normal_map is not None:
            raise InvalidInputError(
                f"method '{method}' shades per vertex and cannot apply the normal map of "
                f"'{obj.name}' in scene '{scene.name}'; use a transfer-texture method or a scene "
                "without normal maps")


def material_attributes(scene) -> dict[str, np.ndarray]:
    """Per-vertex ks (V, 3) and shininess (V, 1) float32 in merged order (kd is added by
    :class:`RasterRenderer`)."""
    ks = np.concatenate([np.broadcast_to(np.asarray(o.material.ks, np.float32),
                                         (o.mesh.n_vertices, 3)) for o in scene.objects])
    shininess = np.concatenate([np.full((o.mesh.n_vertices, 1), o.material.shininess, np.float32)
                                for o in scene.objects])
    return {"ks": ks, "shininess": shininess}


# --- precompute -------------------------------------------------------------------------------

def _vertex_transfer(scene, config, *, progress: bool) -> np.ndarray:
    from prtbench.transport.transfer import compute_transfer

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
    :class:`~prtbench.transport.transfer.RayPattern` and origin offset), so the first row is the transfer
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
    from prtbench.transport.parallel import map_chunks
    from prtbench.transport.raytrace import Tracer, offset_origins
    from prtbench.transport.sh import eval_sh
    from prtbench.transport.transfer import (
        RayPattern,
        _check_inputs,
        _chunks,
        _progress,
        _single_threaded_blas,
    )

    p, n = _check_inputs(points, normals, bands, rays_per_point)
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
    chunks = _chunks(len(p), m, chunk_points)
    with _progress(len(p), f"transfer matrices {scene.name}", progress) as bar, \
            _single_threaded_blas():
        for values, sl in zip(map_chunks(chunk, chunks), chunks):
            out[sl] = values
            bar.update(sl.stop - sl.start)
    return out


def _format_bytes(size: int) -> str:
    if size >= 2**30:
        return f"{size / 2**30:.2f} GiB"
    return f"{size / 2**20:.1f} MiB" if size >= 2**20 else f"{size / 2**10:.0f} KiB"


def matrix_bytes(n_vertices: int, bands: int, *, channels: int = 1) -> int:
    """Bytes of the float32 (V, n², n²) transfer-matrix buffer (× 3 channels with bounces)."""
    return int(n_vertices) * bands**4 * 4 * int(channels)


def matrix_channels(config) -> int:
    """3 when ``config`` bakes interreflection (RGB matrices), else 1."""
    return 3 if getattr(config, "bounces", 0) > 0 and config.visibility else 1


# --- methods ----------------------------------------------------------------------------------

class _GlossyVertexMethod(Method):
    """Shared validation and renderer construction of the glossy vertex methods."""

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
        _validate_materials(cls.name, scene)

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
        from prtbench.tradeoff import cost

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
            product = (cost.triple_product_counts(n) if cls._mode == MODE_TP
                       else {"madds": cost.tpfl_product_madds(n)})
            product = cost.add_counts(loads, product)
        shade = {"madds": cost.shade_transferred_madds(n) + 3 + 2 * cost.TRANSCENDENTAL_MADDS}
        per_vertex = cost.add_counts(product, shade)
        frame = {"bytes": cost.gamma_bytes(n) if cls._mode == MODE_TP else 0.0}
        return cost.add_counts(cpu,
            cost.raster_counts(vertices=scene_vertices, triangles=scene_triangles,
                               pixels=covered_pixels, varyings=3, vertex_bytes=52),
            cost.scaled(per_vertex, scene_vertices), frame)


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
            from prtbench.api.config import check_memory
            from prtbench.transport.compress import check_request

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
                f"sh_bands={config.sh_bands} (max_bytes={_format_bytes(config.max_bytes)} of "
                f"transfer matrices, V × {floats}{config.sh_bands**4} floats; this scene needs "
                f"{_format_bytes(size)}); {hint}, or raise max_bytes")
        # The renderer uploads the matrices as one shader storage block: refuse here, before
        # the precompute (45 min at 10⁶ triangles on 2 cores), what it would refuse anyway.
        from prtbench.render import gl

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
                from methods.vertex.bounces import bounce_matrices

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
        from prtbench.api.cache import cached_arrays, content_key

        key = content_key("sloan-matrices", cls.precompute_version, scene.content_hash(),
                          config.sh_bands, config.rays_per_point, config.seed, config.visibility)
        matrices = cached_arrays("transfer-matrices", key, compute)["matrices"]
        arrays, fit = compress_knobs.compress_signals(
            matrices.reshape(len(matrices), -1), form, seed=config.seed,
            max_bytes=config.max_bytes, progress=progress)
        return Artifact(cls.name, arrays, {**meta, **fit})


# --- renderer ---------------------------------------------------------------------------------

def storage_limit_message(key: str, nbytes: int, limit: int, *, rgb: bool, what: str = "") -> str:
    """The one-line refusal of a per-vertex buffer over the GL's shader storage block limit."""
    return (f"{what}{key} buffer of {_format_bytes(nbytes)} exceeds this GL's shader storage "
            f"block limit of {_format_bytes(limit)}; use fewer sh_bands or a coarser mesh"
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
        from prtbench.render import gl

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
        from prtbench.transport.compress.buffers import CpcaBuffers

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
