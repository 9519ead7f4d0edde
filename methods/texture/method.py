"""Transfer textures (Sirikonda, KT and Narayanan 2022, "PRTT"): ``texture-tp``, ``texture-tpfl``.

Precompute (PRTT Algorithms 1 and 2): a UV atlas of the scene (xatlas; one shared texture or
one texture per object with ``texture_sets``), a texel-space G-buffer of world positions and
shading normals (normal maps applied, PRTT §6.2) rendered with moderngl, the shadowed transfer
T_i(p) = ∫ Y_i V max(n·ω, 0) dω at every covered texel (embree), then dilation. With
``bounces`` = k > 0, k more RGB textures T_1 … T_k hold the interreflected radiance of the
light ``bounce_light`` (PRTT §4.2: light and BRDF are baked, see :mod:`.bounces`).

Render: an early depth pre-pass, then per fragment the transfer vector is sampled from a
texture array and turned into transferred radiance H by the triple product (``texture-tp``,
H_k = Σ_ij Γ_ijk T_i L_j over the sparse Γ) or the fixed-light matrix (``texture-tpfl``,
H_k = Σ_i T_i M_ik); the bounce textures are added to H, and H is shaded with the Phong BRDF.
Both share prt_shading.glsl with the vertex methods, so only where transfer is sampled differs.

Seams: the G-buffer covers every texel a triangle touches (not only those whose centre it
contains), so the texel under any point of a triangle holds data, and bilinear lookups there
read only its 8 neighbours, which one dilation ring fills (dilation never mixes charts). Lookups
are bilinear (``filtering``), clamped to the edge, no mip-maps.

Bounce light: the bounce textures are valid for one light only. The artifact bakes
``bounce_light`` (default: the scene's default light) and records its content hash; rendering
it under another light is an InvalidInputError naming the ``--set bounce_light=...`` to use,
never a silently wrong image. The bake's cost is therefore part of the precompute time, as in
the paper.

Memory: T_0 takes ceil(n²/4) RGBA layers per texture (25 coefficients: 7 layers, 28 channels),
each T_b ceil(3n²/4) layers, at 4 (float32) or 2 (float16) bytes per channel.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from methods.common.atlas.atlas import AtlasMesh, render_gbuffer
from methods.common.atlas.shading import ShadingInputs, distinct_normal_maps
from methods.common.atlas.texels import dilate, to_storage
from methods.texture.bounces import bounce_textures
from methods.texture.compressed import check_form, texel_signals
from methods.texture.renderer import TextureRenderer
from prtbench.api import config as config_mod
from prtbench.api.cache import cached_arrays, content_key
from prtbench.api.config import check_memory, knob, seed_knob
from prtbench.api.errors import InvalidInputError
from prtbench.api.method import Artifact, Method, register_method
from prtbench.render import ops
from prtbench.scene.model import Texture
from prtbench.transport.compress import knobs as compress_knobs
from prtbench.transport.lights import get_light
from prtbench.transport.transfer import compute_transfer


@dataclass(frozen=True)
class TextureConfig:
    """Knobs of the transfer-texture methods (``texture-tp``, ``texture-tpfl``)."""

    sh_bands: int = knob(5, "SH bands n (n² transfer coefficients per texel; PRTT uses 5).",
                         low=1, high=8)
    texture_resolution: int = knob(
        1024, "Side R of each transfer texture in texels (PRTT: 1024).", low=16, high=8192)
    texture_sets: bool = knob(
        False, "One R×R texture per object (PRTT §4.3 texture sets) instead of one shared "
               "atlas; memory grows with the object count.")
    padding: int = knob(2, "Empty texels between atlas charts (xatlas).", low=0, high=64)
    dilation: int = knob(
        3, "Rings of texels filled around covered texels (PRTT: 3). At least 1 is needed for "
           "bilinear lookups near chart borders; 0 only for ablations.", low=0, high=64)
    storage: str = knob("float32", "Texel precision: float32 (PRTT's 100 MB at 1024², 25 "
                        "coefficients) or float16 (half; values beyond ±65504 are an error).",
                        choices=("float32", "float16"))
    filtering: str = knob("bilinear", "Transfer texture lookups: bilinear or nearest.",
                          choices=("bilinear", "nearest"))
    depth_prepass: bool = knob(True, "Early depth pre-pass before shading (PRTT §5); off draws "
                               "one pass with depth test LESS (same image, more shading work).")
    rays_per_point: int = knob(512, "Visibility rays per texel (cosine-weighted, stratified); "
                               "also the gather rays of each bounce.", low=1, high=1 << 20)
    bounces: int = knob(0, "Interreflection textures T_1…T_k (PRTT §4.2; light and BRDF baked).",
                        low=0, high=8)
    bounce_light: str = knob(
        "", "Light baked into the bounce textures (registry name or HDR path; empty: the "
            "scene's default light). Rendering under another light is an error.")
    seed: int = seed_knob("Seed of the per-texel ray patterns.")
    visibility: bool = knob(True, "Trace occlusion in the transfer. False: unshadowed transfer "
                                  "(V = 1), the trivial image the regression gate must beat; "
                                  "needs bounces=0 (no ray hits anything to bounce from).")
    compress: str = compress_knobs.compress_knob()
    clusters: int | None = compress_knobs.clusters_knob()
    pca_vectors: int | None = compress_knobs.pca_vectors_knob()


class TextureMethod(Method):
    """Shared precompute of both transfer-texture methods; subclasses pick the product."""

    storage = "per-texel"

    family = "SH PRT"

    Config = TextureConfig
    precompute_version = "1"
    #: Knobs along which accuracy and cost both grow (searched by ``prtbench advise``).
    main_knobs = ("sh_bands", "texture_resolution")
    product: ClassVar[str] = "tpfl"
    baked_light_knobs = {"bounces": 0}  # bounce_light is baked into the bounce textures
    light_baking_knobs = {"bounces": ("fixed-light", 0, "bounces > 0 bakes bounce_light into "
                                      "the interreflection textures")}
    #: The sun, as for the vertex methods: shadows are what a transfer texture must get right.
    regression_case = {"variant": "glossy", "light": "sun"}
    profile_overrides = {
        # Small atlases need thin padding to pack ~20k-triangle scenes (plants, room) at 128².
        "smoke": {"texture_resolution": 128, "padding": 1, "rays_per_point": 64, "sh_bands": 4},
        "quick": {"texture_resolution": 256, "rays_per_point": 256},
        "paper": {"texture_resolution": 1024, "rays_per_point": 1024},
    }

    @classmethod
    def cache_identity(cls, config: TextureConfig) -> dict:
        return compress_knobs.cache_identity(super().cache_identity(config))

    @classmethod
    def validate(cls, scene, config: TextureConfig) -> None:
        check_form(config, sets=len(scene.objects) if config.texture_sets else 1,
                   resolution=config.texture_resolution)
        for obj in scene.objects:
            material = obj.material
            for attr in ("kd", "ks", "shininess"):
                if isinstance(getattr(material, attr), Texture):
                    raise InvalidInputError(
                        f"method '{cls.name}' takes a constant {attr} per object, but "
                        f"'{obj.name}' in scene '{scene.name}' has a textured {attr}; accepted: "
                        "constant kd, ks, shininess (normal maps are supported)")
            if material.normal_map is not None and obj.mesh.uvs is None:
                raise InvalidInputError(
                    f"object '{obj.name}' has a normal map but no mesh uvs; accepted: "
                    "normal maps on meshes with uvs")
        maps = distinct_normal_maps(scene)
        if len(maps) > 1:
            raise InvalidInputError(
                f"scene '{scene.name}' has {len(maps)} different normal maps; accepted: at most "
                f"one normal-map texture per scene for method '{cls.name}'")
        if config.padding * 8 > config.texture_resolution:
            raise InvalidInputError(
                f"padding={config.padding} with texture_resolution={config.texture_resolution}; "
                "accepted: padding <= texture_resolution / 8")
        if config.bounces > 0 and not config.visibility:
            raise InvalidInputError(
                f"bounces={config.bounces} with visibility=False; accepted: bounces=0 when "
                "visibility is off (unoccluded rays hit nothing to bounce from)")
        # Per texel and texture: G-buffer (29 B), float64 points and normals (48 B), then per
        # coefficient and transfer texture the float64 transfer, its dilated copy and the
        # float32 result (28 B).
        sets = len(scene.objects) if config.texture_sets else 1
        per_texel = 80 + 28 * config.sh_bands**2 * (1 + config.bounces)
        res = config.texture_resolution
        fits = int(math.sqrt(config_mod.memory_budget() / (sets * per_texel)))
        check_memory(f"method '{cls.name}' texture_resolution={res} ({sets} texture(s), "
                     f"sh_bands={config.sh_bands}, bounces={config.bounces})",
                     sets * res * res * per_texel, accepted=f"texture_resolution <= {fits}")
        if config.bounces > 0:
            cls.bake_light(scene, config)  # unknown names fail before any work

    @staticmethod
    def bake_light(scene, config: TextureConfig):
        return get_light(config.bounce_light or scene.default_light)

    @classmethod
    def precompute(cls, scene, config: TextureConfig, *, progress: bool = True) -> Artifact:
        cls.validate(scene, config)
        times: dict[str, float] = {}
        clock = time.perf_counter()
        atlas = AtlasMesh.from_scene(scene, resolution=config.texture_resolution,
                                     padding=config.padding, texture_sets=config.texture_sets)
        times["atlas_s"] = time.perf_counter() - clock
        clock = time.perf_counter()
        shading = ShadingInputs.from_scene(scene)
        gbuffer = render_gbuffer(scene, atlas, shading)
        times["gbuffer_s"] = time.perf_counter() - clock
        sets, res = atlas.sets, atlas.resolution
        covered_index = np.flatnonzero(gbuffer.covered.reshape(-1))
        points = gbuffer.positions.reshape(-1, 3)[covered_index].astype(np.float64)
        normals = gbuffer.normals.reshape(-1, 3)[covered_index].astype(np.float64)

        clock = time.perf_counter()
        transfer_at_texels = compute_transfer(
            scene, points, normals, bands=config.sh_bands, rays_per_point=config.rays_per_point,
            seed=config.seed, progress=progress, visibility=config.visibility)
        times["transfer_s"] = time.perf_counter() - clock

        def dilated(values: np.ndarray) -> np.ndarray:
            flat = np.zeros((sets * res * res, values.shape[-1]), np.float64)
            flat[covered_index] = values
            return dilate(flat.reshape(sets, res, res, -1), gbuffer.covered, gbuffer.chart,
                          rings=config.dilation)[0]

        clock = time.perf_counter()
        transfer = dilated(transfer_at_texels)
        _, filled, texel_chart = dilate(np.zeros((sets, res, res, 1), np.float32),
                                        gbuffer.covered, gbuffer.chart, rings=config.dilation)
        times["dilation_s"] = time.perf_counter() - clock
        # covered / filled / texel_chart are diagnostics (seam checks), not uploaded to the GPU;
        # a compressed artifact uploads ``filled`` (which texel each signal is) with its form.
        form = compress_knobs.resolve(config)
        fit_meta: dict[str, Any] = {}
        arrays = ({"transfer": to_storage(transfer, config.storage, what="transfer texture")}
                  if form is None else {})
        arrays.update({"covered": gbuffer.covered.astype(np.uint8),
                       "filled": filled.astype(np.uint8), "texel_chart": texel_chart,
                       **atlas.arrays()})
        if form is not None:

            clock = time.perf_counter()
            compressed, fit_meta = compress_knobs.compress_signals(
                texel_signals(transfer, filled), form, seed=config.seed, what="texels",
                progress=progress)
            arrays.update(compressed)
            times["compress_s"] = time.perf_counter() - clock
        meta: dict[str, Any] = {
            "sh_bands": config.sh_bands, "texture_resolution": res, "texture_sets": sets,
            "covered_texels": int(len(covered_index)), "filled_texels": int(filled.sum()),
            "atlas_vertices": int(len(atlas.uvs)), "storage": config.storage,
            "bounces": int(config.bounces), **fit_meta}
        if config.bounces > 0:
            clock = time.perf_counter()
            light = cls.bake_light(scene, config)
            bounce = _cached_bounces(scene, atlas, shading, config, points=points, normals=normals,
                                     covered_index=covered_index, transfer=transfer,
                                     light=light, dilate=lambda t: dilated(
                                         t.reshape(-1, t.shape[-1])[covered_index]),
                                     progress=progress)
            arrays["bounce"] = to_storage(bounce, config.storage,
                                          what=f"bounce textures for light '{light.name}'")
            meta.update(bounce_light=light.name, bounce_light_hash=light.content_hash())
            times["bounce_s"] = time.perf_counter() - clock
        meta["times"] = times
        return Artifact(cls.name, arrays, meta)

    @classmethod
    def renderer(cls, scene, artifact: Artifact, config: TextureConfig, *, width: int,
                 height: int):

        return TextureRenderer(scene, artifact, config, product=cls.product, width=width,
                               height=height)

    @classmethod
    def op_counts(cls, config: TextureConfig, *, scene_vertices: int, scene_triangles: int,
                  covered_pixels: int, width: int, height: int, memory_bytes: int):
        """texture_prt.frag per covered pixel (after the depth pre-pass, once each): ⌈n²/4⌉
        RGBA transfer-texture lookups (bilinear: 4 texels read each), H by the triple product
        over the Γ list (texture-tp) or the TPFL matrix (texture-tpfl), ⌈3n²/4⌉ more lookups
        and 3n² adds per baked bounce, then Phong shading of H (shade_transferred). The texture
        resolution changes what is resident, not the per-pixel work: ``ops`` does not grow
        with it. Normal maps (one more lookup) are not counted."""

        n, n2 = config.sh_bands, config.sh_bands**2
        texel = 16 if config.storage == "float32" else 8
        taps = 4 if config.filtering == "bilinear" else 1
        layers = -(-n2 // 4)
        bounce_layers = config.bounces * -(-3 * n2 // 4)
        fetches = layers + bounce_layers
        lookups = {"madds": 3.0 * n2 * config.bounces, "fetches": float(fetches),
                   "bytes": float(fetches * taps * texel)}
        product = (ops.triple_product_counts(n) if cls.product == "tp"
                   else {"madds": ops.tpfl_product_madds(n)})
        frame = {"bytes": ops.gamma_bytes(n) if cls.product == "tp" else 0.0}
        form = compress_knobs.resolve(config)
        if form is not None:
            # texture_cpca.glsl per tap (4 bilinear, 1 nearest): an id, ⌈n′/4⌉ weight texels
            # and (1 + n′)·n² RGB table entries, n′·n² RGB madds; per frame the CPU projects
            # K·(1 + n′) vectors through the n² × n² × 3 matrix M.
            k, m = form.clusters, form.pca_vectors
            tap_fetches = float(1 + -(-m // 4) + 3 * (1 + m) * n2)
            lookups = {"madds": 3.0 * taps * m * n2, "fetches": taps * tap_fetches,
                       "bytes": 4.0 * taps * tap_fetches}
            product = {}
            frame = {"madds": 3.0 * k * (1 + m) * n2 * n2}
        shade = {"madds": ops.shade_transferred_madds(n) + 3 + 2 * ops.TRANSCENDENTAL_MADDS}
        per_pixel = ops.add_counts(lookups, product, shade)
        return ops.add_counts(
            ops.raster_counts(vertices=scene_vertices, triangles=scene_triangles,
                               pixels=covered_pixels, varyings=14, vertex_bytes=92,
                               depth_prepass=config.depth_prepass),
            ops.scaled(per_pixel, covered_pixels), frame)


def _cached_bounces(scene, atlas, shading, config, *, points, normals, covered_index, transfer,
                    light, dilate, progress) -> np.ndarray:
    """(k, S, R, R, 3n²) bounce textures, cached by content (texture-tp and -tpfl share them)."""

    key = content_key("texture-bounces", TextureMethod.precompute_version, scene.content_hash(),
                      atlas.uvs, atlas.faces, transfer.astype(np.float32), light.content_hash(),
                      config.bounces, config.rays_per_point, config.seed, config.filtering,
                      config.dilation)

    def compute() -> dict[str, np.ndarray]:
        textures = bounce_textures(
            scene, atlas, shading, points=points, normals=normals, texel_index=covered_index,
            direct=transfer, light_sh=light.sh(config.sh_bands), bounces=config.bounces,
            rays_per_point=config.rays_per_point, seed=config.seed, dilate=dilate,
            filtering=config.filtering, progress=progress)
        return {"bounce": np.stack(textures).astype(np.float32)}

    return cached_arrays("texture-bounces", key, compute)["bounce"]


@register_method("texture-tp")
class TextureTP(TextureMethod):
    """Transfer textures shaded per fragment with the sparse triple product (PRTT, TP)."""

    product = "tp"
    paper = ("Sirikonda, KT and Narayanan 2022, PRTT (precomputed radiance transfer "
             "textures), Algorithms 1 and 2, TP shading")


@register_method("texture-tpfl")
class TextureTPFL(TextureMethod):
    """Transfer textures shaded per fragment with the fixed-light matrix (PRTT, TPFL)."""

    product = "tpfl"
    # prtbench verdict: the atlas that packs the scene and twice it (two memory budgets), at
    # L2 in half floats, as an engine would ship a diffuse sky term.
    verdict_grid = {"texture_resolution": "auto2", "sh_bands": [3], "storage": ["float16"]}
    paper = ("Sirikonda, KT and Narayanan 2022, PRTT (precomputed radiance transfer "
             "textures), Algorithms 1 and 2, TPFL shading")
    light_dependence = "fixed-light"
    light_dependence_why = "folds the light into the TPFL matrix M_ik = Σ_j Γ_ijk L_j once per light"
    #: The CPCA form of the texels (Sloan 2003) is regressed as ``texture-tpfl:cpca`` (compressed,
    #: texture-tp renders the same images: both project the light per cluster).
    regression_variants = {"cpca": {"compress": "cpca", "clusters": 16, "pca_vectors": 4}}
