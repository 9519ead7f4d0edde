"""Wavelet image relighting (Ng, Ramamoorthi and Hanrahan 2003, §5): one fixed view, glossy.

Precompute, for the scene's one view at the knobs' ``width`` × ``height``: a ray-cast G-buffer
(the pixel-centre rays of :meth:`View.primary_rays`, the same rays as the masked metrics'
geometry mask; back faces stay black, surfaces being one-sided), then at every covered pixel
and every texel t of a 6×N×N cubemap the transport for that pixel's view direction ωo::

    T_t(p) = ∫_texel V(p, ω) max(n·ω, 0) f(ω, ωo) dω,   f = kd/π + ks·(s+1)/(2π)·max(ω·r, 0)^s

(DESIGN.md §4). f is linear in kd and ks, so each pixel stores two scalar transports, the
*lobes* ``D_t = ∫ V·cos`` and ``S_t = ∫ V·cos·(s+1)/(2π)·max(ω·r, 0)^s`` (r = reflect(ωo, n);
S only in scenes with a glossy object, and only its non-zero entries: diffuse pixels store
none), and a frame forms B = kd/π · Σ D̂_i L̂_i + ks · Σ Ŝ_i L̂_i per RGB channel. The rays
are traced once for both lobes; the solid angles are folded into the transport
(:mod:`prtbench.transport.wavelet`), which is Haar-transformed, truncated to ``keep`` per lobe row,
quantised (``storage``) and stored as sparse columns like ``wavelet-vertex``'s.

Render, each frame: the k = ``light_terms`` lighting coefficients picked by ``selection`` (Ng
2003's non-linear approximation) in a sparse product per pixel, written into the image (CPU,
vectorised numpy: there is nothing to rasterise). ``lighting='sh'`` instead replaces the
light by its first ``sh_bands``² spherical harmonics (linear approximation, resampled to the
cubemap) and uses all its wavelet terms: the SH row of Ng 2003's comparison (lecture slide 33).

Only relighting: the view is fixed at precompute time, so asking for more than one view is an
error naming ``wavelet-tp`` (Ng 2004, changing view). No interreflection: only direct light
(``bounces`` is not a knob; the reference is direct-only).

Timing: ``frame_time`` is the host clock around the whole frame (light Haar transform,
selection, sparse product, image composition); the per-light lat-long → cubemap resampling is
not timed, as the SH methods' light projection is not.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from methods.wavelet import counts
from methods.wavelet.gbuffer import pixel_gbuffer
from methods.wavelet.relight import SELECTIONS, STORAGES, Relighter, check_wavelet_config
from prtbench.api.cache import cached_arrays, content_key
from prtbench.api.config import knob
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
from prtbench.transport.sh import eval_sh, phong_lobe
from prtbench.transport.wavelet.cubemap import check_resolution, subsample_pattern
from prtbench.transport.wavelet.sparse import SparseTransport
from prtbench.transport.wavelet.transport import cached_transport, cosines

LIGHTINGS = ("wavelet", "sh")
#: Bump when the per-pixel transport (G-buffer, lobes) changes (part of its cache key).
IMAGE_TRANSPORT_VERSION = 2
#: Subsamples per texel side of the SH lighting's texel means (lighting='sh').
SH_TEXEL_SAMPLES = 2


@dataclass(frozen=True)
class WaveletImageConfig:
    """Knobs of the ``wavelet-image`` method."""

    cubemap: int = knob(32, "Cubemap face resolution N, a power of two (6·N² texels and Haar "
                            "coefficients; Ng 2003 uses 32 and 64).", low=1, high=1024)
    width: int = knob(320, "Width in pixels of the fixed view's image the transport is "
                           "precomputed for (the run must render at width × height).",
                      low=8, high=8192)
    height: int = knob(240, "Height in pixels of the fixed view's image.", low=8, high=8192)
    texel_samples: int = knob(1, "Rays per cubemap texel side S (S×S visibility rays per "
                                 "texel, area-element weighted).", low=1, high=16)
    keep: float = knob(0.25, "Transport coefficients kept per pixel and lobe: a fraction in "
                             "(0, 1] of the 6·N², or an integer count > 1 (largest "
                             "magnitudes; exact zeros are never stored).", low=1e-9,
                       high=6 * 1024**2)
    light_terms: int = knob(100, "k: lighting wavelet coefficients used per frame (non-linear "
                                 "approximation; at most 6·N²; lighting='sh' uses all).",
                            low=1, high=6 * 1024**2)
    selection: str = knob("area", "How the k lighting terms are chosen each frame (see "
                                  "wavelet-vertex).", choices=SELECTIONS)
    storage: str = knob("float16", "Stored transport value type (int8 uses a per-row scale).",
                        choices=STORAGES)
    visibility: bool = knob(True, "Trace occlusion. False: unshadowed transport (V = 1), the "
                                  "trivial image the regression gate must beat.")
    lighting: str = knob("wavelet", "Lighting approximation: 'wavelet' (k terms chosen per "
                                    "frame) or 'sh' (linear: the light's first sh_bands² SH "
                                    "terms, resampled to the cubemap, all wavelet terms used).",
                         choices=LIGHTINGS)
    sh_bands: int = knob(8, "SH bands of lighting='sh' (sh_bands² terms; the light projection "
                            "stops at 64 bands).", low=1, high=64)


def _lobes(scene) -> int:
    """Transport rows per pixel: 2 (diffuse, specular) with a glossy object, else 1."""
    return 2 if any(o.material.is_glossy for o in scene.objects) else 1


def _view_dict(view) -> dict:
    return {k: [float(x) for x in v] if isinstance(v, tuple) else float(v)
            for k, v in dataclasses.asdict(view).items()}


@register_method("wavelet-image")
class WaveletImage(Method):
    """Ng 2003 per-pixel Haar transport for one fixed view (glossy), relit with k terms."""

    storage = "per-pixel"

    family = "wavelet PRT"

    Config = WaveletImageConfig
    precompute_version = "1"
    main_knobs = ("light_terms", "cubemap")
    paper = ("Ng, Ramamoorthi and Hanrahan 2003, All-Frequency Shadows Using Non-linear Wavelet "
             "Lighting Approximation (SIGGRAPH 2003): image relighting, per-pixel transport "
             "with the BRDF of a fixed view, k-term lighting")
    profile_overrides = {
        "smoke": {"cubemap": 16, "light_terms": 64, "width": 64, "height": 48},
        "quick": {"cubemap": 32, "width": 320, "height": 240},
        "paper": {"cubemap": 64, "texel_samples": 2, "width": 1920, "height": 1080},
    }
    regression_case = {"scene": "plants", "variant": "diffuse", "light": "sun",
                       "scene_params": {"ground_subdivisions": 32}}

    fixed_view = True  # the view is part of the artifact's cache key
    #: Knobs read only when rendering: left out of the artifact's cache key, so every
    #: lighting approximation of one transport shares one artifact.
    render_knobs = ("light_terms", "selection", "lighting", "sh_bands")

    @classmethod
    def cache_identity(cls, config: WaveletImageConfig) -> dict:
        return {k: v for k, v in super().cache_identity(config).items()
                if k not in cls.render_knobs}

    @classmethod
    def validate(cls, scene, config: WaveletImageConfig) -> None:
        views = len(scene.trajectory)
        if views != 1:
            raise InvalidInputError(
                f"method 'wavelet-image' relights one fixed view (its transport is per pixel of "
                f"that view), but {views} views were asked; accepted: --views 1, or method "
                "'wavelet-tp' for a changing view")
        for obj in scene.objects:
            if obj.material.normal_map is not None:
                raise InvalidInputError(f"method 'wavelet-image' does not apply normal maps; "
                                        f"'{obj.name}' in scene '{scene.name}' has one")
        _check_config(scene, config)

    @classmethod
    def validate_resolution(cls, config: WaveletImageConfig, *, width: int, height: int) -> None:
        """The run must render the image the transport is precomputed for."""
        if (int(width), int(height)) != (config.width, config.height):
            raise InvalidInputError(
                f"method 'wavelet-image' precomputes its transport for {config.width}x"
                f"{config.height} pixels (knobs width, height) but the run renders "
                f"{width}x{height}; accepted: --set width={width} --set height={height}, or "
                f"--res {config.width}x{config.height}")

    @classmethod
    def precompute(cls, scene, config: WaveletImageConfig, *, progress: bool = True) -> Artifact:
        cls.validate(scene, config)
        m, kept = _check_config(scene, config)
        view = scene.trajectory.views[0]
        g = pixel_gbuffer(scene, view, width=config.width, height=config.height)
        lobes = _lobes(scene)

        def specular(sl: slice, dirs_t: np.ndarray) -> np.ndarray:
            lobe = phong_lobe(cosines(g["reflect"][sl], dirs_t), g["shininess"][sl, None])
            lobe *= g["glossy"][sl, None]  # diffuse pixels: exact zeros, never stored
            return np.stack([np.ones_like(lobe), lobe], axis=1).astype(np.float32)

        # Keyed by the precompute knobs only: render-time knobs (light_terms, selection,
        # lighting, sh_bands) reuse the transport, credited at its recorded compute time.
        transport, rays, trace_s = cached_transport(
            "wavelet-image-transport", IMAGE_TRANSPORT_VERSION, scene.content_hash(),
            _view_dict(view), config.width, config.height, config.cubemap, kept,
            config.texel_samples, config.storage, bool(config.visibility), scene=scene,
            points=g["positions"], normals=g["normals"], config=config, progress=progress,
            lobes=specular if lobes == 2 else None, n_lobes=lobes)
        pixels = len(g["pixels"])
        return Artifact("wavelet-image", {**transport.arrays(), "pixels": g["pixels"],
                                          "kd": g["kd"], "ks": g["ks"]},
                        {"pixels": pixels, "lobes": lobes, "coefficients": m,
                         "kept_per_row": kept, "stored_entries": transport.nnz,
                         "stored_bytes": transport.nbytes,
                         "dense_float32_bytes": pixels * lobes * m * 4, "rays": rays,
                         "trace_s": trace_s, "view": _view_dict(view),
                         "width": config.width, "height": config.height})

    @classmethod
    def op_counts(cls, config: WaveletImageConfig, *, scene_vertices: int,
                  scene_triangles: int, covered_pixels: int, width: int, height: int,
                  memory_bytes: int):
        """The frame is CPU work only (no raster, no upload, no readback): the light's Haar
        transform and the selection of its k terms (:func:`methods.wavelet.counts.light_counts`;
        ``lighting='sh'`` uses all 6N² terms of the SH light's cubemap: its scores, no partial
        sort; either cubemap is per light, not counted), the sparse product over the k
        selected columns for every covered pixel's transport rows
        (:func:`~methods.wavelet.counts.sparse_product_counts`, at most min(k, kept) stored
        entries per row), then per pixel kd/π ⊙ D + ks ⊙ S (3 + 3 RGB madds, the float32 kd,
        ks and rows read) written into the image at its index.

        The covered pixels are the transport's pixels (the same pixel-centre rays as the
        geometry mask). The facts do not tell whether the scene has a glossy object, so both
        lobes are counted for every pixel (the bound: a diffuse scene has one row per pixel,
        and a glossy scene's diffuse pixels store no specular entries). ``memory_bytes`` is not
        counted as read: a frame touches only the k selected columns."""

        m = counts.coefficients(config.cubemap)
        k = m if config.lighting == "sh" else min(config.light_terms, m)
        selection = "magnitude" if config.lighting == "sh" else config.selection
        rows = 2 * covered_pixels
        entries = counts.entries_per_point(k, counts.kept_per_point(config.keep, m))
        per_pixel = {"madds": 6.0, "fetches": 0.0,
                     "bytes": float(4 * counts.RGB32_BYTES + 8 + counts.RGB32_BYTES)}
        return ops.add_counts(
            counts.light_counts(cubemap=config.cubemap, terms=k, selection=selection),
            counts.sparse_product_counts(points=rows, terms=k, entries_per_point=entries,
                                         storage=config.storage),
            ops.scaled(per_pixel, covered_pixels))

    @classmethod
    def renderer(cls, scene, artifact: Artifact, config: WaveletImageConfig, *, width: int,
                 height: int) -> "WaveletImageRenderer":
        cls.validate_resolution(config, width=width, height=height)
        return WaveletImageRenderer(artifact, config)


def _check_config(scene, config: WaveletImageConfig) -> tuple[int, int]:
    """(coefficients per row, kept per row); the memory bound counts every pixel (the covered
    ones are unknown before the G-buffer)."""
    rows = config.width * config.height * _lobes(scene)
    return check_wavelet_config("wavelet-image", config, points=rows,
                                what=f"pixel rows at most ({config.width}x{config.height} "
                                     f"pixels × {_lobes(scene)} lobes)")


def sh_light_cubemap(light, n: int, bands: int) -> np.ndarray:
    """(6, N, N, 3) texel means of the light's ``bands``-band SH projection (linear
    approximation), cached per (light, N, bands). The projection is the light's own
    (:meth:`EnvironmentLight.sh`, exact quadrature of the lat-long map), evaluated at
    :data:`SH_TEXEL_SAMPLES`² area-weighted subsamples per texel."""

    n = check_resolution(n)

    def compute() -> dict[str, np.ndarray]:
        coeffs = light.sh(bands)  # (bands², 3) float64
        dirs, weights = subsample_pattern(n, SH_TEXEL_SAMPLES)
        w = weights / weights.sum(axis=-1, keepdims=True)  # (N, N, S²)
        out = np.empty((6, n, n, 3))
        rows = max(1, (1 << 24) // (bands * bands * SH_TEXEL_SAMPLES**2))  # bounds eval_sh
        for f in range(6):
            flat = dirs[f].reshape(-1, 3)
            values = np.concatenate([eval_sh(flat[i:i + rows * SH_TEXEL_SAMPLES**2], bands)
                                     @ coeffs for i in range(0, len(flat),
                                                             rows * SH_TEXEL_SAMPLES**2)])
            out[f] = np.einsum("ijsc,ijs->ijc", values.reshape(n, n, -1, 3), w)
        return {"cube": out}

    key = content_key("sh-light-cubemap", light.content_hash(), n, bands, SH_TEXEL_SAMPLES)
    return cached_arrays("light-cubemap", key, compute)["cube"]


class _ShRelighter(Relighter):
    """Relighter whose light is its SH projection (all wavelet terms of it are used)."""

    def __init__(self, transport: SparseTransport, *, n: int, bands: int):
        super().__init__(transport, SimpleNamespace(cubemap=n, light_terms=6 * n * n,
                                                    selection="magnitude"))
        self.bands = bands

    def light_cube(self, light) -> np.ndarray:
        key = light.content_hash()
        if key not in self._cubes:
            self._cubes = {key: np.ascontiguousarray(
                np.moveaxis(sh_light_cubemap(light, self.n, self.bands), -1, 0))}
        return self._cubes[key]


class WaveletImageRenderer(Renderer):
    """CPU k-term sparse relighting of every covered pixel of the fixed view."""

    renderer_string = "CPU numpy (sparse per-pixel product; no GL)"

    def __init__(self, artifact: Artifact, config: WaveletImageConfig):
        meta, arrays = artifact.meta, artifact.arrays
        self.config = config
        self.width, self.height = int(meta["width"]), int(meta["height"])
        self.view = meta["view"]
        self.lobes = int(meta["lobes"])
        self.transport = SparseTransport.from_arrays(arrays)
        self.pixels = arrays["pixels"]
        self.kd_pi = (arrays["kd"] / np.pi).astype(np.float32)
        self.ks = arrays["ks"].astype(np.float32)
        self.relight = (_ShRelighter(self.transport, n=config.cubemap, bands=config.sh_bands)
                        if config.lighting == "sh" else Relighter(self.transport, config))
        self._image = np.zeros((self.height * self.width, 3), np.float32)

    @property
    def last_terms(self) -> np.ndarray | None:
        """Lighting terms selected in the last frame (inspection and tests)."""
        return self.relight.last_terms

    def _check_view(self, view) -> None:
        if _view_dict(view) != self.view:
            raise InvalidInputError("method 'wavelet-image' relights only the view its "
                                    "transport was precomputed for; accepted: that view, or "
                                    "method 'wavelet-tp' for a changing view")

    def _frame(self, light) -> np.ndarray:
        rows = self.relight(light).reshape(len(self.pixels), self.lobes, 3)
        radiance = self.kd_pi * rows[:, 0]
        if self.lobes == 2:
            radiance += self.ks * rows[:, 1]
        self._image[self.pixels] = radiance
        return self._image

    def render(self, view, light) -> np.ndarray:
        self._check_view(view)
        return self._frame(light).reshape(self.height, self.width, 3).copy()

    def frame_time(self, view, light, *, warmup: int, frames: int) -> FrameTimes:
        """Host clock around whole CPU frames (Haar of the light, selection, product, image)."""
        self._check_view(view)
        if int(warmup) != warmup or warmup < 1 or int(frames) != frames or frames < 1:
            raise InvalidInputError(f"warmup={warmup!r}, frames={frames!r}; accepted: "
                                    "integers >= 1")
        self.relight.light_cube(light)  # per light, outside the frame
        return wall_frame_times(lambda: self._frame(light), warmup=int(warmup), frames=frames,
                                renderer=self.renderer_string, source="cpu-wall")

    def memory_bytes(self) -> int:
        """Sparse transport + selection weights + per-pixel kd, ks and index + the image."""
        return int(self.relight.nbytes + self.pixels.nbytes + self.kd_pi.nbytes
                   + self.ks.nbytes + self._image.nbytes)
