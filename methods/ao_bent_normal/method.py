"""Ambient occlusion and bent normals: the cheapest relightable sky term engines ship.

Precompute (light-independent), at every vertex (``ao-bent-normal``) or covered texel of the
transfer-texture atlas (``ao-bent-normal-texture``): the cosine-weighted visibility and its
mean unoccluded direction,

    AO(p) = 1/π ∫ V(p, ω) max(n·ω, 0) dω        b(p) = normalize(∫ ω V(p, ω) max(n·ω, 0) dω),

the bent normal b (n where every ray is blocked). Both are the first two SH bands of the
shadowed transfer of :mod:`prtbench.transport.transfer` (the same cosine-weighted ray pattern,
seeds and cache as the PRT methods): T_0 = π Y_00 · AO, and the three l = 1 coefficients are
√(3/4π) times the x, y, z of the direction integral (Y_1,-1 ∝ y, Y_1,0 ∝ z, Y_1,1 ∝ x), so
their direction is b.

Render (any light): B = kd/π · AO · E(b), with E the Ramamoorthi–Hanrahan irradiance of the
light's SH L2 projection at the bent normal, E(b) = Σ_{l≤2} Â_l Σ_m L_lm Y_lm(b), Â_l the
clamped-cosine convolution (DESIGN.md §5). Shadows are not directional: the light's shape only
enters through the bent normal, which is what makes the term cheap and relightable. On an
unoccluded convex object AO = 1 and b = n, so it equals ``vertex`` at 3 bands (tested).

Storage: per vertex, one float32 RGBA (b, AO) in a storage buffer, 16 bytes; per texel, one
RGBA texel of the atlas (``texel_format``: rgba8, b encoded as 0.5 + 0.5·b, 4 bytes, as engines
store it; or rgba16f, 8 bytes), sampled bilinearly and renormalised. Diffuse materials only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from methods.ao_bent_normal import SHADER_DIR
from methods.common.atlas.bake import AtlasTexels, validate_diffuse_atlas
from methods.common.atlas.raster import AtlasRenderer
from methods.common.materials import check_diffuse_constant_kd
from methods.common.residency import named_breakdown
from prtbench.api.config import knob, seed_knob
from prtbench.api.method import Artifact, Method, register_method
from prtbench.render import ops
from prtbench.render.raster import RasterRenderer
from prtbench.transport.sh import clamped_cosine_zonal
from prtbench.transport.transfer import compute_transfer

#: SH bands of the light's irradiance (L2: Ramamoorthi and Hanrahan's nine coefficients).
IRRADIANCE_BANDS = 3
#: Y_00 = 1/(2√π): T_0 = π·Y_00·AO.
Y00 = 0.5 / np.sqrt(np.pi)
#: Bytes per texel of each texel format.
TEXEL_BYTES = {"rgba8": 4, "rgba16f": 8}


def ao_bent_from_transfer(transfer: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """AO and bent normals from the first two SH bands of the shadowed transfer.

    Parameters
    ----------
    transfer : ndarray, shape (N, k) with k >= 4
        T_i = ∫ Y_i V max(n·ω, 0) dω (:func:`prtbench.transport.transfer.compute_transfer`).
    normals : ndarray, shape (N, 3)
        The normals the transfer was computed about (the bent normal where nothing is visible).

    Returns
    -------
    ndarray, shape (N, 4), float32
        Unit bent normal (x, y, z) and AO in [0, 1].
    """
    t = np.asarray(transfer, np.float64)
    ao = np.clip(t[:, 0] / (np.pi * Y00), 0.0, 1.0)
    direction = t[:, [3, 1, 2]]  # (Y_1,1, Y_1,-1, Y_1,0) ∝ (x, y, z)
    length = np.linalg.norm(direction, axis=1, keepdims=True)
    n = np.asarray(normals, np.float64)
    n = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
    # Nothing visible (AO = 0): the direction is undefined; the shading is 0 whatever it is.
    seen = (length[:, 0] > 1e-9) & (ao > 0.0)
    bent = np.where(seen[:, None], direction / np.maximum(length, 1e-30), n)
    return np.concatenate([bent, ao[:, None]], axis=1).astype(np.float32)


def bake_ao_bent(scene, points: np.ndarray, normals: np.ndarray, *, rays_per_point: int,
                 seed: int, visibility: bool, progress: bool) -> np.ndarray:
    """(N, 4) float32 bent normal and AO at ``points`` about ``normals`` (2-band transfer)."""
    transfer = compute_transfer(scene, points, normals, bands=2, rays_per_point=rays_per_point,
                                seed=seed, progress=progress, visibility=visibility)
    return ao_bent_from_transfer(transfer, normals)


def irradiance_madds() -> float:
    """sh_zonal_eval_rgb at L2: sh_eval, an RGB madd per coefficient, the band scaling."""
    n = IRRADIANCE_BANDS
    return ops.sh_eval_madds(n) + 3.0 * n * n + 3.0 * n + 4.0 * n


@dataclass(frozen=True)
class AoBentNormalConfig:
    """Knobs of the ``ao-bent-normal`` method."""

    rays_per_point: int = knob(512, "Visibility rays per vertex (cosine-weighted, stratified: "
                                    "the transfer's ray pattern).", low=1, high=1 << 20)
    seed: int = seed_knob("Seed of the per-vertex random rotations of the ray pattern.")
    visibility: bool = knob(True, "Trace occlusion. False: AO = 1 and the bent normal is the "
                                  "normal (unshadowed irradiance), the trivial image the "
                                  "regression gate must beat.")


@dataclass(frozen=True)
class AoBentNormalTextureConfig:
    """Knobs of the ``ao-bent-normal-texture`` method."""

    texture_resolution: int = knob(512, "Side R of the AO / bent-normal texture in texels "
                                   "(4096: about 90 s of bake on 2 cores at 64 rays).",
                                   low=16, high=4096)
    texture_sets: bool = knob(False, "One R×R texture per object instead of one shared atlas.")
    padding: int = knob(2, "Empty texels between atlas charts (xatlas).", low=0, high=64)
    dilation: int = knob(3, "Rings of texels filled around covered texels (>= 1 for bilinear "
                            "lookups at chart borders).", low=0, high=64)
    texel_format: str = knob("rgba8", "Texel storage: rgba8 (bent normal as 0.5 + 0.5·b, AO; "
                             "4 bytes, the engines' format) or rgba16f (8 bytes).",
                             choices=tuple(TEXEL_BYTES))
    rays_per_point: int = knob(512, "Visibility rays per texel (cosine-weighted, stratified).",
                               low=1, high=1 << 20)
    seed: int = seed_knob("Seed of the per-texel random rotations of the ray pattern.")
    visibility: bool = knob(True, "Trace occlusion. False: AO = 1 and the bent normal is the "
                                  "normal, the trivial image the regression gate must beat.")


class _AoBentBase(Method):
    """What both forms declare."""

    light_dependence = "none"
    paper = ("Ramamoorthi and Hanrahan 2001, An Efficient Representation for Irradiance "
             "Environment Maps (SIGGRAPH 2001): the L2 irradiance; ambient occlusion and bent "
             "normals as in Landis 2002, Production-Ready Global Illumination (SIGGRAPH course "
             "16), and engines' sky-occlusion terms")


@register_method("ao-bent-normal")
class AoBentNormal(_AoBentBase):
    """Per-vertex AO and bent normal, shaded in the vertex shader."""

    Config = AoBentNormalConfig
    storage = "per-vertex"
    family = "AO + bent normal"
    engine_baseline = True
    verdict_grid = {}
    precompute_version = "1"
    #: Nothing trades accuracy for cost: 16 bytes and one L2 evaluation per vertex whatever the rays.
    main_knobs = ()
    profile_overrides = {"smoke": {"rays_per_point": 128}, "quick": {"rays_per_point": 512},
                         "paper": {"rays_per_point": 4096}}
    #: Per-vertex occlusion needs vertices: the 2-triangle ground of the default plants cannot
    #: hold the plants' contact shadows (as for ``vertex``).
    regression_case = {"scene": "plants", "variant": "diffuse", "light": "sky",
                       "scene_params": {"ground_subdivisions": 32}}

    @classmethod
    def validate(cls, scene, config: AoBentNormalConfig) -> None:
        check_diffuse_constant_kd(cls.name, scene)

    @classmethod
    def precompute(cls, scene, config: AoBentNormalConfig, *, progress: bool = True) -> Artifact:
        positions, normals, _, _ = scene.merged()
        ao_bent = bake_ao_bent(scene, positions, normals, rays_per_point=config.rays_per_point,
                               seed=config.seed, visibility=config.visibility, progress=progress)
        return Artifact(cls.name, {"ao_bent": ao_bent},
                        {"vertices": int(len(positions)), "mean_ao": float(ao_bent[:, 3].mean())})

    @classmethod
    def renderer(cls, scene, artifact: Artifact, config: AoBentNormalConfig, *, width: int,
                 height: int) -> "AoBentNormalRenderer":
        return AoBentNormalRenderer(scene, artifact, width=width, height=height)

    @classmethod
    def op_counts(cls, config: AoBentNormalConfig, *, scene_vertices: int, scene_triangles: int,
                  covered_pixels: int, width: int, height: int, memory_bytes: int):
        """ao_bent_normal.vert per vertex: one vec4 load, the L2 irradiance at the bent normal,
        kd/π · AO; interpolated_radiance.frag only interpolates the radiance (3 varyings)."""
        per_vertex = {"madds": irradiance_madds() + 6.0, "fetches": 1.0, "bytes": 16.0}
        return ops.add_counts(
            ops.raster_counts(vertices=scene_vertices, triangles=scene_triangles,
                              pixels=covered_pixels, varyings=3, vertex_bytes=24),
            ops.scaled(per_vertex, scene_vertices))


class _IrradianceUniforms:
    """The light's L2 SH and the clamped-cosine zonal coefficients, uploaded per frame."""

    def _bind_light(self, light) -> None:
        coeffs = np.ascontiguousarray(light.sh(IRRADIANCE_BANDS), np.float32)  # (9, 3)
        self.program["light_sh"].write(coeffs.tobytes())
        self.program["zonal"].write(clamped_cosine_zonal(IRRADIANCE_BANDS)
                                    .astype(np.float32).tobytes())


