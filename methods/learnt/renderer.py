"""GLSL renderer of the learnt transfer (thesis §4.1.4.1) and the GL plumbing both paths share.

GLSL path: an early depth pre-pass, then one shading pass whose fragment shader evaluates the
MLP from hard-coded mat4 constants (``learnt_mlp.glsl`` + the generated
``learnt_weights.glsl``) and shades the transfer with TPFL or TP (``prt_shading.glsl``).
"""

from __future__ import annotations

import numpy as np

from methods.learnt import SHADER_DIR, glsl
from methods.learnt.model import LearntModel
from prtbench.api.method import FrameTimes, Renderer
from prtbench.render import gl
from prtbench.render import prt_shading as _triple
from prtbench.render.raster import clip_planes, kd_per_vertex


def vertex_attributes(scene) -> dict[str, np.ndarray]:
    """Per-vertex inputs of ``learnt.vert`` in merged order: normal, kd, ks, shininess, object."""

    _, normals, _, _ = scene.merged()
    ks = np.concatenate([np.broadcast_to(np.asarray(o.material.ks, np.float32),
                                         (o.mesh.n_vertices, 3)) for o in scene.objects])
    shininess = np.concatenate([np.full((o.mesh.n_vertices, 1), float(o.material.shininess),
                                        np.float32) for o in scene.objects])
    object_id = np.concatenate([np.full((o.mesh.n_vertices, 1), i, np.float32)
                                for i, o in enumerate(scene.objects)])
    return {"normal": normals, "kd": kd_per_vertex(scene), "ks": ks, "shininess": shininess,
            "object_id": object_id}


class LearntGLBase(Renderer):
    """Scene upload, camera and target of both learnt renderers.

    Parameters
    ----------
    scene : Scene
    model : LearntModel
    fragment_shader : str
        Shading (or G-buffer) stage; the vertex stage is ``learnt.vert``.
    defines : dict
    include_dir : Path
        Where the generated includes of this model live.
    attachments : int
        Colour attachments of the target.
    depth_prepass : bool
        Draw depth first and shade with LEQUAL and no depth writes.
    """

    def __init__(self, scene, model: LearntModel, *, width: int, height: int,
                 fragment_shader: str, defines: dict, include_dir, attachments: int = 1,
                 depth_prepass: bool = True):
        self.scene, self.model, self.width, self.height = scene, model, width, height
        self.depth_prepass = depth_prepass
        self.ctx = gl.create_context()
        self.renderer_string = gl.renderer_string(self.ctx)
        self.program = gl.load_program(self.ctx, "learnt.vert", fragment_shader, defines=defines,
                                       search_path=[include_dir, SHADER_DIR])
        positions, _, faces, _ = scene.merged()
        self.vao = gl.upload_mesh(self.ctx, self.program, positions, faces,
                                  attributes=vertex_attributes(scene))
        self.depth_program = self.depth_vao = None
        if depth_prepass:
            self.depth_program = gl.load_program(self.ctx, "learnt.vert", "learnt_depth.frag",
                                                 search_path=[SHADER_DIR])
            self.depth_vao = gl.upload_mesh(self.ctx, self.depth_program, positions, faces)
        self.target = gl.RenderTarget(self.ctx, width, height, attachments=attachments)
        self.timer = gl.GpuTimer(self.ctx)
        self._resident: list = []

    def _bind(self, view, light) -> None:  # pragma: no cover - overridden
        raise NotImplementedError

    def _draw_geometry(self, view, light) -> None:
        """Depth pre-pass (optional) and the main pass into ``self.target``."""

        near, far = clip_planes(self.scene, view)
        clip_from_world = (view.clip_from_camera(self.width / self.height, near, far)
                           @ view.camera_from_world()).T.astype(np.float32).tobytes()
        for program in (self.program, self.depth_program):
            if program is not None:
                program["clip_from_world"].write(clip_from_world)
        if "eye" in self.program:
            self.program["eye"].value = tuple(float(c) for c in view.eye)
        self._bind(view, light)
        fbo, ctx = self.target.fbo, self.ctx
        n_attach = len(self.target.textures)
        on, off = (True,) * 4, (False,) * 4
        fbo.color_mask = on if n_attach == 1 else (on,) * n_attach
        fbo.depth_mask = True
        self.target.use()
        self.target.clear()
        ctx.enable(gl.moderngl.DEPTH_TEST)
        ctx.disable(gl.moderngl.CULL_FACE)  # back faces are drawn black, as in the reference
        ctx.depth_func = "<"
        if self.depth_vao is None:
            self.vao.render()
            return
        fbo.color_mask = off if n_attach == 1 else (off,) * n_attach
        self.depth_vao.render()
        # Shading pass: early depth test against the pre-pass depth, no depth writes, so the
        # network runs once per visible pixel.
        fbo.color_mask = on if n_attach == 1 else (on,) * n_attach
        fbo.depth_mask = False
        ctx.depth_func = "<="
        self.vao.render()
        fbo.depth_mask = True
        ctx.depth_func = "<"

    def release(self) -> None:
        for vao in (self.vao, self.depth_vao):
            if vao is not None:
                for buffer in (vao.extra or {}).get("buffers", []):
                    buffer.release()
                vao.release()
        for obj in (self.program, self.depth_program, *self._resident):
            if obj is not None:
                obj.release()
        self._resident = []
        self.target.release()
        # (GpuTimer.release is not called: moderngl 5.13 queries have no release method.)


class GLSLRenderer(LearntGLBase):
    """The MLP in the fragment shader with hard-coded mat4 weights (thesis §4.1.4.1)."""

    def __init__(self, scene, model: LearntModel, config, *, width: int, height: int):
        glsl.check_glsl_limit(model.spec, len(model.networks), config.glsl_weight_limit)
        self.product = config.product
        defines = {"SH_BANDS": model.spec.bands, "LEARNT_PRODUCT_TP": config.product == "tp"}
        super().__init__(scene, model, width=width, height=height, fragment_shader="learnt.frag",
                         defines=defines,
                         include_dir=glsl.include_dir(model.networks, model.spec, model.partition))
        self.triple = _triple.TripleProductBuffers(self.ctx, model.spec.bands,
                                                   gamma=config.product == "tp")
        self._resident = [self.triple]
        self.weight_bytes = 4 * glsl.hardcoded_floats(model.spec, len(model.networks))

    def _bind(self, view, light) -> None:
        if self.product == "tp":
            self.triple.bind_gamma()
            coeffs = light.sh(self.model.spec.bands).astype(np.float32)
            self.program["light_sh"].write(np.ascontiguousarray(coeffs).tobytes())
        else:
            self.triple.bind_tpfl(light)

    def render(self, view, light) -> np.ndarray:
        self._draw_geometry(view, light)
        return np.ascontiguousarray(self.target.read()[..., :3])

    def frame_time(self, view, light, *, warmup: int, frames: int) -> FrameTimes:
        times = self.timer.time_frames(lambda: self._draw_geometry(view, light), warmup=warmup,
                                       frames=frames)
        return FrameTimes(times.median_ms, times.p95_ms, times.mean_ms, frames,
                          self.renderer_string, times.source)

    def memory_bytes(self) -> int:
        # The hard-coded constants (float32) plus the light's TPFL matrix / the Γ list.
        return int(self.weight_bytes + self.triple.memory_bytes())
