"""neural-wavelet (Raghavan et al. 2023): learnt Haar-wavelet transport of glossy indirect light.

T(x, j, ωo) = f_θ(Mᵀ(H(x) ⊙ W(j)), SH(ωr), n, kd, ks, φ(s)) (:mod:`methods.neural_wavelet.model`),
trained on indirect-only Mitsuba images under many rotated lights and cameras near the scene's
trajectory (:mod:`methods.neural_wavelet.data`, :mod:`methods.neural_wavelet.train`).

Render, per frame: the GL G-buffer pass (:mod:`methods.neural_wavelet.gbuffer`) → read back →
torch on the front-facing covered pixels: the light's Haar coefficients (the lat-long →
cubemap resampling is per light and cached, as for ``wavelet-vertex``), its k largest by
``selection``, T for those k wavelets per pixel (in chunks of ``render_chunk`` pixels), the
dot product with L → indirect radiance; plus the direct light.

**Direct light (real-time, inside the frame).** ``direct="raytraced"`` (the default) is the
paper's choice: per covered pixel, ``direct_samples`` directions importance-sampled from the
environment and as many from the BRDF, combined by the balance heuristic, Embree shadow rays,
then an edge-avoiding à-trous denoiser (:mod:`methods.neural_wavelet.direct`). Its sampler is
built once per light (``light_change_ms``); its rays, shading and filter are timed in every
frame, its BVH, sampler and buffers are in ``memory_breakdown``, its operations in
``op_counts``. ``direct="none"`` renders indirect light alone (the paper's indirect-only
columns). ``direct="offline-reference"`` adds a Mitsuba direct-only render (``direct_spp``,
its own seed :data:`DIRECT_SEED`): pixels from the reference renderer, so it is a *diagnostic*
(:meth:`NeuralWavelet.diagnostic_reason`) that no front, ``advise`` or site page ranks.

``memory_bytes``: hash tables (or vertex features + their mesh), W, M and the MLP as float32 --
what the paper counts. ``memory_breakdown`` adds everything else the renderer holds: the
G-buffer targets, the mesh buffers, the direct term's BVH (estimated), sampler and tables.

Entry point: ``"neural-wavelet" = "methods.neural_wavelet.method:NeuralWavelet"``. Importing this
module imports no torch, moderngl or mitsuba (``prtbench list`` stays instant).
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass

import numpy as np

from methods.neural_wavelet.data import check_light_split, training_views, without_late_defaults
from methods.neural_wavelet.direct import DirectLight, denoise, direct_counts
from methods.neural_wavelet.gbuffer import GBufferPass, check_constant_materials, pixel_rows
from methods.neural_wavelet.hashgrid import check_table
from methods.neural_wavelet.model import NeuralWaveletModel, PixelInputs
from methods.neural_wavelet.train import resolve_device, train_model
from prtbench.api.config import check_memory, knob, seed_knob
from prtbench.api.errors import InvalidInputError
from prtbench.api.method import (
    Artifact,
    FrameTimes,
    Method,
    Renderer,
    register_method,
    wall_frame_times,
)
from prtbench.render import ops
from prtbench.render.reference import render_reference
from prtbench.transport.wavelet import haar
from prtbench.transport.wavelet.cubemap import check_resolution, light_cubemap
from prtbench.transport.wavelet.selection import select_terms

#: Seed of the direct-only render of ``direct="offline-reference"`` (the runner's reference
#: uses 0) and of the ray-traced direct term's samples.
DIRECT_SEED = 104_729
SELECTIONS = ("magnitude", "area")
DIRECT_TERMS = ("raytraced", "none", "offline-reference")
#: Registered lights trained on by default: none that the demo, sweeps, regress, advise or the
#: site evaluate (sky, sun, white, city, studio; docs/PROTOCOL.md, and a test walks them), plus
#: seeded procedural environments (``random_lights``) for variety.
DEFAULT_TRAIN_LIGHTS = ("purple", "courtyard", "forest", "interior", "night")
DEFAULT_HELDOUT_LIGHTS = ("sunrise", "sunset")
#: Cells of a typical light's sampling table (a 512 × 1024 map), for ``op_counts``.
LIGHT_CELLS = 511 * 1024
#: Knobs that change only how a trained model is rendered: left out of the artifact's key.
RENDER_KNOBS = ("light_terms", "selection", "direct", "direct_spp", "direct_samples",
                "direct_denoise", "render_chunk", "heldout_lights")


@dataclass(frozen=True)
class NeuralWaveletConfig:
    """Knobs of the ``neural-wavelet`` method (paper §4–5; sizes lost in our copy say so)."""

    # --- feature field ------------------------------------------------------------------------
    features: str = knob("hashgrid", "Spatial features H(x): hashgrid (the paper) or vertex "
                         "(features on mesh vertices, barycentric + softplus: its Table 6 "
                         "baseline).", choices=("hashgrid", "vertex"))
    levels: int = knob(16, "Hash-grid levels L (paper: 32).", low=1, high=64)
    features_per_level: int = knob(2, "Features per hash-grid level F (paper: 2).", low=1,
                                   high=16)
    base_resolution: int = knob(16, "Coarsest hash-grid resolution (paper: 16).", low=1,
                                high=4096)
    per_level_scale: float = knob(1.5, "Resolution growth per level (the paper's value is "
                                  "lost in our copy; 1.5 is Müller et al.'s usual).", low=1.0,
                                  high=4.0)
    log2_table: int = knob(19, "T: entries per level at most 2^T (the paper's Table 3 ablates "
                           "it; its value is lost in our copy).", low=4, high=30)
    vertex_features: int = knob(32, "R for features=vertex: learnt features per vertex.",
                                low=1, high=512)
    feature_dim: int = knob(32, "D: columns of M (the paper makes M square: D = R).", low=1,
                            high=1024)
    wavelet_grid: int = knob(0, "Resolution of the 2-D wavelet grid W per face (0: the "
                             "cubemap's, the paper's choice: one vector per wavelet).", low=0,
                             high=1024)
    # --- decoder --------------------------------------------------------------------------------
    hidden: int = knob(128, "Neurons per hidden layer of f_θ (paper: 128).", low=4, high=4096)
    layers: int = knob(2, "Hidden ReLU layers of f_θ (paper: 2).", low=1, high=16)
    reflect_degree: int = knob(4, "SH degree ℓ of the ωr encoding ((ℓ+1)² inputs; −1: ωr is "
                               "not an input). The paper's value is lost in our copy. 4: the "
                               "quick table-nw-4 (−1, 2, 4, 6) does not separate the degrees "
                               "beyond table-nw-seeds' run-to-run spread, and the must-hold "
                               "test passes at 4.", low=-1, high=10)
    # --- lighting -------------------------------------------------------------------------------
    cubemap: int = knob(32, "Cubemap face resolution N of the lighting (6·N² Haar wavelets).",
                        low=1, high=256)
    light_terms: int = knob(64, "k: wavelets used per frame (paper: 64; 32 and 128 too).",
                            low=1, high=6 * 256**2)
    selection: str = knob("magnitude", "How the k terms are chosen: magnitude (the paper's "
                          "unweighted selection) or area (Ng 2003).", choices=SELECTIONS)
    bounces: int = knob(1, "Interreflection bounces of the learnt indirect light (also the "
                        "runner's reference: max_depth = bounces + 2).", low=1, high=16)
    direct: str = knob("raytraced", "Direct light added to the learnt indirect: raytraced "
                       "(the paper's: importance-sampled Embree shadow rays + a denoiser, in "
                       "the frame), none (indirect only) or offline-reference (a Mitsuba "
                       "direct-only render: a diagnostic, never ranked).", choices=DIRECT_TERMS)
    direct_samples: int = knob(4, "direct=raytraced: directions per pixel drawn from the light, "
                               "and as many from the BRDF (MIS). 4: on plants/sky at 128x96 "
                               "the denoised term scores 26.1 dB against Mitsuba's direct-only "
                               "image, 8 gives 26.9 and 16 27.4 at 2x and 4x the rays (2: 25.2).",
                               low=1, high=4096)
    direct_denoise: bool = knob(True, "direct=raytraced: filter the direct term's noise "
                                "(edge-avoiding à-trous, guided by normals, depth and variance).")
    direct_spp: int = knob(256, "direct=offline-reference: samples per pixel of the Mitsuba "
                           "direct-only render.", low=2, high=1 << 16)
    # --- training data --------------------------------------------------------------------------
    train_lights: tuple[str, ...] = knob(DEFAULT_TRAIN_LIGHTS, "Registered lights trained on "
                                         "(each at light_rotations turns).")
    heldout_lights: tuple[str, ...] = knob(DEFAULT_HELDOUT_LIGHTS, "Lights never trained on "
                                           "(evaluation); must not overlap train_lights.")
    light_rotations: int = knob(3, "Turns of each training light about +Y (paper: 0°, 120°, "
                                "240°).", low=1, high=64)
    light_tilt: float = knob(0.0, "Largest tilt (degrees) of turns i >= 1 of each training "
                             "light, about a seeded horizontal axis: moves its sources to other "
                             "elevations (0: turns about +Y only, as the paper).", low=0.0,
                             high=180.0)
    random_lights: int = knob(16, "Seeded procedural environments added to the training lights "
                              "(prtbench.transport.random_lights: random sky, ground and one to three "
                              "sources at random elevations, sizes and colours); the paper "
                              "trains on ~1000 maps where we ship eight.", low=0,
                              high=100_000)
    train_views: int = knob(64, "Training cameras near the scene's trajectory.", low=1,
                            high=100_000)
    lights_per_view: int = knob(2, "Training lights rendered per camera (paper: 2).", low=1,
                                high=64)
    view_jitter: float = knob(20.0, "Degrees a training camera turns away from its trajectory "
                              "view (yaw ±[j/3, j], pitch ±j/2).", low=0.5, high=90.0)
    train_width: int = knob(128, "Training image width.", low=4, high=4096)
    train_height: int = knob(96, "Training image height.", low=4, high=4096)
    train_spp: int = knob(64, "Samples per pixel of each training render (paper: 1024, "
                          "denoised).", low=2, high=1 << 16)
    # --- optimisation ---------------------------------------------------------------------------
    train_terms: int = knob(300, "Wavelets per training step: half the light's largest, half "
                            "uniform (paper: 300).", low=2, high=6 * 256**2)
    batch_pixels: int = knob(2048, "Pixels per training step (paper: 2048).", low=1,
                             high=1 << 20)
    steps: int = knob(4000, "Training steps.", low=1, high=10_000_000)
    learning_rate: float = knob(1e-2, "Adam learning rate, cosine-annealed to 1 %.", low=1e-6,
                                high=1.0)
    loss: str = knob("mulaw", "Training loss: mulaw (the paper's §4: L2 of the μ-law "
                     "tonemapped prediction and target, sign-extended to negatives, so that bright "
                     "regions do not dominate), l2 (L2 on linear radiance) or relative (L2 "
                     "divided by the squared prediction, held constant, plus relative_eps: as "
                     "tonemap-insensitive as mulaw but unbiased on noisy Monte Carlo targets).",
                     choices=("mulaw", "l2", "relative"))
    relative_eps: float = knob(0.01, "ε of loss=relative, in units of the mean training target: "
                               "(pred − target)² / (sg(pred) + ε)².", low=1e-6, high=1e3)
    mulaw_mu: float = knob(5000.0, "μ of the μ-law tonemap log(1 + μ|x|)/log(1 + μ) (Kalantari "
                           "and Ramamoorthi 2017's value; the paper's is lost in our copy).",
                           low=1e-3, high=1e7)
    mulaw_white: float = knob(0.99, "Quantile of the training targets that the μ-law maps to "
                              "1 (x is divided by it; the tonemap expects values in [0, 1]).",
                              low=0.5, high=1.0)
    adaptive_sampling: float = knob(0.5, "Fraction of each batch drawn by view variance and "
                                    "glossiness (0: uniform).", low=0.0, high=1.0)
    device: str = knob("auto", "Torch device: auto (CUDA when available), cpu or cuda.",
                       choices=("auto", "cpu", "cuda"))
    render_chunk: int = knob(4096, "Pixels evaluated together when rendering (bounds memory "
                             "to chunk × k × hidden floats).", low=1, high=1 << 22)
    seed: int = seed_knob("Seed of views, light draws, initialisation and batches.")


PROFILE_OVERRIDES = {
    "smoke": {"cubemap": 8, "levels": 8, "log2_table": 12, "feature_dim": 16, "hidden": 32,
              "vertex_features": 16, "train_lights": ("purple",), "random_lights": 3,
              "heldout_lights": ("sun",), "light_rotations": 2, "train_views": 4,
              "lights_per_view": 1, "train_width": 32, "train_height": 24, "train_spp": 8,
              "train_terms": 32, "light_terms": 16, "batch_pixels": 256, "steps": 80,
              "direct_spp": 32, "direct_samples": 2},
    "quick": {"cubemap": 16, "log2_table": 16, "hidden": 64, "train_views": 48,
              "train_terms": 128, "batch_pixels": 1024, "steps": 1500, "direct_spp": 256},
    "paper": {"cubemap": 64, "levels": 32, "log2_table": 22, "feature_dim": 64,
              "train_views": 2000, "train_width": 512, "train_height": 512, "train_spp": 1024,
              "steps": 200_000, "direct_spp": 1024},
}


@register_method("neural-wavelet")
class NeuralWavelet(Method):
    """Hash grid × wavelet grid (CP) decoded by an MLP, dotted with k lighting wavelets."""

    storage = "network"

    family = "neural PRT"

    Config = NeuralWaveletConfig
    precompute_version = "1"
    views_in_key = True  # its training cameras are derived from the trajectory's views
    main_knobs = ("light_terms", "log2_table")
    paper = ("Raghavan, Wang, Ramamoorthi et al. 2023, Neural free-viewpoint relighting for "
             "glossy indirect illumination (§3-5)")
    light_dependence = "family"
    light_dependence_why = ("the transport is learnt from images under a family of training "
                            "lights; other lights are extrapolated")
    profile_overrides = PROFILE_OVERRIDES

    @classmethod
    def cache_identity(cls, config: NeuralWaveletConfig) -> dict:
        # Knobs added later leave the artifacts trained before them at their old keys; knobs
        # of the rendering alone never retrain.
        knobs = without_late_defaults(super().cache_identity(config))
        return {k: v for k, v in knobs.items() if k not in RENDER_KNOBS}

    @classmethod
    def diagnostic_reason(cls, config: NeuralWaveletConfig) -> str | None:
        if config.direct == "offline-reference":
            return "its direct light is a Mitsuba render: pixels from the reference renderer"
        return None

    @classmethod
    def training_lights(cls, config: NeuralWaveletConfig) -> tuple[str, ...]:
        return tuple(config.train_lights)

    @classmethod
    def training_cameras(cls, scene, config: NeuralWaveletConfig) -> list:
        return training_views(scene, count=config.train_views, jitter=config.view_jitter,
                              seed=config.seed)

    @classmethod
    def validate(cls, scene, config: NeuralWaveletConfig) -> None:
        check_constant_materials(cls.name, scene)
        n = check_resolution(config.cubemap, what="cubemap")
        m = 6 * n * n
        if config.light_terms > m:
            raise InvalidInputError(f"light_terms={config.light_terms} exceeds the {m} wavelet "
                                    f"coefficients of a cubemap={n} (6·N²); accepted: 1..{m}")
        if config.wavelet_grid:
            check_resolution(config.wavelet_grid, what="wavelet_grid")
        check_light_split(config.train_lights, config.heldout_lights)
        if config.features == "hashgrid":

            check_table(levels=config.levels, features=config.features_per_level,
                        base_resolution=config.base_resolution,
                        per_level_scale=config.per_level_scale, log2_table=config.log2_table)
        if scene.n_triangles >= 1 << 24:
            raise InvalidInputError(f"scene '{scene.name}' has {scene.n_triangles} triangles; "
                                    "accepted: < 2^24 (the G-buffer stores the index in a float)")

        work = config.batch_pixels * min(config.train_terms, m) * config.hidden \
            * (config.layers + 1) * 4 * 3
        check_memory(f"method '{cls.name}' batch_pixels={config.batch_pixels} x train_terms="
                     f"{config.train_terms} x hidden={config.hidden}", work,
                     accepted="a smaller batch_pixels, train_terms or hidden")

    @classmethod
    def precompute(cls, scene, config: NeuralWaveletConfig, *, progress: bool = True
                   ) -> Artifact:

        cls.validate(scene, config)
        arrays, stats = train_model(scene, config, progress=progress)
        if progress:

            print(f"[neural-wavelet] {config.features}: {stats['data_images']} training images "
                  f"({stats['data_rows']} pixels, Mitsuba {stats['data_render_s']:.1f} s), "
                  f"{config.steps} steps in {stats['train_s']:.1f} s on {stats['device']} "
                  f"({stats['pixels_per_s']:.0f} pixels/s); loss {stats['loss_first']:.4g} -> "
                  f"{stats['loss_last']:.4g}", file=sys.stderr, flush=True)
        return Artifact(cls.name, arrays, stats)

    @classmethod
    def op_counts(cls, config: NeuralWaveletConfig, *, scene_vertices: int,
                  scene_triangles: int, covered_pixels: int, width: int, height: int,
                  memory_bytes: int):
        """The G-buffer draw (4 RGBA32F targets read back), then per covered pixel: the field
        (hash grid: 8 fetches of F features per level and the trilinear weights; vertex: 3
        fetches of R, the barycentrics, softplus), the per-pixel half of the first layer and
        SH(ωr); per pixel and selected wavelet: H ⊙ W (R), M (R·D), the wavelet half of the
        first layer (D·hidden), the hidden layers, the RGB output and the dot product with L.
        The light's Haar transform and selection are per frame (6N² log N). The ray-traced
        direct term per covered pixel: :func:`methods.neural_wavelet.direct.direct_counts`."""

        k, hidden = config.light_terms, config.hidden
        if config.features == "hashgrid":
            rank = config.levels * config.features_per_level
            field = {"madds": float(config.levels * (8 * (config.features_per_level + 3) + 12)),
                     "fetches": float(8 * config.levels), "bytes": 0.0}
        else:
            rank = config.vertex_features
            field = {"madds": float(3 * rank + 30 + rank * ops.TRANSCENDENTAL_MADDS),
                     "fetches": 3.0, "bytes": 0.0}
        sh = (config.reflect_degree + 1) ** 2 if config.reflect_degree >= 0 else 0
        per_pixel = ops.add_counts(field, {"madds": float((sh + 10) * hidden + 4 * sh + 12)})
        per_term = {"madds": float(rank + rank * config.feature_dim
                                   + config.feature_dim * hidden + hidden
                                   + (config.layers - 1) * (hidden * hidden + hidden)
                                   + 3 * hidden + 3 + 3), "fetches": 1.0, "bytes": 0.0}
        n = 6 * config.cubemap ** 2
        return ops.add_counts(
            ops.raster_counts(vertices=scene_vertices, triangles=scene_triangles,
                               pixels=covered_pixels, varyings=10, vertex_bytes=52),
            {"bytes": float(4 * 16 * width * height)},  # the G-buffer read back
            ops.scaled(ops.add_counts(per_pixel, ops.scaled(per_term, k)), covered_pixels),
            {"madds": float(n * 2 * max(config.cubemap.bit_length(), 1) + n)},
            ops.scaled(direct_counts(samples=config.direct_samples, triangles=scene_triangles,
                                     light_cells=LIGHT_CELLS, denoised=config.direct_denoise),
                       covered_pixels if config.direct == "raytraced" else 0),
            {"bytes": float(memory_bytes)})

    @classmethod
    def renderer(cls, scene, artifact: Artifact, config: NeuralWaveletConfig, *, width: int,
                 height: int) -> "NeuralWaveletRenderer":
        return NeuralWaveletRenderer(scene, artifact.arrays, config, width=width, height=height)


class NeuralWaveletRenderer(Renderer):
    """GL G-buffer → the direct term (shadow rays) + torch T for the k selected wavelets per
    covered pixel → Σ L_j T_j."""

    def __init__(self, scene, arrays, config: NeuralWaveletConfig, *, width: int, height: int):
        import torch

        self.torch = torch
        self.scene, self.config = scene, config
        self.width, self.height = int(width), int(height)
        self.device = resolve_device(config.device)
        self.model = NeuralWaveletModel.from_arrays(arrays, device=self.device)
        self.gpass = GBufferPass(scene, width=self.width, height=self.height)
        self.ctx = self.gpass.ctx
        where = (torch.cuda.get_device_name(self.device) if self.device != "cpu"
                 else f"CPU ({torch.get_num_threads()} threads)")
        self.renderer_string = f"{self.gpass.renderer_string} + torch {where}"
        self.weights = None
        if config.selection == "area":
            self.weights = haar.support_solid_angles(config.cubemap).reshape(-1)
        self._cubes: dict[str, np.ndarray] = {}
        self._offline: dict[tuple, np.ndarray] = {}
        self.direct = (DirectLight(scene, light_samples=config.direct_samples,
                                   brdf_samples=config.direct_samples, seed=DIRECT_SEED)
                       if config.direct == "raytraced" else None)
        self.last_terms: np.ndarray | None = None
        self.frame_components = {}
        self._parts: dict[str, float] = {}

    def light_cube(self, light, *, force: bool = False) -> np.ndarray:
        """(3, 6, N, N) texel-mean radiance of ``light`` (per light, not per frame)."""
        key = light.content_hash()
        if force or key not in self._cubes:
            self._cubes = {key: np.ascontiguousarray(
                np.moveaxis(light_cubemap(light, self.config.cubemap), -1, 0))}
        return self._cubes[key]

    def light_change(self, light) -> bool:
        """A new light's cubemap resampling and, for the ray-traced direct term, its sampler."""
        self.light_cube(light, force=True)
        if self.direct is not None:
            self.direct.set_light(light, force=True)
        return True

    def offline_direct(self, view, light) -> np.ndarray:
        """The Mitsuba direct-only render (H, W, 3) of the diagnostic ``offline-reference``."""
        key = (view, light.content_hash())
        if key not in self._offline:
            ref = render_reference(self.scene, light, view, width=self.width,
                                   height=self.height, spp=self.config.direct_spp, bounces=0,
                                   seed=DIRECT_SEED)
            self._offline = {key: ref.image}
        return self._offline[key]

    def _tick(self, name: str, start: float) -> float:
        now = time.perf_counter()
        self._parts[name] = self._parts.get(name, 0.0) + (now - start) * 1e3
        return now

    def frame(self, view, light) -> tuple[np.ndarray, np.ndarray]:
        """(indirect, direct) radiance (H, W, 3) each, row 0 at the top: one frame's work."""
        torch, w, h = self.torch, self.width, self.height
        start = time.perf_counter()
        self.gpass.draw(view)
        gbuffer = self.gpass.read_gl()  # GL order: bottom row first
        rows = pixel_rows(gbuffer, view.eye)
        start = self._tick("gbuffer + readback", start)
        direct = np.zeros((h * w, 3), np.float32)
        if self.direct is not None and len(rows["pixel"]):
            radiance, variance = self.direct.radiance(rows, light)
            start = self._tick("direct: rays + shading", start)
            if self.config.direct_denoise:
                covered = np.zeros(h * w, bool)
                covered[rows["pixel"]] = True
                image = np.zeros((h * w, 3), np.float32)
                image[rows["pixel"]] = radiance
                var = np.zeros(h * w, np.float32)
                var[rows["pixel"]] = variance
                normals = np.zeros((h * w, 3), np.float32)
                normals[rows["pixel"]] = rows["normals"]
                depth = np.zeros(h * w, np.float32)
                depth[rows["pixel"]] = np.linalg.norm(
                    rows["positions"] - np.asarray(view.eye, np.float32)[None], axis=1)
                radiance = denoise(image.reshape(h, w, 3), var.reshape(h, w),
                                   covered=covered.reshape(h, w),
                                   normals=normals.reshape(h, w, 3),
                                   depth=depth.reshape(h, w)).reshape(-1, 3)[rows["pixel"]]
                start = self._tick("direct: denoise", start)
            direct[rows["pixel"]] = radiance
        coeffs = haar.forward(self.light_cube(light)).reshape(3, -1).T  # (6N², 3)
        rule = {"support": self.weights} if self.config.selection == "area" else {}
        terms = select_terms(coeffs, self.config.light_terms, rule=self.config.selection,
                             **rule)
        self.last_terms = terms
        start = self._tick("light: haar + selection", start)
        lj = torch.as_tensor(coeffs[terms], dtype=torch.float32, device=self.device)
        indirect = np.zeros((h * w, 3), np.float32)
        n = len(rows["pixel"])
        if n:
            def t(key, dtype=torch.float32):
                return torch.as_tensor(rows[key], dtype=dtype, device=self.device)

            inputs = PixelInputs(t("positions"), t("normals"), t("wo"), t("kd"), t("ks"),
                                 t("shininess"), t("triangles", torch.int64))
            out = []
            with torch.no_grad():
                for first in range(0, n, self.config.render_chunk):
                    part = inputs.rows(slice(first, first + self.config.render_chunk))
                    out.append(self.model.radiance(part, terms, lj))
                radiance = torch.cat(out).cpu().numpy()
            indirect[rows["pixel"]] = radiance
        self._tick("indirect: network + dot", start)
        return indirect.reshape(h, w, 3)[::-1], direct.reshape(h, w, 3)[::-1]

    def indirect(self, view, light) -> np.ndarray:
        """The learnt indirect radiance (H, W, 3), row 0 at the top."""
        return self.frame(view, light)[0]

    def render(self, view, light) -> np.ndarray:
        indirect, direct = self.frame(view, light)
        image = indirect + direct
        if self.config.direct == "offline-reference":
            image = image + self.offline_direct(view, light)
        return np.ascontiguousarray(image, dtype=np.float32)

    def frame_time(self, view, light, *, warmup: int, frames: int) -> FrameTimes:
        """Host clock around whole frames: the G-buffer draw and readback, the direct term's
        rays, shading and denoiser, the light's Haar transform and selection, host → device,
        the network, the dot product, device → host and the compositing. Per frame part, the
        median over the timed frames is kept in :attr:`frame_components`. (The diagnostic
        ``offline-reference`` image is rendered once, outside the frame.)"""
        if int(warmup) != warmup or warmup < 1 or int(frames) != frames or frames < 1:
            raise InvalidInputError(f"warmup={warmup!r}, frames={frames!r}; accepted: "
                                    "integers >= 1")
        torch = self.torch
        if self.config.direct == "offline-reference":
            self.offline_direct(view, light)
        samples: list[dict[str, float]] = []

        def frame() -> None:
            self._parts = {}
            self.render(view, light)
            self.ctx.finish()
            if self.device != "cpu":
                torch.cuda.synchronize()
            samples.append(dict(self._parts))

        times = wall_frame_times(frame, warmup=int(warmup), frames=frames,
                                 renderer=self.renderer_string, source="wall+sync")
        timed = samples[-int(frames):]
        self.frame_components = {k: float(np.median([s.get(k, 0.0) for s in timed]))
                                 for k in timed[0]} if timed else {}
        return times

    def memory_bytes(self) -> int:
        """Field (hash tables, or vertex features + mesh) + W + M + MLP, float32."""
        return int(sum(self.model.resident_bytes().values()))

    def memory_breakdown(self) -> dict[str, int]:
        parts = super().memory_breakdown()
        if self.direct is not None:
            parts["cpu: direct.bvh (estimated)"] = self.direct.bvh_bytes
        return parts

    def release(self) -> None:
        self.gpass.release()