class AoBentNormalRenderer(_IrradianceUniforms, RasterRenderer):
    """The (b, AO) vectors in a shader storage buffer; the light's L2 SH in a uniform."""

    shader_dirs = (SHADER_DIR,)

    def __init__(self, scene, artifact: Artifact, *, width: int, height: int):
        super().__init__(scene, width=width, height=height, vertex_shader="ao_bent_normal.vert",
                         fragment_shader="interpolated_radiance.frag",
                         defines={"SH_BANDS": IRRADIANCE_BANDS})
        data = np.ascontiguousarray(artifact.arrays["ao_bent"], np.float32)
        self.ao_bent_buffer = self.ctx.buffer(data.tobytes())
        self._resident = [self.ao_bent_buffer]
        self._parts = {"gpu: AO and bent normal per vertex (float32 RGBA)": int(data.nbytes)}

    def _bind(self, view, light) -> None:
        self.ao_bent_buffer.bind_to_storage_buffer(0)
        self._bind_light(light)

    def memory_breakdown(self) -> dict[str, int]:
        """The (b, AO) buffer, then the mesh's buffers and the render target."""
        return named_breakdown(self, self._parts, self._resident)

    def memory_bytes(self) -> int:
        """The method's own data: 16 bytes per vertex."""
        return int(sum(self._parts.values()))


