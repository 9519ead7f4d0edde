"""GL runtime of the data-driven method: shadow maps, fake G-buffer, matrix transfer, shading.

Per frame (Belcour et al. 2022 §4.3), all on the GPU, no readback:

1. ``shadows``: every analytic light renders its shadow tile(s) into one R32F atlas (a point
   light or wide spot uses six cube tiles, a spot one perspective tile, a directional light one
   orthographic tile fitted to the scene's bounding sphere). An environment map is drawn as
   median-cut directional lights (:func:`~methods.data_driven.lights.median_cut`).
2. ``gbuffer``: the fake G-buffer, deferred shading of the measurement points with the same
   lights and shadows into a (P, 1) texture: the direct vector x.
3. ``transfer``: the coefficients u = M x (and the mean's weight ‖x‖) into a tiny texture.
4. ``shading``: depth pre-pass, then direct light plus the blend of the basis textures.

The "no GI" shader is pass 4 without the indirect term (the baseline of the paper's table 1).
Passes are timed separately by :meth:`DataDrivenRenderer.pass_times`.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from methods.data_driven import SHADER_DIR
from methods.data_driven.shadows import LIGHT_DEFINES, DirectLighting
from prtbench.api.method import FrameTimes, Renderer
from prtbench.render import gl
from prtbench.scene.model import View


def _clip_planes(scene_lo: np.ndarray, scene_hi: np.ndarray, view: View) -> tuple[float, float]:
    centre, radius = (scene_lo + scene_hi) / 2, float(np.linalg.norm(scene_hi - scene_lo)) / 2
    dist = float(np.linalg.norm(np.asarray(view.eye) - centre))
    far = dist + radius * 1.01 + 1e-3
    return max(dist - radius * 1.01, far * 1e-4), far


class FakeGBuffer:
    """The measurement points as G-buffer textures and the deferred pass that shades them."""

    def __init__(self, ctx, points: np.ndarray, normals: np.ndarray, albedo: np.ndarray):
        self.ctx = ctx
        p, s = points.shape[:2]
        self.n_points, self.supersample = int(p), int(s)
        self.program = gl.load_program(ctx, "data_driven_fullscreen.vert", "data_driven_gbuffer.frag",
                                       defines={**LIGHT_DEFINES, "SUPERSAMPLE": self.supersample},
                                       search_path=[SHADER_DIR])

        def texture(values: np.ndarray):
            rgba = np.zeros((s, p, 4), np.float32)  # row s, column i
            rgba[..., :3] = np.transpose(values, (1, 0, 2))
            tex = ctx.texture((p, s), 4, rgba.tobytes(), dtype="f4")
            tex.filter = (ctx.NEAREST, ctx.NEAREST)
            return tex

        self.textures = [texture(points), texture(normals), texture(albedo)]
        self.output = ctx.texture((p, 1), 4, dtype="f4")
        self.output.filter = (ctx.NEAREST, ctx.NEAREST)
        self.fbo = ctx.framebuffer(color_attachments=[self.output])
        self.vao = ctx.vertex_array(self.program, [])

    def run(self, lighting: DirectLighting) -> None:
        self.fbo.use()
        self.ctx.viewport = (0, 0, self.n_points, 1)
        self.ctx.disable(gl.moderngl.DEPTH_TEST)
        lighting.bind(self.program, unit=0)
        for unit, (tex, name) in enumerate(zip(self.textures, ("g_position", "g_normal", "g_albedo")),
                                           start=1):
            tex.use(unit)
            self.program[name].value = unit
        self.vao.render(gl.moderngl.TRIANGLES, vertices=3)

    def read(self) -> np.ndarray:
        """(P, 3) float32 direct vector (the last run)."""
        raw = self.fbo.read(components=4, dtype="f4", viewport=(0, 0, self.n_points, 1))
        return np.frombuffer(raw, np.float32).reshape(self.n_points, 4)[:, :3].copy()

    def memory_bytes(self) -> int:
        return int(sum(t.width * t.height * 16 for t in self.textures) + self.n_points * 16)

    def release(self) -> None:
        for obj in (self.vao, self.fbo, self.output, *self.textures, self.program):
            obj.release()


class Transfer:
    """u = M x on the GPU: the transfer matrix texture and the coefficient target."""

    def __init__(self, ctx, matrix: np.ndarray, *, n_basis: int, n_points: int, multi_channel: bool,
                 gamma: float):
        self.ctx = ctx
        self.n_basis, self.n_points = int(n_basis), int(n_points)
        self.multi = bool(multi_channel)
        self.groups = (self.n_basis + 3) // 4
        self.rows = 1 if self.multi else 3
        defines = {"MULTI_CHANNEL": int(self.multi), "GAMMA_SPACE": int(gamma != 1.0),
                   "GAMMA": float(gamma)}
        self.program = gl.load_program(ctx, "data_driven_fullscreen.vert", "data_driven_transfer.frag",
                                       defines=defines, search_path=[SHADER_DIR])
        # (C, n - 1, X) -> one (X wide, C·(n - 1) high) texture: channel c's rows follow c - 1's
        # (C = 3); a single matrix (C = 1) serves every channel.
        m = np.asarray(matrix, np.float32)
        self.channel_stride = int(m.shape[1]) if m.shape[0] > 1 else 0
        m = m.reshape(-1, m.shape[2])
        if m.size == 0:  # only the mean: a dummy 1x1 texture keeps the sampler valid
            m = np.zeros((1, 1), np.float32)
        self.matrix = ctx.texture((m.shape[1], m.shape[0]), 1, np.ascontiguousarray(m).tobytes(),
                                  dtype="f4")
        self.matrix.filter = (ctx.NEAREST, ctx.NEAREST)
        self.output = ctx.texture((self.groups, self.rows), 4, dtype="f4")
        self.output.filter = (ctx.NEAREST, ctx.NEAREST)
        self.fbo = ctx.framebuffer(color_attachments=[self.output])
        self.vao = ctx.vertex_array(self.program, [])
        self.matrix_bytes = int(np.asarray(matrix).size * 4)

    def run(self, direct_vector, *, light_scale: float = 1.0) -> None:
        self.fbo.use()
        self.ctx.viewport = (0, 0, self.groups, self.rows)
        self.ctx.disable(gl.moderngl.DEPTH_TEST)
        direct_vector.use(0)
        self.matrix.use(1)
        self.program["direct_vector"].value = 0
        self.program["transfer_matrix"].value = 1
        self.program["n_points"].value = self.n_points
        self.program["n_basis"].value = self.n_basis
        if "channel_stride" in self.program:  # compiled out when only the mean is blended
            self.program["channel_stride"].value = self.channel_stride
        if "light_scale" in self.program:  # gamma space only (see DirectLighting.light_scale)
            self.program["light_scale"].value = float(light_scale)
        self.vao.render(gl.moderngl.TRIANGLES, vertices=3)

    def read(self) -> np.ndarray:
        """Coefficients as (rows, 4·groups): row c holds the weights of channel c."""
        raw = self.fbo.read(components=4, dtype="f4", viewport=(0, 0, self.groups, self.rows))
        return np.frombuffer(raw, np.float32).reshape(self.rows, self.groups * 4).copy()

    def release(self) -> None:
        for obj in (self.vao, self.fbo, self.output, self.matrix, self.program):
            obj.release()


class DataDrivenRenderer(Renderer):
    """Renders direct light and the data-driven indirect light of one artifact.

    Parameters
    ----------
    scene : Scene
    arrays : dict of str to ndarray
        The artifact's arrays (render mesh, measurement G-buffer, basis, transfer matrix).
    width, height : int
    basis_count : int
        n, mean included.
    multi_channel : bool
    gamma : float
    shadow_resolution, env_shadow_resolution, env_lights : int
    """

    def __init__(self, scene, arrays: dict[str, np.ndarray], *, width: int, height: int,
                 basis_count: int, multi_channel: bool, gamma: float, shadow_resolution: int,
                 env_shadow_resolution: int, env_lights: int):
        self.scene, self.width, self.height = scene, int(width), int(height)
        self.ctx = gl.create_context()
        self.renderer_string = gl.renderer_string(self.ctx)
        self.lo, self.hi = scene.bounds()
        self.basis_count = int(basis_count)
        self.multi, self.gamma = bool(multi_channel), float(gamma)
        positions, faces = arrays["mesh_positions"], arrays["mesh_faces"]
        self.lighting = DirectLighting(self.ctx, positions, faces, lo=self.lo, hi=self.hi,
                                       shadow_resolution=shadow_resolution,
                                       env_shadow_resolution=env_shadow_resolution,
                                       env_lights=env_lights)
        self.gbuffer = FakeGBuffer(self.ctx, arrays["g_position"], arrays["g_normal"],
                                   arrays["g_albedo"])
        self.transfer = Transfer(self.ctx, arrays["transfer_matrix"], n_basis=self.basis_count,
                                 n_points=self.gbuffer.n_points, multi_channel=self.multi,
                                 gamma=self.gamma)
        basis = np.ascontiguousarray(arrays["basis_textures"], np.float32)  # (layers, R, R, 4)
        layers, res = basis.shape[0], basis.shape[1]
        self.basis = self.ctx.texture_array((res, res, layers), 4, basis.tobytes(), dtype="f4")
        self.basis.filter = (self.ctx.LINEAR, self.ctx.LINEAR)
        self.basis.repeat_x = self.basis.repeat_y = False
        self.layers = layers
        self._mesh = (positions, arrays["mesh_normals"], arrays["mesh_albedo"], arrays["mesh_uvs"],
                      faces)
        self._programs: dict[tuple[bool, bool], Any] = {}
        #: The light scale the coefficient texture holds its weights relative to (gamma space;
        #: see pass_transfer). Weights written directly (evaluation.write_coefficients) are 1.
        self.coefficient_scale = 1.0
        self.depth_program = gl.load_program(self.ctx, "data_driven_shade.vert", "data_driven_depth.frag",
                                             search_path=[SHADER_DIR])
        self.depth_vao = gl.upload_mesh(self.ctx, self.depth_program, positions, faces)
        self.target = gl.RenderTarget(self.ctx, self.width, self.height)
        self.timer = gl.GpuTimer(self.ctx)
        self._query = self.ctx.query(time=True)
        self.mesh_bytes = int(self.depth_vao.extra["bytes"])

    # -- programs ------------------------------------------------------------------------------

    def _program(self, direct: bool, indirect: bool):
        key = (direct, indirect)
        if key not in self._programs:
            defines = {**LIGHT_DEFINES, "DIRECT": int(direct), "INDIRECT": int(indirect),
                       "MULTI_CHANNEL": int(self.multi), "N_BASIS": self.basis_count,
                       "N_TEXTURES": self.layers, "GAMMA_SPACE": int(self.gamma != 1.0),
                       "GAMMA": self.gamma}
            program = gl.load_program(self.ctx, "data_driven_shade.vert", "data_driven_shade.frag",
                                      defines=defines, search_path=[SHADER_DIR])
            positions, normals, albedo, uvs, faces = self._mesh
            vao = gl.upload_mesh(self.ctx, program, positions, faces,
                                 attributes={"normal": normals, "kd": albedo, "lightmap_uv": uvs})
            self._programs[key] = (program, vao)
        return self._programs[key]

    # -- passes --------------------------------------------------------------------------------

    def prepare_light(self, light: Any) -> None:
        self.lighting.set_light(light)

    def pass_shadows(self) -> None:
        self.lighting.render_shadows()

    def pass_gbuffer(self) -> None:
        self.gbuffer.run(self.lighting)

    def pass_transfer(self) -> None:
        # Gamma space divides the direct light by the lights' peak power before v^(1/γ) (float32
        # stays finite for any light) and the shading multiplies it back: coefficient_scale is
        # the light the coefficient texture is relative to.
        scale = self.lighting.tiles.light_scale if self.gamma != 1.0 else 1.0
        self.transfer.run(self.gbuffer.output, light_scale=scale)
        self.coefficient_scale = scale

    def pass_shading(self, view: View, *, direct: bool = True, indirect: bool = True) -> None:
        near, far = _clip_planes(self.lo, self.hi, view)
        clip = view.clip_from_camera(self.width / self.height, near, far) @ view.camera_from_world()
        clip_bytes = clip.T.astype(np.float32).tobytes()
        self.target.use()
        self.target.clear()
        self.ctx.enable(gl.moderngl.DEPTH_TEST)
        self.ctx.disable(gl.moderngl.CULL_FACE)
        # Depth pre-pass, then shade each visible pixel once (DESIGN.md §9).
        self.ctx.depth_func = "<"
        self.depth_program["clip_from_world"].write(clip_bytes)
        self.depth_vao.render()
        self.ctx.depth_func = "<="
        program, vao = self._program(direct, indirect)
        program["clip_from_world"].write(clip_bytes)
        if direct:
            self.lighting.bind(program, unit=0)
        if indirect:
            self.basis.use(1)
            self.transfer.output.use(2)
            program["basis"].value = 1
            program["coefficients"].value = 2
            if "light_scale" in program:  # gamma space only
                program["light_scale"].value = float(self.coefficient_scale)
        self.target.fbo.depth_mask = False
        vao.render()
        self.target.fbo.depth_mask = True
        self.ctx.depth_func = "<"

    def draw(self, view: View, light: Any, *, direct: bool = True, indirect: bool = True) -> None:
        """One whole frame (shadows only when direct light is drawn or measured)."""
        self.prepare_light(light)
        self.pass_shadows()
        if indirect:
            self.pass_gbuffer()
            self.pass_transfer()
        self.pass_shading(view, direct=direct, indirect=indirect)

    # -- Renderer contract ---------------------------------------------------------------------

    def render(self, view: View, light: Any, *, direct: bool = True,
               indirect: bool = True) -> np.ndarray:
        """Linear HDR image (H, W, 3); ``direct``/``indirect`` select the components."""
        self.draw(view, light, direct=direct, indirect=indirect)
        return np.ascontiguousarray(self.target.read()[..., :3])

    def direct_vector(self, light: Any) -> np.ndarray:
        """(P, 3) direct light at the measurement points (the fake G-buffer's output)."""
        self.prepare_light(light)
        self.pass_shadows()
        self.pass_gbuffer()
        return self.gbuffer.read()

    def coefficients(self, light: Any) -> np.ndarray:
        """The transfer pass's output for ``light`` (see :meth:`Transfer.read`), relative to
        the light itself (gamma space: the texture's weights times coefficient_scale^(1/γ))."""
        self.direct_vector(light)
        self.pass_transfer()
        raw = self.transfer.read()
        if self.gamma == 1.0:
            return raw
        return raw.astype(np.float64) * self.coefficient_scale ** (1.0 / self.gamma)

    def frame_time(self, view: View, light: Any, *, warmup: int, frames: int) -> FrameTimes:
        times = self.timer.time_frames(lambda: self.draw(view, light), warmup=warmup, frames=frames)
        return FrameTimes(times.median_ms, times.p95_ms, times.mean_ms, frames,
                          self.renderer_string, times.source)

    def pass_times(self, view: View, light: Any, *, warmup: int, frames: int,
                   ) -> dict[str, FrameTimes]:
        """Median times of each pass in one session: ``shadows``, ``gbuffer``, ``transfer``,
        ``shading`` (GI shader), ``no_gi`` (direct-only shader) and ``frame`` (all of it).

        Passes are timed interleaved, ``frames`` rounds of one sample each, so that load on a
        shared machine affects them alike.
        """
        self.prepare_light(light)
        self.draw(view, light)
        passes = {
            "shadows": self.pass_shadows,
            "gbuffer": self.pass_gbuffer,
            "transfer": self.pass_transfer,
            "shading": lambda: self.pass_shading(view),
            "no_gi": lambda: self.pass_shading(view, indirect=False),
            "frame": lambda: self.draw(view, light),
        }
        for fn in passes.values():
            for _ in range(max(1, int(warmup))):
                fn()
        self.ctx.finish()
        samples: dict[str, list[float]] = {k: [] for k in passes}
        for _ in range(int(frames)):
            for name, fn in passes.items():
                samples[name].append(self._time_once(fn))
        source = self.timer.source
        out = {}
        for name, values in samples.items():
            v = np.asarray(values)
            out[name] = FrameTimes(float(np.median(v)), float(np.percentile(v, 95)), float(v.mean()),
                                   len(v), self.renderer_string, source)
        return out

    def _time_once(self, fn) -> float:
        """Milliseconds of one call of ``fn`` (timer query, or wall clock + glFinish on CPUs)."""

        if self.timer.source == "wall+finish":
            start = time.perf_counter()
            fn()
            self.ctx.finish()
            return (time.perf_counter() - start) * 1e3
        with self._query:
            fn()
        self.ctx.finish()
        return self._query.elapsed / 1e6

    def storage(self) -> dict[str, int]:
        """Resident bytes by part: basis textures, transfer matrix, G-buffer, mesh, shadows."""
        return {"basis": int(self.basis.width * self.basis.height * self.layers * 16),
                "transfer_matrix": self.transfer.matrix_bytes,
                "gbuffer": self.gbuffer.memory_bytes(),
                "mesh": self.mesh_bytes,
                "shadow_atlas": self.lighting.memory_bytes()}

    def memory_bytes(self) -> int:
        """What the indirect method adds to a renderer: basis, matrix, fake G-buffer."""
        s = self.storage()
        return s["basis"] + s["transfer_matrix"] + s["gbuffer"]

    def release(self) -> None:
        for program, vao in self._programs.values():
            buffers = (getattr(vao, "extra", None) or {}).get("buffers", [])
            for obj in (vao, *buffers, program):
                obj.release()
        self._programs = {}
        buffers = (getattr(self.depth_vao, "extra", None) or {}).get("buffers", [])
        for obj in (self.depth_vao, *buffers, self.depth_program, self.basis):
            obj.release()
        self.lighting.release()
        self.gbuffer.release()
        self.transfer.release()
        self.target.release()
        # moderngl queries have no release(); they go with the context.
