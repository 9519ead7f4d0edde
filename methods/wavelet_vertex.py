"""Wavelet vertex PRT (Ng, Ramamoorthi and Hanrahan 2003): all-frequency shadows at vertices.

Precompute: per vertex, the shadowed diffuse transport V·max(n·ω, 0) integrated over every
texel of a 6×N×N cubemap (one embree ray per texel, or S×S), Haar-transformed per face,
truncated to the ``keep`` largest coefficients, quantised (``storage``) and stored as sparse
columns (:mod:`prtbench.wavelet`).

Render, each frame: the light's cubemap (its lat-long map integrated over each texel, cached per
light like an SH projection) is Haar-transformed, its ``light_terms`` = k most important
coefficients are selected by ``selection`` (non-linear approximation: the set changes with the
light), the sparse product B_v = kd/π · Σ_{i in k} T_vi L_i is formed on the CPU
(:meth:`SparseTransport.relight`, vectorised numpy, cost ∝ stored entries of the k columns),
uploaded as per-vertex radiance and rasterised (GL, interpolated per vertex like ``vertex``).

Timing: ``frame_time`` is the host clock around the whole frame — light Haar transform,
selection, sparse product, upload, draw and glFinish — because the relighting is CPU work that
a GPU timer query would not see (the lat-long → cubemap resampling is per light, not per frame,
and is not timed, as the SH projection of ``vertex`` is not).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from statistics import fmean, median

import numpy as np

from prtbench.config import check_memory, knob
from prtbench.errors import InvalidInputError
from prtbench.method import Artifact, FrameTimes, Method, register_method
from prtbench.wavelet.sparse import SparseTransport

from ._raster import RasterRenderer

SELECTIONS = ("magnitude", "area", "transport")
STORAGES = ("float32", "float16", "int8")
#: Memory of a chunk's ray buffers and Haar work arrays on top of the stored transport (bytes).
_WORKING_BYTES = 512 << 20


@dataclass(frozen=True)
class WaveletVertexConfig:
    """Knobs of the ``wavelet-vertex`` method."""

    cubemap: int = knob(32, "Cubemap face resolution N, a power of two (6·N² texels and Haar "
                            "coefficients; the papers use 32 and 64).", low=1, high=1024)
    texel_samples: int = knob(1, "Rays per texel side S (S×S visibility rays per texel, "
                                 "area-element weighted); 1 = one ray through the texel centre.",
                              low=1, high=16)
    keep: float = knob(0.25, "Transport coefficients kept per vertex: a fraction in (0, 1] of "
                             "the 6·N², or an integer count > 1 (largest magnitudes; exact zeros "
                             "are never stored).", low=1e-9, high=6 * 1024**2)
    light_terms: int = knob(100, "k: lighting wavelet coefficients used per frame (non-linear "
                                 "approximation; at most 6·N²).", low=1, high=6 * 1024**2)
    selection: str = knob("area", "How the k lighting terms are chosen each frame: largest "
                                  "magnitude, area-weighted magnitude (Ng 2003) or "
                                  "transport-weighted magnitude (× mean |T| over vertices).",
                          choices=SELECTIONS)
    storage: str = knob("float16", "Stored transport value type (int8 uses a per-vertex scale).",
                        choices=STORAGES)
    visibility: bool = knob(True, "Trace occlusion. False: unshadowed transport (V = 1), the "
                                  "trivial image the regression gate must beat.")


def _check_config(scene, config: WaveletVertexConfig) -> tuple[int, int]:
    """(coefficients per vertex, kept per vertex); one-line errors for bad values."""
    from prtbench.wavelet.cubemap import check_resolution
    from prtbench.wavelet.sparse import VALUE_BYTES, row_dtype
    from prtbench.wavelet.transport import keep_count

    n = check_resolution(config.cubemap, what="cubemap")
    m = 6 * n * n
    if config.light_terms > m:
        raise InvalidInputError(f"light_terms={config.light_terms} exceeds the {m} wavelet "
                                f"coefficients of a cubemap={n} (6·N²); accepted: 1..{m}")
    kept = keep_count(config.keep, m)
    vertices = scene.n_vertices
    entry = VALUE_BYTES[config.storage] + row_dtype(vertices).itemsize
    # Stored entries at most (vertices × kept), built from per-chunk triples (int64 point and
    # coefficient, float64 value: 24 bytes) and sorted once: ~2 copies of those at the peak.
    need = vertices * kept * (entry + 2 * 24) + _WORKING_BYTES
    check_memory(f"method 'wavelet-vertex' cubemap={n} keep={config.keep:g} ({kept} of {m} "
                 f"coefficients) on {vertices} vertices", need,
                 accepted="a smaller cubemap or keep")
    return m, kept


@register_method("wavelet-vertex")
class WaveletVertex(Method):
    """Ng 2003 Haar-wavelet transport at vertices, relit with k selected lighting terms."""

    Config = WaveletVertexConfig
    precompute_version = "1"
    main_knobs = ("light_terms", "cubemap")
    summary = "Ng 2003 all-frequency Haar-wavelet transport at vertices, k lighting terms per frame"
    paper = ("Ng, Ramamoorthi and Hanrahan 2003, All-Frequency Shadows Using Non-linear Wavelet "
             "Lighting Approximation (SIGGRAPH 2003): diffuse vertex transport, cubemap Haar, "
             "k-term lighting")
    profile_overrides = {
        "smoke": {"cubemap": 16, "light_terms": 64},
        "quick": {"cubemap": 32},
        "paper": {"cubemap": 64, "texel_samples": 2},
    }
    #: As ``vertex``: a sun's sharp shadows on a 32×32 ground make shadowing the measured
    #: difference from the unshadowed render.
    regression_case = {"scene": "plants", "variant": "diffuse", "light": "sun",
                       "scene_params": {"ground_subdivisions": 32}}

    @classmethod
    def validate(cls, scene, config: WaveletVertexConfig) -> None:
        for obj in scene.objects:
            if obj.material.is_glossy:
                raise InvalidInputError(
                    f"method 'wavelet-vertex' renders diffuse materials only, but scene "
                    f"'{scene.name}' variant '{scene.variant}' has glossy '{obj.name}'; use "
                    "--variant diffuse")
            if obj.material.is_textured:
                raise InvalidInputError(
                    f"method 'wavelet-vertex' takes constant kd per object; '{obj.name}' in "
                    f"scene '{scene.name}' is textured")
        _check_config(scene, config)

    @classmethod
    def precompute(cls, scene, config: WaveletVertexConfig, *, progress: bool = True) -> Artifact:
        from prtbench.cache import cached_arrays, content_key
        from prtbench.wavelet.transport import TRANSPORT_VERSION, compute_wavelet_transport

        cls.validate(scene, config)  # also when called directly, before any ray
        m, kept = _check_config(scene, config)
        positions, normals, _, _ = scene.merged()

        def compute() -> dict[str, np.ndarray]:
            transport, stats = compute_wavelet_transport(
                scene, positions, normals, n=config.cubemap, keep=config.keep,
                texel_samples=config.texel_samples, storage=config.storage,
                visibility=config.visibility, progress=progress)
            return {**transport.arrays(), "rays": np.array(stats["rays"]),
                    "trace_s": np.array(stats["trace_s"])}

        # Keyed by the precompute knobs only: changing light_terms or selection (render-time
        # knobs) reuses the transport, credited at its recorded compute time.
        key = content_key("wavelet-vertex-transport", TRANSPORT_VERSION, scene.content_hash(),
                          config.cubemap, kept, config.texel_samples, config.storage,
                          bool(config.visibility))
        arrays = cached_arrays("wavelet-transport", key, compute)
        rays, trace_s = int(arrays.pop("rays")), float(arrays.pop("trace_s"))
        transport = SparseTransport.from_arrays(arrays)
        dense = len(positions) * m * 4  # the float32 matrix this replaces
        return Artifact("wavelet-vertex", transport.arrays(),
                        {"vertices": int(len(positions)), "coefficients": m,
                         "kept_per_vertex": kept, "stored_entries": transport.nnz,
                         "stored_bytes": transport.nbytes, "dense_float32_bytes": dense,
                         "rays": rays, "trace_s": trace_s})

    @classmethod
    def renderer(cls, scene, artifact: Artifact, config: WaveletVertexConfig, *, width: int,
                 height: int) -> "WaveletVertexRenderer":
        return WaveletVertexRenderer(scene, artifact, config, width=width, height=height)


class WaveletVertexRenderer(RasterRenderer):
    """CPU k-term sparse relighting per vertex, rasterised with per-vertex radiance."""

    def __init__(self, scene, artifact: Artifact, config: WaveletVertexConfig, *, width: int,
                 height: int):
        from prtbench.wavelet import haar
        self.config = config
        self.transport = SparseTransport.from_arrays(artifact.arrays)
        n = config.cubemap
        super().__init__(scene, width=width, height=height, vertex_shader="wavelet_vertex.vert",
                         fragment_shader="vertex_prt.frag", defines={})
        # Per-coefficient weights of the selection rule: resident, read every frame.
        if config.selection == "area":
            self.weights = haar.support_solid_angles(n).reshape(-1).astype(np.float32)
        elif config.selection == "transport":
            self.weights = self.transport.column_mean_abs()
        else:
            self.weights = None
        self.incident = self.ctx.buffer(reserve=12 * self.transport.n_points)
        self._resident = [self.incident]
        self._cubes: dict[str, np.ndarray] = {}
        #: Terms selected in the last frame (inspection and tests).
        self.last_terms: np.ndarray | None = None

    def _light_cube(self, light) -> np.ndarray:
        """(3, 6, N, N) texel-mean radiance of ``light`` (per light, not per frame)."""
        from prtbench.wavelet.cubemap import light_cubemap

        key = light.content_hash()
        if key not in self._cubes:
            self._cubes = {key: np.ascontiguousarray(
                np.moveaxis(light_cubemap(light, self.config.cubemap), -1, 0))}
        return self._cubes[key]

    def relight(self, light) -> np.ndarray:
        """(V, 3) float32 Σ_{i in k} T_vi L_i for ``light``: the per-frame CPU work."""
        from prtbench.wavelet import haar
        from prtbench.wavelet.selection import select_terms

        coeffs = haar.forward(self._light_cube(light)).reshape(3, -1).T  # (6N², 3)
        rule = {"area": {"support": self.weights},
                "transport": {"transport_weight": self.weights}}.get(self.config.selection, {})
        terms = select_terms(coeffs, self.config.light_terms, rule=self.config.selection, **rule)
        self.last_terms = terms
        return self.transport.relight(coeffs, terms).astype(np.float32)

    def _bind(self, view, light) -> None:
        self.incident.write(np.ascontiguousarray(self.relight(light)).tobytes())
        self.incident.bind_to_storage_buffer(0)

    def frame_time(self, view, light, *, warmup: int, frames: int) -> FrameTimes:
        """Host clock around whole frames (CPU relighting + upload + draw + glFinish)."""
        if int(warmup) != warmup or warmup < 1 or int(frames) != frames or frames < 1:
            raise InvalidInputError(f"warmup={warmup!r}, frames={frames!r}; accepted: "
                                    "integers >= 1")
        self._light_cube(light)  # per light, outside the frame
        for _ in range(int(warmup)):
            self._draw(view, light)
        self.ctx.finish()
        samples = []
        for _ in range(int(frames)):
            start = time.perf_counter()
            self._draw(view, light)
            self.ctx.finish()
            samples.append((time.perf_counter() - start) * 1e3)
        return FrameTimes(float(median(samples)), float(np.percentile(samples, 95)),
                          float(fmean(samples)), int(frames), self.renderer_string,
                          "wall+finish")

    def memory_bytes(self) -> int:
        """Sparse transport + selection weights + the per-vertex radiance buffer."""
        weights = 0 if self.weights is None else int(self.weights.nbytes)
        return int(self.transport.nbytes + weights + self.incident.size)
