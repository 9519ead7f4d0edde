"""Transfer-texture renderer: depth pre-pass, then per-fragment TP or TPFL shading.

The transfer textures live in one RGBA ``sampler2DArray`` (T_0 of every texture of the set)
and, with bounces, a second one (T_1 … T_k). Lookups are bilinear (or nearest, ``filtering``)
within the atlas: conservative G-buffer coverage plus at least one ring of dilation guarantee
that every texel a lookup inside a triangle reads holds data of that triangle's chart. No
mip-maps (PRTT does not use them either; the knob would change what is measured).
"""

from __future__ import annotations

import numpy as np

from methods.common.atlas import SHADER_DIR as ATLAS_SHADER_DIR
from methods.common.atlas.atlas import AtlasMesh
from methods.common.atlas.raster import upload_atlas_mesh
from methods.common.atlas.shading import ShadingInputs, normal_map_texture
from methods.common.atlas.texels import layer_count, rgba_layers
from methods.texture import SHADER_DIR
from methods.texture.compressed import CompressedTexels
from prtbench.api.errors import InvalidInputError
from prtbench.api.method import Artifact, Renderer
from prtbench.render import gl
from prtbench.render import prt_shading as _triple
from prtbench.render.raster import TargetFrames, clip_planes
from prtbench.transport.compress import knobs as compress_knobs


