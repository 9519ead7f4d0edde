"""Probe volumes as engines ship them (``probe-volume``).

Placement (:mod:`.placement`): N³ probes on a uniform grid, or Unity's adaptive probe volumes,
4×4×4 bricks of cubic cells refined 3× per level towards the geometry, found through an index
texture. Each probe is traced with uniform sphere rays (:mod:`.bake`): its visibility SH, its
validity (fraction of back-face hits, Unity APV), a virtual offset out of geometry for invalid
ones, dilation of invalid probes, and for ``visibility_test=chebyshev`` DDGI's depth moments.

Light classes (``light_mode``):

* ``relight``: each probe stores the SH of its sky visibility V (L1: 4, L2: 9 values) or, with
  the ambient cube, its cosine-weighted visibility a_d about the six axes. The fragment shader
  interpolates them and multiplies in the light given as SH per frame, R_k = Σ_ij Γ_ijk V_i L_j
  (the triple product, prt_shading.glsl), or C_d = a_d · E_L(d) (Unity's sky-occlusion idea
  along the cube's axes): any light at run time, light dependence none.
* ``fixed``: each probe stores the radiance of one light, baked at ``bake_bands`` (R = Γ·V·L
  there, truncated to L1 / L2) or the ambient cube's irradiance colours; ``bake_light`` names
  it (baked in the precompute; other lights are an error) or, empty, the renderer bakes each
  light once on the CPU outside the frame (as the irradiance volume does).

Render: per pixel the lookup at p + ``normal_bias``·n (in finest cells), the 8 probes of the
cell with trilinear weights, restricted by the visibility test (``none``; ``validity``: invalid
probes left out and the weights renormalised, Unity's validity-based leak reduction;
``chebyshev``: DDGI's smooth back-face term and the Chebyshev bound of the probe's depth moments
in the probe-to-point direction, Majercik et al. 2019), the decode of the pool's storage
(:mod:`.encoding`), then E at the normal (SH: Σ_l Â_l Σ_m R_lm Y_lm(n); cube:
Σ_i n_i² C_{±i}) and B = kd/π · E. Diffuse materials only.

Memory (``memory_breakdown``): the probe pool (engine storage, fixed: exactly 16 bytes per
probe at L1 and 32 at L2, Unity's layout), the validity bytes, the brick index, the depth
moments and the relight's Γ list, each counted over the pool's allocated slots.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from methods.common.materials import check_diffuse_constant_kd
from methods.probe_volume.bake import bake_probes, fold
from methods.probe_volume.encoding import (
    COEFFICIENTS,
    SH_ENCODING_BANDS,
    bytes_per_probe,
    layout,
)
from methods.probe_volume.placement import brick_layout, uniform_layout
from methods.probe_volume.renderer import ProbeVolumeRenderer
from prtbench.api.config import knob, seed_knob
from prtbench.api.errors import InvalidInputError
from prtbench.api.method import Artifact, Method, register_method
from prtbench.render import ops
from prtbench.transport.lights import get_light


@dataclass(frozen=True)
class ProbeVolumeConfig:
    """Knobs of the ``probe-volume`` method."""

    encoding: str = knob("l2", "Per-probe basis: l1 (SH, 4 coefficients), l2 (SH, 9) or "
                         "ambient-cube (Half-Life 2: six colours along ±x, ±y, ±z).",
                         choices=tuple(COEFFICIENTS))
    light_mode: str = knob("relight", "relight: per-probe sky-visibility transfer, the light "
                           "multiplied in per pixel (any light); fixed: one light's radiance "
                           "baked in the probes.", choices=("relight", "fixed"))
    storage: str = knob("engine", "Probe pool storage: engine (the shipped quantised layout: "
                        "fixed L1 in 16 bytes per probe, L2 in 32) or float16.",
                        choices=("engine", "float16"))
    placement: str = knob("bricks", "uniform (N³ grid) or bricks (Unity APV: 4×4×4 bricks, "
                          "denser near geometry).", choices=("uniform", "bricks"))
    resolution: int = knob(19, "Probes per axis N (uniform), or 1 + cells along the longest "
                               "axis at the finest level (bricks; rounded up to whole bricks).",
                           low=2, high=64)
    brick_levels: int = knob(2, "Brick levels (each 3× denser than the one above it).",
                             low=1, high=3)
    rays_per_probe: int = knob(256, "Uniform sphere rays per probe (stratified, randomly "
                                    "rotated).", low=1, high=1 << 16)
    bake_bands: int = knob(6, "fixed: SH bands at which visibility and light are multiplied "
                              "before the truncation to the encoding (>= its bands).",
                           low=1, high=8)
    bake_light: str = knob("", "fixed: light baked in the precompute (registry name or HDR "
                               "path; rendering another is an error). Empty: each light rendered "
                               "is baked once, on the CPU, outside the frame time.")
    visibility_test: str = knob("validity", "Weights of the 8 probes: none (trilinear), "
                                "validity (invalid probes left out) or chebyshev (DDGI depth "
                                "moments, and validity).", choices=("none", "validity",
                                                                    "chebyshev"))
    depth_texels: int = knob(8, "chebyshev: octahedral depth-moment texels per side per probe.",
                             low=2, high=16)
    normal_bias: float = knob(0.3, "Lookup offset along the normal, in finest cells.",
                              low=0.0, high=4.0)
    padding: float = knob(0.02, "Volume padding on each side, as a fraction of the scene "
                                "diagonal.", low=0.0, high=1.0)
    invalid_backface_fraction: float = knob(
        0.25, "Probes with more back-face hits than this fraction of their rays are invalid.",
        low=0.0, high=1.0)
    virtual_offset: float = knob(0.2, "Virtual offset search distance, in probe spacings "
                                      "(0: off).", low=0.0, high=1.0)
    dilation_iterations: int = knob(1, "Dilation passes filling invalid probes from their valid "
                                       "neighbours (0: none).", low=0, high=8)
    seed: int = seed_knob("Seed of the ray pattern's shift and the per-probe rotations.")
    visibility: bool = knob(True, "Trace occlusion at the probes. False: every ray escapes "
                                  "(unshadowed environment light, every probe valid), the "
                                  "trivial image the regression gate must beat.")


def check_config(config: ProbeVolumeConfig) -> None:
    """Refuse knob combinations the bake cannot honour (one line each)."""
    needed = SH_ENCODING_BANDS.get(config.encoding, 1)
    if config.light_mode == "fixed" and config.bake_bands < needed:
        raise InvalidInputError(f"bake_bands={config.bake_bands} with encoding={config.encoding}; "
                                f"accepted: bake_bands >= {needed}")
    if config.bake_light and config.light_mode != "fixed":
        raise InvalidInputError(f"bake_light={config.bake_light} with light_mode=relight; "
                                "accepted: bake_light only with light_mode=fixed")


def probe_layout(scene, config: ProbeVolumeConfig):
    """The configured placement (:mod:`.placement`)."""
    if config.placement == "uniform":
        return uniform_layout(scene, resolution=config.resolution, padding=config.padding)
    return brick_layout(scene, resolution=config.resolution, levels=config.brick_levels,
                        padding=config.padding)


@register_method("probe-volume")
class ProbeVolume(Method):
    """SH (or ambient-cube) probes in a volume, interpolated per fragment."""

    Config = ProbeVolumeConfig
    storage = "per-probe"
    family = "probe volume"
    verdict_grid = {"light_mode": ["relight", "fixed"]}
    engine_baseline = True
    precompute_version = "1"
    main_knobs = ("resolution",)
    paper = ("Unity adaptive probe volumes (Unity-Technologies/Graphics, ProbeVolume: bricks, "
             "validity, virtual offset, dilation, the ProbeBrickPool layout, sky occlusion); "
             "Majercik, Guertin, Nowrouzezahrai and McGuire 2019, Dynamic Diffuse Global "
             "Illumination with Ray-Traced Irradiance Fields (JCGT 8(2)): Chebyshev visibility; "
             "McTaggart 2004, Half-Life 2 / Valve Source Shading (GDC): the ambient cube; "
             "Ramamoorthi and Hanrahan 2001: the irradiance")
    light_dependence = "none"
    baked_light_knobs = {"light_mode": "relight"}  # light_mode=fixed: the protocol's `fixed`
    light_baking_knobs = {"light_mode": ("fixed-light", "relight", "light_mode=fixed bakes one "
                                         "light's radiance into the probes")}
    profile_overrides = {
        "smoke": {"rays_per_probe": 64, "resolution": 10, "brick_levels": 1},
        "quick": {"rays_per_probe": 256},
        "paper": {"rays_per_probe": 1024},
    }
    #: The baked form in the shipped layout is regressed as ``probe-volume:fixed``.
    regression_variants = {"fixed": {"light_mode": "fixed"}}

    @classmethod
    def validate(cls, scene, config: ProbeVolumeConfig) -> None:
        check_config(config)
        check_diffuse_constant_kd(cls.name, scene,
                                  renders="stores irradiance and renders diffuse materials only")
        if config.bake_light:
            get_light(config.bake_light)  # an unknown name fails before any work

    @classmethod
    def precompute(cls, scene, config: ProbeVolumeConfig, *, progress: bool = True) -> Artifact:
        cls.validate(scene, config)
        layout = probe_layout(scene, config)
        relight = config.light_mode == "relight"
        bands = (SH_ENCODING_BANDS.get(config.encoding, 1) if relight else config.bake_bands)
        chebyshev = config.visibility_test == "chebyshev"
        bake = bake_probes(scene, layout, bands=bands, rays=config.rays_per_probe,
                           seed=config.seed, occlusion=config.visibility,
                           invalid_backface_fraction=config.invalid_backface_fraction,
                           virtual_offset=config.virtual_offset,
                           dilation_iterations=config.dilation_iterations,
                           depth_texels=config.depth_texels if chebyshev else 0,
                           progress=progress)
        arrays = {"probe_texel": layout.texel.astype(np.int32),
                  "probe_positions": layout.positions.astype(np.float32),
                  "capture_positions": bake.capture.astype(np.float32),
                  "valid": bake.valid.astype(np.uint8),
                  "backface_fraction": bake.backface_fraction.astype(np.float32),
                  "volume_origin": layout.origin.astype(np.float64),
                  "cell_size": layout.cell.astype(np.float64)}
        if layout.index is not None:
            arrays["brick_index"] = layout.index
        if bake.depth is not None:
            arrays["depth_moments"] = bake.depth.astype(np.float16)
        cube = config.encoding == "ambient-cube"
        meta = {"probes": layout.probes, "pool_probes": layout.pool_probes,
                "pool_shape": list(layout.pool_shape), "pool_bricks": list(layout.pool_bricks),
                "grid": layout.grid, "placement": layout.kind,
                "valid_probes": int(bake.valid.sum()),
                "offset_probes": int(np.any(bake.capture != layout.positions, axis=1).sum())}
        if relight:
            arrays["transfer"] = (bake.cube if cube else bake.visibility).astype(np.float32)
        elif config.bake_light:
            light = get_light(config.bake_light)
            coeffs = fold(bake.visibility, light.sh(config.bake_bands), encoding=config.encoding,
                          bake_bands=config.bake_bands)
            arrays["radiance"] = coeffs.astype(np.float32)
            meta.update(bake_light=light.name, bake_light_hash=light.content_hash())
        else:
            arrays["visibility"] = bake.visibility.astype(np.float32)
        return Artifact(cls.name, arrays, meta)

    @classmethod
    def renderer(cls, scene, artifact: Artifact, config: ProbeVolumeConfig, *, width: int,
                 height: int) -> ProbeVolumeRenderer:
        check_config(config)
        return ProbeVolumeRenderer(scene, artifact, config, width=width, height=height)

    @classmethod
    def op_counts(cls, config: ProbeVolumeConfig, *, scene_vertices: int, scene_triangles: int,
                  covered_pixels: int, width: int, height: int, memory_bytes: int):
        """probe_volume.frag per covered pixel (once each, after the depth pre-pass): the cell
        (bricks: one index fetch and the brick's origin), per corner its validity fetch, the
        pool's texel fetches, the decode and the weighted sum (3 madds per value), with
        chebyshev four depth-moment fetches, the octahedral encoding and the weight terms; then
        relight's triple product (SH) or three axis irradiances (cube), and E at the normal. Like the irradiance volume's, per-pixel work does not grow
        with the resolution: only what is resident does."""
        k = COEFFICIENTS[config.encoding]
        channels = 1 if config.light_mode == "relight" else 3
        per_probe = bytes_per_probe(config.encoding, config.storage, channels)
        textures = len(layout(config.encoding, config.storage, channels))
        bricks = config.placement == "bricks"
        locate = {"madds": 42.0 if bricks else 20.0, "fetches": 1.0 if bricks else 0.0,
                  "bytes": 4.0 if bricks else 0.0}
        validity = config.visibility_test != "none"
        per_corner = {"madds": 6.0 + 3.0 * k * channels,  # weight, decode, weighted sum
                      "fetches": float(textures + validity), "bytes": float(per_probe + validity)}
        if config.visibility_test == "chebyshev":
            per_corner = ops.add_counts(per_corner, {
                "madds": 40.0 + 3 * ops.TRANSCENDENTAL_MADDS, "fetches": 4.0, "bytes": 16.0})
        sh = SH_ENCODING_BANDS.get(config.encoding)
        relight_sh = sh is not None and channels == 1
        if sh is not None:  # sh_zonal_eval_rgb at the normal (and the triple product)
            shade = {"madds": ops.sh_eval_madds(sh) + 3.0 * sh * sh + 7.0 * sh}
            if relight_sh:
                shade = ops.add_counts(shade, ops.triple_product_counts(sh))
        else:  # n² and three colours; relight: the light's L2 irradiance along three axes
            shade = {"madds": 12.0 + (3 * (ops.sh_eval_madds(3) + 48.0) if channels == 1
                                      else 0.0)}
        per_pixel = ops.add_counts(locate, ops.scaled(per_corner, 8.0), shade, {"madds": 6.0})
        frame = {"bytes": ops.gamma_bytes(sh) if relight_sh else 0.0}
        return ops.add_counts(
            ops.raster_counts(vertices=scene_vertices, triangles=scene_triangles,
                              pixels=covered_pixels, varyings=9, vertex_bytes=36,
                              depth_prepass=True),
            ops.scaled(per_pixel, covered_pixels), frame)
