"""``factored-brdf``: PRT for changing view with an in-out factored BRDF (Wang et al. 2004,
Sloan 2004; the lecture's "Factored BRDFs").

Each object's cosine-weighted Phong BRDF (DESIGN.md §4) is factored into J separable terms,
ρ(ωi, ωo) ≈ Σ_j g_j(ωo) h_j(ωi), by the solid-angle-weighted SVD of the BRDF sampled on two
hemisphere grids in the vertex's local frame (:mod:`prtbench.transport.compress.factor`). Then the
outgoing radiance towards ωo is

    B(p, ωo) = ∫ L V ρ dω ≈ Σ_j g_j(ωo) · Σ_i T^j_i(p) L_i,   T^j_i(p) = ∫ Y_i V h_j dω,

so each vertex stores J view-independent SH transfer vectors T^j (J·n² floats instead of the
n⁴ of Sloan's glossy transfer matrix) and the vertex shader combines the J light dot products
with the outgoing factors g_j looked up at the current view (a texture per material and term).
The radiance is interpolated across triangles (Gouraud), as for the other vertex methods.

Local frame: (t1, t2, n) = ``prtbench.transport.ray_pattern.tangent_frames(n, 0)`` per vertex, passed to
the shader as attributes, so precompute and render use the same tangents. The transfer reuses
the diffuse transfer's rays (:class:`~prtbench.transport.ray_pattern.RayPattern`, same seed: the same
directions) with the weight h̃_j(ω) = h_j/cos θ looked up bilinearly in the incoming table.

What limits it (the lecture's critique, "only less glossy materials"): a Phong lobe of large
exponent s needs many terms; the factorization error at fixed J grows with s.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from methods.common.materials import validate_constant_materials
from methods.factored_brdf import SHADER_DIR
from prtbench.api.config import knob, seed_knob
from prtbench.api.errors import InvalidInputError
from prtbench.api.method import Artifact, Method, register_method
from prtbench.render import ops
from prtbench.render.raster import RasterRenderer
from prtbench.transport.compress.factor import HemisphereGrid, bilinear_lookup, factor_brdf
from prtbench.transport.parallel import map_chunks, single_threaded_blas
from prtbench.transport.ray_pattern import RayPattern, tangent_frames
from prtbench.transport.raytrace import Tracer, offset_origins
from prtbench.transport.sh import eval_sh
from prtbench.transport.transfer import check_inputs, point_chunks, progress_bar

_PROFILES = {
    "smoke": {"rays_per_point": 128, "sh_bands": 4, "brdf_resolution": 8},
    "quick": {"rays_per_point": 512},
    "paper": {"rays_per_point": 4096, "brdf_resolution": 16},
}

#: Scratch budget (bytes) of the per-ray SH values of one chunk of the transfer.
_SCRATCH_BYTES = 64 << 20


@dataclass(frozen=True)
class FactoredBrdfConfig:
    """Knobs of ``factored-brdf``."""

    terms: int = knob(4, "Separable BRDF terms J per material (J SH transfer vectors per "
                         "vertex); at most the sampled BRDF's rank (1 for a diffuse material).",
                      low=1, high=8)
    sh_bands: int = knob(5, "SH bands n of the light and of each term's transfer.", low=1,
                         high=8)
    brdf_resolution: int = knob(
        12, "θ rows R of the outgoing-factor tables (R × 4R over the hemisphere); the incoming "
            "tables, sampled for the SVD and the transfer, have 2R × 8R.", low=2, high=16)
    rays_per_point: int = knob(512, "Visibility rays per vertex (cosine-weighted, stratified).",
                               low=1, high=1 << 20)
    seed: int = seed_knob("Seed of the per-vertex random rotations of the ray pattern.")
    visibility: bool = knob(True, "Trace occlusion in the transfer. False: unshadowed transfer "
                                  "(V = 1), the trivial image the regression gate must beat.")


def grids(config: FactoredBrdfConfig):
    """(outgoing grid, incoming grid) of ``config``."""

    r = config.brdf_resolution
    return HemisphereGrid(r, 4 * r), HemisphereGrid(2 * r, 8 * r)


def _material_key(material) -> tuple:
    return (tuple(float(c) for c in material.kd), tuple(float(c) for c in material.ks),
            float(material.shininess))


def scene_materials(scene) -> tuple[list, np.ndarray]:
    """(distinct materials, (V,) int32 index of each vertex's material, merged order)."""
    keys, index, per_vertex = [], {}, []
    for obj in scene.objects:
        key = _material_key(obj.material)
        if key not in index:
            index[key] = len(keys)
            keys.append((key, obj.material))
        per_vertex.append(np.full(obj.mesh.n_vertices, index[key], np.int32))
    return [m for _, m in keys], np.concatenate(per_vertex)


def brdf_frames(normals: np.ndarray) -> np.ndarray:
    """(V, 3, 3) float64 local frames (rows t1, t2, n) in which the BRDF is factored."""

    n = np.asarray(normals, np.float64)
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    return tangent_frames(n, np.zeros(len(n)))


def factored_transfer(scene, points: np.ndarray, normals: np.ndarray, *, incoming: np.ndarray,
                      material_of_point: np.ndarray, in_grid, bands: int, rays_per_point: int,
                      seed: int = 0, progress: bool = True, visibility: bool = True
                      ) -> np.ndarray:
    """T^j_i(p) = ∫ Y_i(ω) V(p, ω) h_j(ω) dω for every point and term.

    Estimator: the cosine-weighted rays of :func:`prtbench.transport.transfer.compute_transfer` (same
    seed: same directions), T^j_i ≈ π/M Σ_r V_r Y_i(ω_r) h̃_j(ω_r) with h̃_j = h_j / cos θ
    looked up bilinearly in the point's material's incoming table, in the frame
    :func:`brdf_frames`. With h̃ = 1 this is the diffuse transfer vector.

    Parameters
    ----------
    points, normals : ndarray, shape (N, 3)
    incoming : ndarray, shape (materials, J, rows, cols)
        h̃_j tables on ``in_grid``.
    material_of_point : ndarray, shape (N,), int
    in_grid : HemisphereGrid
    bands, rays_per_point, seed, progress, visibility
        As for :func:`~prtbench.transport.transfer.compute_transfer`.

    Returns
    -------
    ndarray, shape (N, J, n²), float32
    """

    p, n = check_inputs(points, normals, bands, rays_per_point)
    m, n2, terms = int(rays_per_point), bands * bands, incoming.shape[1]
    material_of_point = np.asarray(material_of_point)
    tracer = Tracer.from_scene(scene)
    pattern = RayPattern(len(p), m, seed)
    frames0 = brdf_frames(n)
    origins_all = offset_origins(p, n, diagonal=tracer.diagonal).astype(np.float32)
    out = np.zeros((len(p), terms, n2), dtype=np.float32)

    def chunk(sl: slice) -> np.ndarray:
        dirs = pattern.world_directions(pattern.frames(n[sl], sl), sl)  # (c, M, 3) float32
        count = sl.stop - sl.start
        visible = (~tracer.occluded(np.repeat(origins_all[sl], m, axis=0),
                                    dirs.reshape(-1, 3)).reshape(-1, m) if visibility
                   else np.ones((count, m), dtype=bool))
        world = dirs.astype(np.float64)
        local = np.einsum("pab,pmb->pma", frames0[sl], world)  # (c, M, 3) in the BRDF frame
        weight = np.empty((count, m, terms))
        materials = material_of_point[sl]
        for k in np.unique(materials):
            rows = np.flatnonzero(materials == k)
            weight[rows] = bilinear_lookup(incoming[k], local[rows].reshape(-1, 3),
                                           in_grid).reshape(len(rows), m, terms)
        weight *= visible[..., None] * (np.pi / m)
        y = eval_sh(world.reshape(-1, 3), bands).reshape(count, m, n2)
        return np.einsum("pmj,pmi->pji", weight, y).astype(np.float32)

    chunks = point_chunks(len(p), m, max(1, _SCRATCH_BYTES // (8 * m * (n2 + terms + 3))))
    with progress_bar(len(p), f"factored transfer {scene.name}", progress) as bar, \
            single_threaded_blas():
        for values, sl in zip(map_chunks(chunk, chunks), chunks):
            out[sl] = values
            bar.update(sl.stop - sl.start)
    return out


@register_method("factored-brdf")
class FactoredBrdf(Method):
    """Factored BRDF (J separable terms), J SH transfer vectors per vertex, view per vertex."""

    storage = "per-vertex"

    family = "SH PRT"

    Config = FactoredBrdfConfig
    precompute_version = "3"  # 2: the s = 0 Phong lobe is a hemisphere about r; 3: one-thread SVD
    paper = ("Wang, Tran and Luebke 2004, All-Frequency Relighting of Non-Diffuse Objects using "
             "Separable BRDF Approximation (EGSR 2004), with SH transfer as in Sloan 2004; the "
             "lecture's \"Factored BRDFs\"")
    profile_overrides = _PROFILES
    #: As for the glossy vertex methods: plants glossy on a subdivided ground under the sun.
    regression_case = {"variant": "glossy", "light": "sun",
                       "scene_params": {"ground_subdivisions": 32}}
    main_knobs = ("sh_bands", "terms")
    #: On a diffuse scene (J = 1) it renders what ``vertex`` renders, at a higher cost.
    glossy_only = True

    @classmethod
    def validate(cls, scene, config: FactoredBrdfConfig) -> None:
        validate_constant_materials(cls.name, scene)
        materials, _ = scene_materials(scene)
        if config.terms > 1 and not any(max(m.ks) > 0 for m in materials):
            # Every material is diffuse: ρ = kd/π·cos θi has rank exactly 1.
            raise InvalidInputError(
                f"terms={config.terms} on scene '{scene.name}', whose materials are all diffuse "
                "(ks = 0): the sampled BRDF has rank 1; accepted: terms=1")

    @classmethod
    def factor(cls, scene, config: FactoredBrdfConfig):
        """(per-material :class:`~prtbench.transport.compress.factor.FactoredBrdf` with min(J, rank)
        terms, (V,) material index of each vertex)."""

        out_grid, in_grid = grids(config)
        materials, of_vertex = scene_materials(scene)
        factors = [factor_brdf(m.kd, m.ks, m.shininess, terms=config.terms, out_grid=out_grid,
                               in_grid=in_grid, name=m.name, at_most=True) for m in materials]
        top = max(f.rank for f in factors)
        if config.terms > top:
            # A glossy material of rank 1: its lobe is narrower than the tables' cells (or
            # s = 0, a constant lobe), so the samples see only the diffuse-like part.
            hint = (" (a lobe narrower than the BRDF tables' cells is not sampled: a higher "
                    "brdf_resolution may resolve it)" if top == 1 and any(
                        max(m.ks) > 0 and m.shininess > 0 for m in materials) else "")
            raise InvalidInputError(f"terms={config.terms} on scene '{scene.name}', whose "
                                    f"sampled BRDFs have rank at most {top}; accepted: terms "
                                    f"1 to {top}{hint}")
        return factors, of_vertex

    @classmethod
    def precompute(cls, scene, config: FactoredBrdfConfig, *, progress: bool = True) -> Artifact:
        clock = time.perf_counter()
        factors, of_vertex = cls.factor(scene, config)
        factor_s = time.perf_counter() - clock
        out_grid, in_grid = grids(config)
        j = config.terms
        # Materials with a lower rank than J get zero terms (g = h = 0): one layout per vertex.
        outgoing = np.zeros((len(factors), j, 3, out_grid.rows, out_grid.cols), np.float32)
        incoming = np.zeros((len(factors), j, in_grid.rows, in_grid.cols))
        for k, f in enumerate(factors):
            outgoing[k, :f.terms] = f.outgoing
            incoming[k, :f.terms] = f.incoming
        positions, normals, _, _ = scene.merged()
        transfer = factored_transfer(
            scene, positions, normals, incoming=incoming, material_of_point=of_vertex,
            in_grid=in_grid, bands=config.sh_bands, rays_per_point=config.rays_per_point,
            seed=config.seed, progress=progress, visibility=config.visibility)
        meta = {"vertices": int(len(positions)), "sh_bands": config.sh_bands, "terms": j,
                "materials": [m.name for m in scene_materials(scene)[0]],
                "material_terms": [f.terms for f in factors],
                "material_ranks": [f.rank for f in factors],
                "factor_error": [f.relative_error() for f in factors], "factor_s": factor_s}
        return Artifact(cls.name, {"transfer": transfer, "outgoing": outgoing,
                                   "material_of_vertex": of_vertex}, meta)

    @classmethod
    def renderer(cls, scene, artifact: Artifact, config: FactoredBrdfConfig, *, width: int,
                 height: int) -> "FactoredBrdfRenderer":
        return FactoredBrdfRenderer(scene, artifact, sh_bands=config.sh_bands, width=width,
                                    height=height)

    @classmethod
    def op_counts(cls, config: FactoredBrdfConfig, *, scene_vertices: int, scene_triangles: int,
                  covered_pixels: int, width: int, height: int, memory_bytes: int):
        """factored_brdf.vert per vertex: J·n² SSBO loads and RGB madds (the light dot
        products), the view's local angles (acos, atan) and J bilinear RGB lookups of g_j and
        RGB madds. The fragment stage interpolates the radiance (3 varyings)."""

        j, n2 = config.terms, config.sh_bands**2
        fetches = float(j * n2 + j)
        per_vertex = {"madds": 3.0 * j * n2 + 3.0 * j + 12 + 2 * ops.TRANSCENDENTAL_MADDS,
                      "fetches": fetches, "bytes": 4.0 * j * n2 + 4 * 12.0 * j}
        return ops.add_counts(
            ops.raster_counts(vertices=scene_vertices, triangles=scene_triangles,
                               pixels=covered_pixels, varyings=3, vertex_bytes=64),
            ops.scaled(per_vertex, scene_vertices))


class FactoredBrdfRenderer(RasterRenderer):
    """Per vertex Σ_j g_j(ωo) (T^j · L), Gouraud-interpolated.

    Resident: the transfer buffer (V·J·n² float32, binding 0) and the outgoing-factor texture
    array (materials·J layers of R × 4R RGB float32).
    """

    shader_dirs = (SHADER_DIR,)

    def __init__(self, scene, artifact: Artifact, *, sh_bands: int, width: int, height: int):
        transfer = np.ascontiguousarray(artifact.arrays["transfer"], np.float32)
        outgoing = np.asarray(artifact.arrays["outgoing"], np.float32)
        of_vertex = np.asarray(artifact.arrays["material_of_vertex"], np.int32)
        n2 = sh_bands * sh_bands
        if transfer.ndim != 3 or transfer.shape[0] != scene.n_vertices or transfer.shape[2] != n2:
            raise InvalidInputError(f"artifact 'transfer' has shape {transfer.shape}; expected "
                                    f"({scene.n_vertices}, J, {n2}) for scene '{scene.name}' "
                                    f"with sh_bands={sh_bands}")
        materials, terms, _, rows, cols = outgoing.shape
        self.sh_bands, self.terms = sh_bands, terms
        _, normals, _, _ = scene.merged()
        frames = brdf_frames(normals).astype(np.float32)
        super().__init__(scene, width=width, height=height, vertex_shader="factored_brdf.vert",
                         fragment_shader="interpolated_radiance.frag",
                         defines={"SH_BANDS": sh_bands, "TERMS": terms},
                         extra_attributes={"tangent": frames[:, 0], "bitangent": frames[:, 1],
                                           "material": of_vertex.astype(np.float32)[:, None]})
        self.transfer_buffer = self.ctx.buffer(transfer.tobytes())
        # (materials·J, R, 4R) RGB layers; s = φ/2π repeats, t = θ/(π/2) clamps to the edge.
        layers = np.ascontiguousarray(np.moveaxis(outgoing, 2, -1).reshape(
            materials * terms, rows, cols, 3))
        self.outgoing = self.ctx.texture_array((cols, rows, materials * terms), 3,
                                               layers.tobytes(), dtype="f4")
        self.outgoing.filter = (self.ctx.LINEAR, self.ctx.LINEAR)
        self.outgoing.repeat_x, self.outgoing.repeat_y = True, False
        self._texture_bytes = int(layers.nbytes)
        self._resident = [self.transfer_buffer, self.outgoing]

    def _bind(self, view, light) -> None:
        self.transfer_buffer.bind_to_storage_buffer(0)
        self.outgoing.use(location=0)
        self.program["outgoing_factors"].value = 0
        coeffs = light.sh(self.sh_bands).astype(np.float32)  # (n², 3)
        self.program["light_sh"].write(np.ascontiguousarray(coeffs).tobytes())

    def memory_bytes(self) -> int:
        """The J transfer vectors per vertex plus the outgoing-factor tables."""
        return int(self.transfer_buffer.size) + self._texture_bytes