class TextureRenderer(TargetFrames, Renderer):
    """Draws the atlas mesh: depth-only pre-pass, then shading with depth test LEQUAL.

    Parameters
    ----------
    scene : Scene
    artifact : Artifact
        From :meth:`methods.texture.TextureMethod.precompute`.
    config : TextureConfig
    product : {"tp", "tpfl"}
    width, height : int
    """

    def __init__(self, scene, artifact: Artifact, config, *, product: str, width: int,
                 height: int):
        self.scene, self.width, self.height = scene, int(width), int(height)
        self.product = product
        self.depth_prepass = bool(config.depth_prepass)
        self.sh_bands = int(config.sh_bands)
        self.meta = dict(artifact.meta)
        self.ctx = ctx = gl.create_context()
        self.renderer_string = gl.renderer_string(ctx)
        arrays = artifact.arrays
        bounce = arrays.get("bounce")
        self.cpca = None
        if compress_knobs.is_compressed(arrays):  # PCA / VQ / CPCA form (.compressed)

            filled = np.asarray(arrays["filled"], bool)
            model = compress_knobs.load_model(arrays, n_signals=int(filled.sum()))
            self.cpca = CompressedTexels(ctx, model, filled, sh_bands=self.sh_bands)
            sets, res = filled.shape[0], filled.shape[1]
            channels = model.dimension
        else:
            transfer = arrays["transfer"]
            sets, res, channels = transfer.shape[0], transfer.shape[1], transfer.shape[-1]
        n_bounces = 0 if bounce is None else bounce.shape[0]
        self.transfer_layers = layer_count(channels)
        self.bounce_layers = layer_count(3 * self.sh_bands**2)
        max_layers = int(ctx.info["GL_MAX_ARRAY_TEXTURE_LAYERS"])
        needed = max(sets * self.transfer_layers, n_bounces * sets * self.bounce_layers)
        if needed > max_layers:
            raise InvalidInputError(
                f"transfer textures need {needed} array layers; accepted: <= {max_layers} "
                f"(GL_MAX_ARRAY_TEXTURE_LAYERS): fewer sh_bands, bounces or texture sets")
        defines = {"SH_BANDS": self.sh_bands, "PRODUCT_TP": product == "tp",
                   "TRANSFER_LAYERS": self.transfer_layers, "BOUNCES": n_bounces,
                   "BOUNCE_LAYERS": self.bounce_layers, "TEXTURE_SETS": sets}
        if self.cpca is not None:  # the light goes through the per-cluster projection
            defines.update(self.cpca.defines, PRODUCT_TP=False,
                           BILINEAR=config.filtering == "bilinear")
        self.program = gl.load_program(ctx, "texture_prt.vert", "texture_prt.frag", defines=defines,
                                       search_path=[SHADER_DIR, ATLAS_SHADER_DIR])
        self.depth_program = gl.load_program(ctx, "texture_depth.vert", "texture_depth.frag",
                                             search_path=[SHADER_DIR])
        self._resident = []
        self._texture_bytes = 0
        filter_ = ctx.LINEAR if config.filtering == "bilinear" else ctx.NEAREST
        self.transfer_texture = (self._texture_array(rgba_layers(transfer), filter_)
                                 if self.cpca is None else None)
        if self.cpca is not None:
            self._resident += self.cpca.resident()
        self.bounce_texture = None
        if n_bounces:
            self.bounce_texture = self._texture_array(
                rgba_layers(bounce.reshape(n_bounces * sets, res, res, -1)), filter_)
        shading = ShadingInputs.from_scene(scene)
        self.normal_map = normal_map_texture(ctx, shading.normal_map)
        atlas = AtlasMesh.from_arrays(arrays, resolution=int(self.meta["texture_resolution"]),
                                      sets=int(self.meta["texture_sets"]))
        self._mesh_buffers, (self.vao, self.depth_vao) = upload_atlas_mesh(
            ctx, scene, atlas, shading, (self.program, self.depth_program))
        self.timer = gl.GpuTimer(ctx)
        self.target = gl.RenderTarget(ctx, self.width, self.height)
        # Γ list (TP) or the per-light matrix M (TPFL), uploaded exactly as the vertex methods do.
        self.triple = _triple.TripleProductBuffers(
            ctx, self.sh_bands, gamma=product == "tp" and self.cpca is None)
        self._light_bound = None
        # Bounce textures bake one light: another light is a new precompute (no light change).
        self.bakes_its_light = bool(self.meta.get("bounces"))

    # -- setup ------------------------------------------------------------------------------
    def _texture_array(self, layers: np.ndarray, filter_):
        dtype = "f2" if layers.dtype == np.float16 else "f4"
        n, r = layers.shape[0], layers.shape[1]
        tex = self.ctx.texture_array((r, r, n), 4, np.ascontiguousarray(layers).tobytes(),
                                     dtype=dtype)
        tex.filter = (filter_, filter_)
        tex.repeat_x = tex.repeat_y = False  # CLAMP_TO_EDGE: charts never wrap around
        self._resident.append(tex)
        self._texture_bytes += int(layers.nbytes)
        return tex

    # -- per light --------------------------------------------------------------------------
    def _check_light(self, light) -> None:
        if not self.meta.get("bounces"):
            return
        if light.content_hash() != self.meta.get("bounce_light_hash"):
            raise InvalidInputError(
                f"this artifact's {self.meta['bounces']} bounce texture(s) bake light "
                f"'{self.meta['bounce_light']}', not '{light.name}'; accepted: render with "
                f"light '{self.meta['bounce_light']}', or precompute with "
                f"bounce_light={light.name} (--set bounce_light={light.name})")

    def _bind_light(self, light) -> None:
        if self.cpca is not None:
            self.cpca.bind(self.program, light)
        elif self.product == "tp":
            self.triple.bind_gamma()
            key = light.content_hash()
            if self._light_bound != key:
                coeffs = np.ascontiguousarray(light.sh(self.sh_bands), np.float32)  # (n², 3)
                self.program["light_sh"].write(coeffs.tobytes())
                self._light_bound = key
        else:
            self.triple.bind_tpfl(light)  # M recomputed on the CPU only when the light changes

    # -- drawing ----------------------------------------------------------------------------
    def _draw(self, view, light) -> None:
        near, far = clip_planes(self.scene, view)
        clip_from_world = (view.clip_from_camera(self.width / self.height, near, far)
                           @ view.camera_from_world()).T.astype(np.float32).tobytes()
        self.program["clip_from_world"].write(clip_from_world)
        self.depth_program["clip_from_world"].write(clip_from_world)
        if "eye" in self.program:
            self.program["eye"].value = tuple(float(c) for c in view.eye)
        self._bind_light(light)
        if self.transfer_texture is not None:
            self.transfer_texture.use(location=0)
            self.program["transfer_layers"].value = 0
        if self.bounce_texture is not None:
            self.bounce_texture.use(location=1)
            self.program["bounce_layers"].value = 1
        self.normal_map.use(location=2)
        if "normal_map" in self.program:
            self.program["normal_map"].value = 2
        fbo = self.target.fbo
        self.target.use()
        fbo.color_mask = (True, True, True, True)
        fbo.depth_mask = True
        self.target.clear()
        ctx = self.ctx
        ctx.enable(gl.moderngl.DEPTH_TEST)
        ctx.disable(gl.moderngl.CULL_FACE)  # back faces occlude, and are shaded black
        ctx.depth_func = "<"
        if not self.depth_prepass:
            self.vao.render()
            return
        # Pass 1: depth only, so pass 2 shades each pixel's visible fragment once.
        fbo.color_mask = (False, False, False, False)
        self.depth_vao.render()
        # Pass 2: shading, early depth test against the pre-pass depth, no depth writes.
        fbo.color_mask = (True, True, True, True)
        fbo.depth_mask = False
        ctx.depth_func = "<="
        self.vao.render()
        fbo.depth_mask = True
        ctx.depth_func = "<"

    def memory_bytes(self) -> int:
        """Transfer texture arrays (all T_0 and T_b layers, RGBA, at the stored precision) plus
        the small Γ list (TP, ~9 KB at 5 bands) or TPFL matrix (7.5 KB), as the vertex methods
        count them. Compressed: the form's textures, projection table and CPU-side means and
        bases (:meth:`~.compressed.CompressedTexels.memory_bytes`) instead of T_0."""
        cpca = self.cpca.memory_bytes() if self.cpca is not None else 0
        return self._texture_bytes + self.triple.memory_bytes() + cpca

    def release(self) -> None:
        for obj in [self.vao, self.depth_vao, *self._mesh_buffers, self.program,
                    self.depth_program, self.normal_map, *self._resident]:
            obj.release()
        self.triple.release()
        self.target.release()
        self._resident = []