def texel_storage(ao_bent: np.ndarray, texel_format: str) -> np.ndarray:
    """(…, 4) bent normal and AO as stored: uint8 (0.5 + 0.5·b, AO) or float16."""
    values = np.asarray(ao_bent, np.float64)
    if texel_format == "rgba16f":
        return values.astype(np.float16)
    encoded = np.concatenate([0.5 + 0.5 * values[..., :3], values[..., 3:]], axis=-1)
    return np.rint(np.clip(encoded, 0.0, 1.0) * 255.0).astype(np.uint8)


@register_method("ao-bent-normal-texture")
class AoBentNormalTexture(_AoBentBase):
    """AO and bent normal per texel of the atlas, shaded per fragment."""

    Config = AoBentNormalTextureConfig
    storage = "per-texel"
    family = "AO + bent normal"
    engine_baseline = True
    verdict_grid = {"texture_resolution": "auto"}
    precompute_version = "1"
    main_knobs = ("texture_resolution",)
    profile_overrides = {
        # Small atlases need thin padding to pack ~20k-triangle scenes (plants, room) at 128².
        "smoke": {"texture_resolution": 128, "padding": 1, "rays_per_point": 64},
        "quick": {"texture_resolution": 256, "rays_per_point": 256},
        "paper": {"texture_resolution": 1024, "rays_per_point": 1024},
    }

    @classmethod
    def validate(cls, scene, config: AoBentNormalTextureConfig) -> None:
        # Measured peak: 272-315 bytes per texel (the 2-band transfer and its rays, the
        # dilated float64 texture and its copies, the stored form), the G-buffer's included.
        validate_diffuse_atlas(cls.name, scene, texture_resolution=config.texture_resolution,
                               padding=config.padding, texture_sets=config.texture_sets,
                               bytes_per_texel=240)

    @classmethod
    def precompute(cls, scene, config: AoBentNormalTextureConfig, *,
                   progress: bool = True) -> Artifact:
        cls.validate(scene, config)
        texels = AtlasTexels.from_scene(scene, resolution=config.texture_resolution,
                                        padding=config.padding, texture_sets=config.texture_sets)
        ao_bent = bake_ao_bent(scene, texels.points, texels.normals,
                               rays_per_point=config.rays_per_point, seed=config.seed,
                               visibility=config.visibility, progress=progress)
        texture = texels.texture(ao_bent, rings=config.dilation)
        arrays = {"ao_bent": texel_storage(texture, config.texel_format),
                  **texels.arrays(rings=config.dilation)}
        meta = {**texels.meta(), "texel_format": config.texel_format,
                "mean_ao": float(ao_bent[:, 3].mean()) if len(ao_bent) else 0.0,
                "times": texels.times}
        return Artifact(cls.name, arrays, meta)

    @classmethod
    def renderer(cls, scene, artifact: Artifact, config: AoBentNormalTextureConfig, *,
                 width: int, height: int) -> "AoBentNormalTextureRenderer":
        return AoBentNormalTextureRenderer(scene, artifact, config, width=width, height=height)

    @classmethod
    def op_counts(cls, config: AoBentNormalTextureConfig, *, scene_vertices: int,
                  scene_triangles: int, covered_pixels: int, width: int, height: int,
                  memory_bytes: int):
        """ao_bent_normal.frag per covered pixel (once each, after the depth pre-pass): one
        bilinear RGBA lookup (4 taps), the decode and renormalisation of b, the L2 irradiance
        at b, kd/π · AO."""
        per_pixel = {"madds": 3.0 + 6.0 + ops.TRANSCENDENTAL_MADDS + irradiance_madds() + 6.0,
                     "fetches": 1.0, "bytes": 4.0 * TEXEL_BYTES[config.texel_format]}
        return ops.add_counts(
            ops.raster_counts(vertices=scene_vertices, triangles=scene_triangles,
                              pixels=covered_pixels, varyings=14, vertex_bytes=92,
                              depth_prepass=True),
            ops.scaled(per_pixel, covered_pixels))


class AoBentNormalTextureRenderer(_IrradianceUniforms, AtlasRenderer):
    """The (b, AO) texels in a texture array (one layer per texture set)."""

    shader_dirs = (SHADER_DIR,)

    def __init__(self, scene, artifact: Artifact, config: AoBentNormalTextureConfig, *,
                 width: int, height: int):
        stored = artifact.arrays["ao_bent"]
        unorm = stored.dtype == np.uint8
        super().__init__(scene, artifact.arrays, artifact.meta,
                         fragment_shader="ao_bent_normal.frag",
                         defines={"SH_BANDS": IRRADIANCE_BANDS, "UNORM8": int(unorm)},
                         width=width, height=height)
        fmt = "RGBA8" if unorm else "RGBA16F"
        self.ao_bent_texture = self.texture_array(f"AO and bent normal texture ({fmt})", stored)

    def _bind(self, view, light) -> None:
        self.ao_bent_texture.use(location=0)
        self.program["ao_bent"].value = 0
        self._bind_light(light)
