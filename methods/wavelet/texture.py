"""Wavelet transfer textures: all-frequency Haar transport per texel of the PRTT atlas.

The transport of ``wavelet-vertex`` (Ng 2003: V·max(n·ω, 0) over every texel of a 6×N×N
cubemap, Haar, truncated per point, quantised, sparse columns) stored per *texel* of the
transfer-texture atlas of ``texture-tp`` (xatlas charts, texel-space G-buffer: PRTT's
decoupling of shading detail from tessellation) instead of per vertex. No paper combines the
two: PRTT stores SH, Ng 2003 stores per vertex or per pixel of a fixed view.

Precompute: atlas and conservative texel G-buffer (shared with the transfer-texture methods),
the wavelet transport at every covered texel, and the transfer textures' ``dilation`` as linear
maps (:func:`dilation_rings`). Dilating the G-buffer instead and tracing from the averaged
positions was tried and rejected: on a curved chart the mean of neighbouring positions lies
below the surface, and in the furnace test over 1 % of a sphere's texels came out fully
occluded (zero incident light).

Render, each frame: the same k-term relighting as ``wavelet-vertex`` at every filled texel
(:class:`methods.wavelet.relight.Relighter`, CPU) at every covered texel, dilated by the
maps, written into an RGB float32 texture array
(one layer per texture of the set), looked up bilinearly per fragment and multiplied by kd/π.
``frame_time`` is the host clock around the whole frame (relighting, texture upload, draw,
glFinish).

Memory (what ``memory_bytes`` counts): the sparse transport of every filled texel (indices +
values [+ int8 scales]), the selection weights and the RGBA32F incident texture array. It is
far above ``wavelet-vertex`` on the same scene: a texel atlas has many more points than a mesh
has vertices, and each holds its kept coefficients. Measured on sphere-over-plane (2-triangle
ground), quick profile (cubemap 32, keep 0.25, float16): 302 MiB at a 256² atlas, 77 MiB at
128², against 10 MiB for ``wavelet-vertex`` and 16 MiB for ``texture-tpfl`` at 8 bands.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from methods.common.atlas.atlas import AtlasMesh, render_gbuffer
from methods.common.atlas.shading import ShadingInputs
from methods.common.atlas.texels import NEIGHBOURS, dilate
from methods.common.materials import check_diffuse_constant_kd
from methods.wavelet import SHADER_DIR, counts
from methods.wavelet.relight import (
    SELECTIONS,
    STORAGES,
    Relighter,
    check_wavelet_config,
    host_frame_times,
)
from prtbench.api.config import knob
from prtbench.api.errors import InvalidInputError
from prtbench.api.method import Artifact, FrameTimes, Method, Renderer, register_method
from prtbench.render import gl, ops
from prtbench.render.raster import clip_planes, kd_per_vertex
from prtbench.transport.wavelet.sparse import SparseTransport
from prtbench.transport.wavelet.transport import cached_transport


def dilation_rings(covered: np.ndarray, chart: np.ndarray, *, rings: int) -> list[tuple]:
    """The transfer textures' dilation (:func:`methods.common.atlas.texels.dilate`) as linear maps.

    Dilation gives each new texel the mean of some of its 8 neighbours; it is linear, so it is
    applied to the per-frame incident radiance exactly by these maps (a few gathers) instead of
    a whole ``dilate`` call per frame. Each ring's map is read off one ``dilate`` call on a
    9-channel one-hot image coloured by ``(y mod 3, x mod 3)``: the 8 neighbours of a texel
    have 8 distinct colours, so a new texel's channel weights name its sources and weights.

    Parameters
    ----------
    covered : ndarray, shape (S, R, R), bool
    chart : ndarray, shape (S, R, R), int
    rings : int

    Returns
    -------
    list of (targets, entry_target, sources, weights)
        Per ring, in order: flat texel indices of the new texels (T,), and per source entry
        the position in ``targets`` (E,), the flat source texel (E,) and its weight (E,).
    """

    s, r = covered.shape[0], covered.shape[1]
    yy, xx = np.mgrid[0:r, 0:r]
    colour = np.broadcast_to((yy % 3) * 3 + xx % 3, (s, r, r))
    onehot = np.eye(9, dtype=np.float64)[colour]  # (S, R, R, 9)
    filled, ch, out = covered.copy(), chart, []
    for _ in range(int(rings)):
        values, grown, ch_next = dilate(np.where(filled[..., None], onehot, 0.0), filled, ch,
                                        rings=1)
        targets = np.flatnonzero((grown & ~filled).reshape(-1))
        if len(targets) == 0:
            break
        w = values.reshape(-1, 9)[targets]
        t_s, rest = np.divmod(targets, r * r)
        t_y, t_x = np.divmod(rest, r)
        entry_target, sources, weights = [], [], []
        for dy, dx in NEIGHBOURS:
            y, x = t_y + dy, t_x + dx
            inside = (y >= 0) & (y < r) & (x >= 0) & (x < r)
            c = ((y % 3) * 3 + x % 3)
            wt = np.where(inside, w[np.arange(len(targets)), c], 0.0)
            use = np.flatnonzero(wt > 0)
            entry_target.append(use)
            sources.append((t_s[use] * r + y[use]) * r + x[use])
            weights.append(wt[use])
        out.append((targets.astype(np.int64), np.concatenate(entry_target).astype(np.int64),
                    np.concatenate(sources).astype(np.int64),
                    np.concatenate(weights).astype(np.float32)))
        filled, ch = grown, ch_next
    return out


@dataclass(frozen=True)
class WaveletTextureConfig:
    """Knobs of the ``wavelet-texture`` method."""

    cubemap: int = knob(32, "Cubemap face resolution N, a power of two (6·N² texels and Haar "
                            "coefficients).", low=1, high=1024)
    texture_resolution: int = knob(256, "Side R of the atlas texture in texels.", low=16,
                                   high=8192)
    padding: int = knob(2, "Empty texels between atlas charts (xatlas).", low=0, high=64)
    dilation: int = knob(1, "Rings of texels filled around every chart each frame, as the "
                            "transfer textures dilate (>= 1 for bilinear lookups at chart "
                            "borders; 0 only for ablations).", low=0, high=8)
    texel_samples: int = knob(1, "Rays per cubemap texel side S (S×S visibility rays per "
                                 "cubemap texel).", low=1, high=16)
    keep: float = knob(0.25, "Transport coefficients kept per atlas texel: a fraction in (0, 1] "
                             "of the 6·N², or an integer count > 1.", low=1e-9, high=6 * 1024**2)
    light_terms: int = knob(100, "k: lighting wavelet coefficients used per frame (at most "
                                 "6·N²).", low=1, high=6 * 1024**2)
    selection: str = knob("area", "How the k lighting terms are chosen each frame (see "
                                  "wavelet-vertex).", choices=SELECTIONS)
    storage: str = knob("float16", "Stored transport value type (int8 uses a per-texel scale).",
                        choices=STORAGES)
    visibility: bool = knob(True, "Trace occlusion. False: unshadowed transport (V = 1), the "
                                  "trivial image the regression gate must beat.")


@register_method("wavelet-texture")
class WaveletTexture(Method):
    """Haar-wavelet transport per atlas texel, relit with k selected lighting terms."""

    storage = "per-texel"

    family = "wavelet PRT"

    Config = WaveletTextureConfig
    precompute_version = "1"
    main_knobs = ("light_terms", "texture_resolution")
    paper = ("Ng, Ramamoorthi and Hanrahan 2003 (non-linear wavelet lighting, diffuse transport) "
             "stored in the transfer-texture atlas of Sirikonda, KT and Narayanan 2022 (PRTT): "
             "a combination no paper describes")
    profile_overrides = {
        "smoke": {"cubemap": 16, "light_terms": 64, "texture_resolution": 128, "padding": 1},
        "quick": {"cubemap": 32},
        # 512² × 1536 kept float16 coefficients is ~21 GB while building: the most one machine
        # here holds (the validation bounds the texels by the whole texture).
        "paper": {"cubemap": 32, "texture_resolution": 512},
    }
    #: The case of the other shadowed diffuse methods, at the atlas resolution of the smoke
    #: profile: the sun's shadows on the plants' ground.
    regression_case = {"scene": "plants", "variant": "diffuse", "light": "sun"}

    @classmethod
    def validate(cls, scene, config: WaveletTextureConfig) -> None:
        check_diffuse_constant_kd("wavelet-texture", scene, kd_only=True)  # normal maps are ours
        for obj in scene.objects:
            if obj.material.normal_map is not None and obj.mesh.uvs is None:
                raise InvalidInputError(f"object '{obj.name}' has a normal map but no mesh "
                                        "uvs; accepted: normal maps on meshes with uvs")
        if config.padding * 8 > config.texture_resolution:
            raise InvalidInputError(
                f"padding={config.padding} with texture_resolution={config.texture_resolution}; "
                "accepted: padding <= texture_resolution / 8")
        # Before the atlas exists the filled texels are unknown: bound them by the texture.
        res = config.texture_resolution
        check_wavelet_config("wavelet-texture", config, points=res * res,
                             what=f"texels at most (texture_resolution={res})")

    @classmethod
    def precompute(cls, scene, config: WaveletTextureConfig, *, progress: bool = True) -> Artifact:
        cls.validate(scene, config)
        atlas = AtlasMesh.from_scene(scene, resolution=config.texture_resolution,
                                     padding=config.padding, texture_sets=False)
        gbuffer = render_gbuffer(scene, atlas, ShadingInputs.from_scene(scene))
        texels = np.flatnonzero(gbuffer.covered.reshape(-1))
        points = gbuffer.positions.reshape(-1, 3)[texels].astype(np.float64)
        normals = gbuffer.normals.reshape(-1, 3)[texels].astype(np.float64)
        rings = dilation_rings(gbuffer.covered, gbuffer.chart, rings=config.dilation)
        m, kept = check_wavelet_config("wavelet-texture", config, points=len(texels),
                                       what="texels")

        transport, rays, _ = cached_transport(
            "wavelet-texture-transport", scene.content_hash(), points, normals, config.cubemap,
            kept, config.texel_samples, config.storage, bool(config.visibility), scene=scene,
            points=points, normals=normals, config=config, progress=progress)
        meta = {"texture_resolution": atlas.resolution,
                "filled_texels": int(len(texels) + sum(len(r[0]) for r in rings)),
                "covered_texels": int(len(texels)), "coefficients": m,
                "kept_per_texel": kept, "stored_entries": transport.nnz,
                "stored_bytes": transport.nbytes, "dense_float32_bytes": len(texels) * m * 4,
                "rays": rays}
        ring_arrays = {f"ring{i}_{name}": a for i, ring in enumerate(rings)
                       for name, a in zip(("targets", "entry_target", "sources", "weights"), ring)}
        return Artifact("wavelet-texture", {**transport.arrays(), "texels": texels.astype(np.int64),
                                            **ring_arrays, **atlas.arrays()},
                        {**meta, "dilation_rings": len(rings)})

    @classmethod
    def op_counts(cls, config: WaveletTextureConfig, *, scene_vertices: int,
                  scene_triangles: int, covered_pixels: int, width: int, height: int,
                  memory_bytes: int):
        """Per frame on the CPU: the light's Haar transform and the selection of its k terms
        (:func:`methods.wavelet.counts.light_counts`; the lat-long → cubemap resampling is per
        light, not counted), then every atlas texel of the frame: a covered texel's sparse
        product over the k selected columns (at most min(k, kept) stored entries,
        :func:`~methods.wavelet.counts.sparse_product_counts`) written into the RGBA image
        (its index and 12 bytes), or a dilation ring's texel: per channel up to 8 weighted
        sources gathered (index, weight and value) and summed. The facts do not tell how many
        texels the atlas covers or the rings fill (together at most R²), so R² texels are
        counted at the dearer of the two per-texel costs: the bound. Then the whole R² RGBA32F
        image is uploaded. wavelet_texture.frag per covered pixel: one bilinear RGBA32F lookup
        (4 taps of 16 bytes) and kd/π · E (3 madds); 2 varyings interpolated (the set and kd
        are flat); no depth pre-pass.

        ``texture_resolution`` sets the texels relit and uploaded every frame, so ``ops`` grows
        with it; ``dilation`` changes the work only within the R² bound. As for
        ``wavelet-vertex``, ``memory_bytes`` is not counted as read: a frame touches only the
        k selected columns of the transport."""

        m = counts.coefficients(config.cubemap)
        k = min(config.light_terms, m)
        texels = config.texture_resolution**2
        entries = counts.entries_per_point(k, counts.kept_per_point(config.keep, m))
        relit = ops.add_counts(
            ops.scaled(counts.sparse_product_counts(points=texels, terms=k, storage=config.storage,
                                                    entries_per_point=entries), 1.0 / texels),
            {"madds": 0.0, "fetches": 0.0, "bytes": 8.0 + 2 * counts.RGB32_BYTES})
        # Per channel and source: its index, weight and target streamed (8 + 4 + 8 bytes), its
        # value gathered (1 fetch, 4 bytes), a multiply and the bincount's add; per channel
        # the texel's index and value written.
        ring = {"madds": 3.0 * 8 * 2, "fetches": 3.0 * 8, "bytes": 3.0 * (8 * (8 + 4 + 8 + 4) + 12)}
        per_texel = {key: max(relit[key], ring[key]) for key in relit}
        per_pixel = {"madds": 3.0, "fetches": 1.0, "bytes": 4.0 * 16}
        return ops.add_counts(
            counts.light_counts(cubemap=config.cubemap, terms=k, selection=config.selection),
            ops.scaled(per_texel, texels), counts.upload_counts(values=4 * texels),
            ops.raster_counts(vertices=scene_vertices, triangles=scene_triangles,
                              pixels=covered_pixels, varyings=2, vertex_bytes=36),
            ops.scaled(per_pixel, covered_pixels))

    @classmethod
    def renderer(cls, scene, artifact: Artifact, config: WaveletTextureConfig, *, width: int,
                 height: int) -> "WaveletTextureRenderer":
        return WaveletTextureRenderer(scene, artifact, config, width=width, height=height)


class WaveletTextureRenderer(Renderer):
    """CPU k-term relighting per atlas texel, uploaded as a texture, looked up per fragment."""

    def __init__(self, scene, artifact: Artifact, config: WaveletTextureConfig, *, width: int,
                 height: int):

        self.scene, self.width, self.height = scene, int(width), int(height)
        arrays = artifact.arrays
        self.transport = SparseTransport.from_arrays(arrays)
        self.relight = Relighter(self.transport, config)
        self.texels = arrays["texels"]
        self.rings = [tuple(arrays[f"ring{i}_{name}"] for name in
                            ("targets", "entry_target", "sources", "weights"))
                      for i in range(int(artifact.meta["dilation_rings"]))]
        self.resolution = int(artifact.meta["texture_resolution"])
        atlas = AtlasMesh.from_arrays(arrays, resolution=self.resolution, sets=1)
        self.ctx = ctx = gl.create_context()
        self.renderer_string = gl.renderer_string(ctx)
        self.program = gl.load_program(ctx, "wavelet_texture.vert", "wavelet_texture.frag",
                                       search_path=[SHADER_DIR])
        positions, _, _, _ = scene.merged()
        src = atlas.vertex_source
        attributes = {"in_position": positions[src], "in_atlas_uv": atlas.uvs,
                      "in_texture_set": atlas.texture_set.astype(np.float32)[:, None],
                      "in_kd": kd_per_vertex(scene)[src]}
        self._buffers = {name: ctx.buffer(np.ascontiguousarray(v, np.float32).tobytes())
                         for name, v in attributes.items()}
        index = ctx.buffer(np.ascontiguousarray(atlas.faces, np.uint32).tobytes())
        self._buffers["index"] = index
        bindings = [(buf, f"{np.asarray(attributes[name]).reshape(len(src), -1).shape[1]}f", name)
                    for name, buf in self._buffers.items() if name in attributes
                    and name in self.program]
        self.vao = ctx.vertex_array(self.program, bindings, index_buffer=index,
                                    index_element_size=4)
        r = self.resolution
        self.texture = ctx.texture_array((r, r, 1), 4, dtype="f4")
        self.texture.filter = (ctx.LINEAR, ctx.LINEAR)
        self.texture.repeat_x = self.texture.repeat_y = False  # charts never wrap around
        # Row j of the texture holds v-texel j (GL's t = 0 first): as the transfer textures.
        self._image = np.zeros((r * r, 4), np.float32)
        self.target = gl.RenderTarget(ctx, self.width, self.height)

    @property
    def last_terms(self):
        return self.relight.last_terms

    def _draw(self, view, light) -> None:
        image = self._image
        image[self.texels, :3] = self.relight(light)
        for targets, entry_target, sources, weights in self.rings:  # dilation, ring by ring
            for c in range(3):
                image[targets, c] = np.bincount(entry_target, weights=image[sources, c] * weights,
                                                minlength=len(targets))
        self.texture.write(self._image.tobytes())
        near, far = clip_planes(self.scene, view)
        clip_from_world = view.clip_from_camera(self.width / self.height, near, far) @ view.camera_from_world()
        self.program["clip_from_world"].write(clip_from_world.T.astype(np.float32).tobytes())
        self.texture.use(location=0)
        self.program["incident"].value = 0
        self.target.use()
        self.target.clear()
        self.ctx.enable(gl.moderngl.DEPTH_TEST)
        self.ctx.disable(gl.moderngl.CULL_FACE)  # back faces are shaded black
        self.vao.render()

    def render(self, view, light) -> np.ndarray:
        self._draw(view, light)
        return np.ascontiguousarray(self.target.read()[..., :3])

    def frame_time(self, view, light, *, warmup: int, frames: int) -> FrameTimes:
        """Host clock around whole frames (CPU relighting + texture upload + draw + glFinish)."""
        self.relight.light_cube(light)  # per light, outside the frame
        return host_frame_times(self.ctx, lambda: self._draw(view, light), warmup=warmup,
                                frames=frames, renderer=self.renderer_string)

    def memory_bytes(self) -> int:
        """Sparse transport + selection weights + the RGBA32F incident texture."""
        return int(self.relight.nbytes + self._image.nbytes)

    def release(self) -> None:
        for obj in [self.vao, *self._buffers.values(), self.program, self.texture]:
            obj.release()
        self.target.release()
