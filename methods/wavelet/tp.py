"""Wavelet triple products (Ng, Ramamoorthi and Hanrahan 2004): all-frequency, changing view.

Direct lighting B(p, ωo) = ∫ L(ω) V(p, ω) ρ̃(ω; n, ωo) dω with three Haar signals on a 6×N×N
cubemap (:mod:`prtbench.transport.wavelet.triple`):

* **V** per vertex (precompute): the texel's visible fraction (one embree ray per texel, or
  S×S; no cosine, no solid angle), Haar-transformed, truncated to ``keep`` and stored sparse
  and quantised like ``wavelet-vertex``
  (:func:`~prtbench.transport.wavelet.transport.compute_wavelet_transport` with ``cosine=False``);
* **ρ̃** the cosine-weighted Phong BRDF of DESIGN.md §4 with the texel solid angles folded in,
  split as kd·D + ks·G (:mod:`prtbench.transport.wavelet.brdf`): the diffuse factor D depends only on
  the (static) normal and is projected once per vertex at precompute; the glossy factor G
  depends on (n, ωo). By default it is projected **per vertex per frame** for the vertex's own
  mirror direction, truncated to ``brdf_keep``: no direction binning, and its cost,
  O(glossy vertices · 6N² · brdf_samples²), is inside the measured frame. With
  ``brdf_table`` = T it is Ng 2004's table instead (:class:`~prtbench.transport.wavelet.brdf.BrdfTable`):
  G precomputed for the normal bins of a 6×T×T cube that the object's normals fall in × all
  6T² mirror-direction bins, looked up nearest per vertex per frame (O(kept) per vertex, the
  table resident and counted in ``memory_bytes``; n and r binned to the table);
* **L** per frame: the light's cubemap Haar-transformed and cut to its ``light_terms`` = k
  most important coefficients by ``selection`` (non-linear approximation, as ``wavelet-vertex``).

Each frame the triple product runs per vertex by the tree algorithm (cost in the stored
coefficients, not 6N²) for D and for G, B = kd ⊙ TP(L, V, D) + ks ⊙ TP(L, V, G) is uploaded
as per-vertex radiance and rasterised (Gouraud, like the other vertex methods).

Timing: ``frame_time`` is the host clock around the whole frame (light Haar transform,
selection, light parent sums, glossy BRDF projection, both triple products, upload, draw,
glFinish); the lat-long → cubemap resampling is per light and not timed, as in
``wavelet-vertex``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from methods.common.materials import validate_constant_materials
from methods.wavelet import SHADER_DIR, counts
from methods.wavelet.relight import (
    SELECTIONS,
    STORAGES,
    Relighter,
    check_wavelet_config,
    host_frame_times,
)
from prtbench.api.config import check_memory, knob
from prtbench.api.errors import InvalidInputError
from prtbench.api.method import Artifact, FrameTimes, Method, register_method
from prtbench.render import ops
from prtbench.render.raster import RasterRenderer
from prtbench.transport.wavelet import brdf, haar
from prtbench.transport.wavelet.brdf import BrdfTable
from prtbench.transport.wavelet.selection import select_terms
from prtbench.transport.wavelet.sparse import SparseTransport
from prtbench.transport.wavelet.transport import cached_transport
from prtbench.transport.wavelet.triple import SparseRows, mean_pyramid, triple_product

#: Bytes per glossy BRDF entry formed each frame: int64 key, point and coefficient + float32
#: value.
BRDF_ENTRY_BYTES = 28
#: Bytes per tabulated BRDF entry (``brdf_table``): int32 coefficient + float32 value.
TABLE_ENTRY_BYTES = 8


@dataclass(frozen=True)
class WaveletTPConfig:
    """Knobs of the ``wavelet-tp`` method."""

    cubemap: int = knob(16, "Cubemap face resolution N, a power of two (6·N² texels and Haar "
                            "coefficients per signal; Ng 2004 uses 32 and 64).", low=1, high=1024)
    texel_samples: int = knob(1, "Visibility rays per texel side S (S×S per texel); 1 = one "
                                 "ray through the texel centre.", low=1, high=16)
    keep: float = knob(0.25, "Visibility coefficients kept per vertex: a fraction in (0, 1] of "
                             "the 6·N², or an integer count > 1 (largest magnitudes; exact zeros "
                             "are never stored).", low=1e-9, high=6 * 1024**2)
    light_terms: int = knob(100, "k: lighting wavelet coefficients used per frame (non-linear "
                                 "approximation; at most 6·N²).", low=1, high=6 * 1024**2)
    selection: str = knob("area", "How the k lighting terms are chosen each frame: largest "
                                  "magnitude, area-weighted magnitude (Ng 2003) or "
                                  "transport-weighted magnitude (× mean |V| over vertices).",
                          choices=SELECTIONS)
    brdf_keep: int = knob(128, "Haar coefficients kept per vertex of each BRDF factor (diffuse "
                               "once, glossy every frame); at most 6·N².",
                          low=1, high=6 * 1024**2)
    brdf_table: int = knob(0, "0: project the glossy BRDF factor for each vertex's own normal "
                              "and mirror direction every frame. T (a power of two): Ng 2004's "
                              "table, G precomputed for the 6×T×T-cube bins of the normals × "
                              "all 6·T² mirror-direction bins, looked up nearest per frame.",
                          low=0, high=64)
    brdf_samples: int = knob(1, "Midpoints per texel side integrating the BRDF over each texel "
                                "(S×S, area-element weighted).", low=1, high=8)
    storage: str = knob("float16", "Stored visibility value type (int8 uses a per-vertex "
                                   "scale).", choices=STORAGES)
    visibility: bool = knob(True, "Trace occlusion. False: V = 1 on the upper hemisphere "
                                  "(unshadowed), the trivial image the regression gate must beat.")


def _check_config(scene, config: WaveletTPConfig) -> tuple[int, int]:
    """(coefficients per vertex, visibility kept per vertex); one-line errors for bad values."""
    m, kept = check_wavelet_config("wavelet-tp", config, points=scene.n_vertices,
                                   what="vertices")
    if config.brdf_keep > m:
        raise InvalidInputError(f"brdf_keep={config.brdf_keep} exceeds the {m} wavelet "
                                f"coefficients of a cubemap={config.cubemap} (6·N²); "
                                f"accepted: 1..{m}")
    # The diffuse and glossy factors' entries, plus a chunk of dense texels being projected,
    # plus the tables (at most min(vertices, 6T²) normal bins × 6T² mirror bins per object).
    need = 2 * scene.n_vertices * config.brdf_keep * BRDF_ENTRY_BYTES + (64 << 20)
    if config.brdf_table:
        t = config.brdf_table
        if t & (t - 1):
            raise InvalidInputError(f"brdf_table={t}; accepted: 0 (project per vertex per "
                                    "frame) or a power of two 1..64 (the table's cube bins)")
        bins = 6 * t * t
        need += sum(min(o.mesh.n_vertices, bins) * bins * config.brdf_keep * TABLE_ENTRY_BYTES
                    for o in scene.objects if o.material.is_glossy)
    check_memory(f"method 'wavelet-tp' cubemap={config.cubemap} brdf_keep={config.brdf_keep} "
                 f"brdf_table={config.brdf_table} on {scene.n_vertices} vertices", need,
                 accepted="a smaller brdf_keep or brdf_table")
    return m, kept


def _rows_from_transport(transport: SparseTransport):
    """The column-major stored visibility as per-vertex rows for the triple product."""

    cols = np.repeat(np.arange(transport.n_coeffs), np.diff(transport.indptr))
    values = transport.values.astype(np.float32)
    if transport.scale is not None:
        values *= transport.scale[transport.rows]
    return SparseRows.from_entries(transport.rows.astype(np.int64), cols, values,
                                   n_points=transport.n_points, n_coeffs=transport.n_coeffs)


@register_method("wavelet-tp")
class WaveletTP(Method):
    """Ng 2004 Haar triple products per vertex: visibility × per-frame BRDF × k-term light."""

    storage = "per-vertex"

    family = "wavelet PRT"

    Config = WaveletTPConfig
    precompute_version = "2"  # 2: the s = 0 Phong lobe is a hemisphere about r
    main_knobs = ("light_terms", "cubemap")
    #: On a diffuse scene ``wavelet-vertex`` renders the same at a lower cost.
    glossy_only = True
    paper = ("Ng, Ramamoorthi and Hanrahan 2004, Triple Product Wavelet Integrals for "
             "All-Frequency Relighting (SIGGRAPH 2004): Haar tree algorithm, direct lighting, "
             "changing view and lighting")
    profile_overrides = {
        "smoke": {"cubemap": 8, "light_terms": 64, "brdf_keep": 64},
        "quick": {"cubemap": 16},
        "paper": {"cubemap": 32, "texel_samples": 2, "brdf_samples": 2, "brdf_keep": 256},
    }
    #: Glossy sphere over a subdivided ground under the sun: shadows and highlights.
    regression_case = {"scene": "sphere-over-plane", "variant": "glossy", "light": "sun",
                       "scene_params": {"plane_subdivisions": 32}}

    @classmethod
    def validate(cls, scene, config: WaveletTPConfig) -> None:
        validate_constant_materials("wavelet-tp", scene)
        _check_config(scene, config)

    @classmethod
    def precompute(cls, scene, config: WaveletTPConfig, *, progress: bool = True) -> Artifact:
        cls.validate(scene, config)  # also when called directly, before any ray
        m, kept = _check_config(scene, config)
        positions, normals, _, _ = scene.merged()
        normals = normals / np.linalg.norm(normals, axis=1, keepdims=True)

        # Keyed by the visibility knobs only: render-time knobs reuse it.
        transport, rays, trace_s = cached_transport(
            "wavelet-tp-visibility", scene.content_hash(), config.cubemap, kept,
            config.texel_samples, config.storage, bool(config.visibility), scene=scene,
            points=positions, normals=normals, config=config, progress=progress, cosine=False)
        d_points, d_coeffs, d_values = brdf.project(normals, n=config.cubemap,
                                                    keep=config.brdf_keep,
                                                    samples=config.brdf_samples)
        diffuse = {"diffuse_points": d_points.astype(np.uint32),
                   "diffuse_coeffs": d_coeffs.astype(np.uint32), "diffuse_values": d_values}
        tables, start, count = {}, 0, 0
        for obj in scene.objects:  # Ng 2004's glossy tables, one per glossy object
            sl = slice(start, start + obj.mesh.n_vertices)
            start = sl.stop
            if config.brdf_table and obj.material.is_glossy:
                table, slots = brdf.BrdfTable.build(
                    normals[sl], t=config.brdf_table, n=config.cubemap, keep=config.brdf_keep,
                    shininess=float(obj.material.shininess), samples=config.brdf_samples)
                prefix = f"table{count}_"
                tables.update(table.arrays(prefix))
                tables[f"{prefix}slots"] = slots.astype(np.uint32)
                count += 1
        return Artifact("wavelet-tp", {**transport.arrays(), **diffuse, **tables},
                        {"vertices": int(len(positions)), "coefficients": m,
                         "kept_per_vertex": kept, "stored_entries": transport.nnz,
                         "stored_bytes": transport.nbytes,
                         "diffuse_entries": int(len(d_values)),
                         "table_bytes": int(sum(a.nbytes for a in tables.values())),
                         "dense_float32_bytes": len(positions) * m * 4,
                         "rays": rays, "trace_s": trace_s})

    @classmethod
    def op_counts(cls, config: WaveletTPConfig, *, scene_vertices: int, scene_triangles: int,
                  covered_pixels: int, width: int, height: int, memory_bytes: int):
        """Per frame on the CPU (:meth:`WaveletTPRenderer.radiance`):

        * the light's Haar transform and the selection of its k terms
          (:func:`methods.wavelet.counts.light_counts`; the lat-long → cubemap resampling is
          per light, not counted), the truncated light written (6N² RGB float64, k gathered)
          and its mean pyramid (:func:`~methods.wavelet.counts.mean_pyramid_counts`);
        * per glossy vertex the eye vector, its normalisation and the mirror direction
          (3 + 3 + 2 transcendentals + 9 madds), then the glossy factor G: projected
          (:func:`~methods.wavelet.counts.brdf_projection_counts`: 6N²·S² texel subsamples,
          float32 Haar, the ``brdf_keep`` largest) or, with ``brdf_table``, looked up (the
          mirror direction's bin, 20 madds and a division, and ``brdf_keep`` entries gathered:
          2 fetches, 8 bytes each); each entry's key formed and stored (``BRDF_ENTRY_BYTES``);
        * two triple products by the tree algorithm, TP(L, V, D) and TP(L, V, G)
          (:func:`~methods.wavelet.counts.triple_product_counts`: binary searches of the
          stored V entries among the BRDF's, parent means of the lit wavelets in 1 + 3·level
          lookups, the three-sibling terms), with at most ``kept`` visibility and ``brdf_keep``
          BRDF entries per vertex and at most min(k, ·) of them lit; kd ⊙ + ks ⊙ (6 madds);
        * the (V, 3) float32 radiance uploaded.

        wavelet_tp.vert reads it (3 SSBO loads); interpolated_radiance.frag interpolates 3
        varyings. The facts do not tell which vertices are glossy, so every vertex is counted
        glossy (the bound; the method runs on scenes with a glossy object). As for
        ``wavelet-vertex``, ``memory_bytes`` is not counted as read: the triple products touch
        only the stored entries they search."""

        n = config.cubemap
        m = counts.coefficients(n)
        k = min(config.light_terms, m)
        v = scene_vertices
        visibility = counts.kept_per_point(config.keep, m)
        brdf_keep = min(config.brdf_keep, m)
        light = ops.add_counts(
            counts.light_counts(cubemap=n, terms=k, selection=config.selection),
            {"madds": 0.0, "fetches": float(k), "bytes": float(counts.RGB64_BYTES * (m + k))},
            counts.mean_pyramid_counts(cubemap=n))
        if config.brdf_table:
            glossy = {"madds": 20.0 + ops.TRANSCENDENTAL_MADDS + brdf_keep,
                      "fetches": 2.0 * brdf_keep, "bytes": 8.0 * brdf_keep}
        else:
            glossy = counts.brdf_projection_counts(cubemap=n, samples=config.brdf_samples,
                                                   keep=brdf_keep)
        per_vertex = ops.add_counts(
            {"madds": 3.0 + 3.0 + 2 * ops.TRANSCENDENTAL_MADDS + 9.0 + brdf_keep + 6.0,
             "fetches": 0.0, "bytes": float(BRDF_ENTRY_BYTES * brdf_keep)},
            glossy, {"madds": 0.0, "fetches": 3.0, "bytes": 12.0})  # + the shader's loads
        product = counts.triple_product_counts(points=v, cubemap=n, terms=k,
                                               visibility_entries=visibility,
                                               brdf_entries=brdf_keep)
        return ops.add_counts(
            light, ops.scaled(per_vertex, v), ops.scaled(product, 2),
            counts.upload_counts(values=3 * v),
            ops.raster_counts(vertices=v, triangles=scene_triangles, pixels=covered_pixels,
                              varyings=3, vertex_bytes=12))

    @classmethod
    def renderer(cls, scene, artifact: Artifact, config: WaveletTPConfig, *, width: int,
                 height: int) -> "WaveletTPRenderer":
        return WaveletTPRenderer(scene, artifact, config, width=width, height=height)


class WaveletTPRenderer(RasterRenderer):
    """Per frame: k-term light, glossy BRDF per vertex, two triple products, raster."""

    shader_dirs = (SHADER_DIR,)

    def __init__(self, scene, artifact: Artifact, config: WaveletTPConfig, *, width: int,
                 height: int):

        self.config = config
        transport = SparseTransport.from_arrays(artifact.arrays)
        self.visibility = _rows_from_transport(transport)
        a = artifact.arrays
        self.diffuse = SparseRows.from_entries(a["diffuse_points"], a["diffuse_coeffs"],
                                               a["diffuse_values"], n_points=transport.n_points,
                                               n_coeffs=transport.n_coeffs)
        super().__init__(scene, width=width, height=height, vertex_shader="wavelet_tp.vert",
                         fragment_shader="interpolated_radiance.frag", defines={})
        # Selection weights (area: support solid angles; transport: mean |V̂|) and light cubes.
        self.relight = Relighter(transport, config)
        self.relight.transport = None  # only its weights and light cubes are used: not resident
        positions, normals, _, _ = scene.merged()
        self.positions = positions.astype(np.float64)
        self.normals = normals / np.linalg.norm(normals, axis=1, keepdims=True)
        self.kd, self.ks, self.glossy = [], [], []  # per vertex kd, ks; glossy object ranges
        start = 0
        for obj in scene.objects:
            count = obj.mesh.n_vertices
            self.kd.append(np.broadcast_to(np.asarray(obj.material.kd, np.float64), (count, 3)))
            self.ks.append(np.broadcast_to(np.asarray(obj.material.ks, np.float64), (count, 3)))
            if obj.material.is_glossy:
                self.glossy.append((slice(start, start + count), float(obj.material.shininess)))
            start += count
        self.kd, self.ks = np.concatenate(self.kd), np.concatenate(self.ks)
        self.tables = []  # (BrdfTable, slots) per glossy object with brdf_table
        if config.brdf_table:

            self.tables = [(BrdfTable.from_arrays(a, f"table{g}_"),
                            a[f"table{g}_slots"].astype(np.int64))
                           for g in range(len(self.glossy))]
        self.incident = self.ctx.buffer(reserve=12 * transport.n_points)
        self._resident = [self.incident]
        self.last_terms: np.ndarray | None = None
        self.last_glossy: SparseRows | None = None

    def glossy_rows(self, view):
        """The glossy factor G for every glossy vertex's (n, r) in ``view``, as SparseRows."""

        parts = []
        for g, (sl, shininess) in enumerate(self.glossy):
            to_eye = np.asarray(view.eye, np.float64) - self.positions[sl]
            to_eye /= np.maximum(np.linalg.norm(to_eye, axis=1, keepdims=True), 1e-30)
            r = brdf.reflect(to_eye, self.normals[sl])
            if self.tables:
                table, slots = self.tables[g]
                p, c, v = table.gather(slots, r)
            else:
                p, c, v = brdf.project(self.normals[sl], n=self.config.cubemap,
                                       keep=self.config.brdf_keep, reflections=r,
                                       shininess=shininess, samples=self.config.brdf_samples)
            parts.append((p + sl.start, c, v))
        if not parts:
            return SparseRows(np.zeros(0, np.int64), np.zeros(0, np.float32),
                              self.visibility.n_points, self.visibility.n_coeffs)
        # Objects are in merged order, each by vertex: concatenated keys stay sorted.
        p, c, v = (np.concatenate([q[i] for q in parts]) for i in range(3))
        return SparseRows(p * self.visibility.n_coeffs + c, v, self.visibility.n_points,
                          self.visibility.n_coeffs, points=p, coeffs=c)

    def radiance(self, view, light) -> np.ndarray:
        """(P, 3) float32 outgoing radiance towards ``view`` of every vertex: the frame's CPU
        work."""

        n = self.config.cubemap
        coeffs = haar.forward(self.relight.light_cube(light)).reshape(3, -1).T  # (6N², 3)
        rule = {"area": {"support": self.relight.weights},
                "transport": {"transport_weight": self.relight.weights}
                }.get(self.config.selection, {})
        terms = select_terms(coeffs, self.config.light_terms, rule=self.config.selection, **rule)
        self.last_terms = terms
        lit = np.zeros_like(coeffs)
        lit[terms] = coeffs[terms]
        mean = mean_pyramid(lit.T.reshape(3, 6, n, n)).reshape(3, -1).T
        out = self.kd * triple_product(lit, self.visibility, self.diffuse, light_mean=mean)
        if self.glossy:
            self.last_glossy = self.glossy_rows(view)
            out += self.ks * triple_product(lit, self.visibility, self.last_glossy,
                                            light_mean=mean)
        return out.astype(np.float32)

    def _bind(self, view, light) -> None:
        self.incident.write(np.ascontiguousarray(self.radiance(view, light)).tobytes())
        self.incident.bind_to_storage_buffer(0)

    def frame_time(self, view, light, *, warmup: int, frames: int) -> FrameTimes:
        """Host clock around whole frames (CPU BRDF + triple products + upload + draw + finish)."""
        self.relight.light_cube(light)  # per light, outside the frame
        return host_frame_times(self.ctx, lambda: self._draw(view, light), warmup=warmup,
                                frames=frames, renderer=self.renderer_string)

    def memory_bytes(self) -> int:
        """Visibility rows, diffuse BRDF rows, the glossy rows' bound (glossy vertices ×
        brdf_keep entries), the BRDF tables and their per-vertex slots (``brdf_table``),
        selection weights and the per-vertex radiance buffer."""
        glossy_vertices = sum(sl.stop - sl.start for sl, _ in self.glossy)
        weights = 0 if self.relight.weights is None else self.relight.weights.nbytes
        tables = sum(table.nbytes + slots.nbytes for table, slots in self.tables)
        return int(self.visibility.nbytes + self.diffuse.nbytes + weights + self.incident.size
                   + glossy_vertices * self.config.brdf_keep * BRDF_ENTRY_BYTES + tables)
