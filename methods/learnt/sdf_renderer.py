"""The renderers of ``learnt-sdf``: sphere tracing with the network in one GLSL fragment shader, or a GL
G-buffer read back and the network run in torch on the hit pixels (thesis §4.2.2).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from methods.learnt import SHADER_DIR, glsl
from methods.learnt.network import (
    TorchNetwork,
    resolve_device,
)
from methods.learnt.torch_renderer import shade_torch
from prtbench.api.errors import InvalidInputError
from prtbench.api.method import (
    FrameTimes,
    Renderer,
    wall_frame_times,
)
from prtbench.render import gl
from prtbench.render import prt_shading as _triple
from prtbench.render.prt_shading import tpfl_matrix_rgb
from prtbench.render.sdf_gl import GBufferPass, bind_camera, fullscreen_vao, load_sdf_program
from prtbench.transport.sh import triple_product_tensor

if TYPE_CHECKING:  # the config's module imports this one
    from methods.learnt.sdf import LearntSdfConfig


# --- renderers ---------------------------------------------------------------------------------

def material_table(scene) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """kd (M, 3), ks (M, 3), shininess (M,) float32 of the SDF's material ids."""
    materials = scene.sdf.materials
    kd = np.array([np.broadcast_to(np.asarray(m.kd, np.float32), 3) for m in materials], np.float32)
    ks = np.array([np.broadcast_to(np.asarray(m.ks, np.float32), 3) for m in materials], np.float32)
    shininess = np.array([float(m.shininess) for m in materials], np.float32)
    return kd, ks, shininess


class GlslSdfRenderer(Renderer):
    """Sphere tracing, the MLP and TPFL/TP shading in one full-screen fragment shader."""

    def __init__(self, scene, network, spec, config: LearntSdfConfig, *, width: int,
                 height: int):

        glsl.check_glsl_limit(spec, 1, config.glsl_weight_limit)
        self.width, self.height, self.bands, self.product = width, height, spec.bands, config.product
        self.ctx = gl.create_context()
        self.renderer_string = gl.renderer_string(self.ctx)
        kd, ks, shininess = material_table(scene)
        defines = {"SH_BANDS": spec.bands, "LEARNT_PRODUCT_TP": config.product == "tp",
                   "SDF_MATERIALS": len(kd)}
        self.program = load_sdf_program(
            self.ctx, scene, "learnt_sdf.frag", defines=defines, max_steps=config.max_steps,
            sources={"learnt_weights.glsl": glsl.weights_source([network], spec)},
            search_path=[SHADER_DIR])
        for name, values in (("material_kd", kd), ("material_ks", ks),
                             ("material_shininess", shininess)):
            # Compiled out when unused: at sh_bands=1 the Phong lobe's only coefficient g_0
            # does not depend on s (issue #15 stability case sh_bands=1 raised KeyError).
            if name in self.program:
                self.program[name].write(values.tobytes())
        self.vao = fullscreen_vao(self.ctx, self.program)
        self.target = gl.RenderTarget(self.ctx, width, height)
        self.triple = _triple.TripleProductBuffers(self.ctx, spec.bands,
                                                   gamma=config.product == "tp")
        self.timer = gl.GpuTimer(self.ctx)
        self.weight_bytes = 4 * glsl.hardcoded_floats(spec, 1)

    def _draw(self, view, light) -> None:
        bind_camera(self.program, view, self.width, self.height)
        if self.product == "tp":
            self.triple.bind_gamma()
            coeffs = np.ascontiguousarray(light.sh(self.bands), np.float32)
            self.program["light_sh"].write(coeffs.tobytes())
        else:
            self.triple.bind_tpfl(light)
        self.target.use()
        self.target.clear()
        self.ctx.disable(gl.moderngl.DEPTH_TEST)
        self.vao.render(gl.moderngl.TRIANGLES, vertices=3)

    def render(self, view, light) -> np.ndarray:
        self._draw(view, light)
        return np.ascontiguousarray(self.target.read()[..., :3])

    def frame_time(self, view, light, *, warmup: int, frames: int) -> FrameTimes:
        times = self.timer.time_frames(lambda: self._draw(view, light), warmup=warmup,
                                       frames=frames)
        return FrameTimes(times.median_ms, times.p95_ms, times.mean_ms, frames,
                          self.renderer_string, times.source)

    def memory_bytes(self) -> int:
        # The hard-coded weights (float32) and the light's TPFL matrix / the Γ list.
        return int(self.weight_bytes + self.triple.memory_bytes())

    def release(self) -> None:
        for obj in (self.vao, self.program, self.triple, self.target):
            obj.release()


class TorchSdfRenderer(Renderer):
    """Sphere-traced G-buffer -> torch network on hit pixels -> TPFL/TP shading in torch."""

    def __init__(self, scene, network, spec, config: LearntSdfConfig, *, width: int,
                 height: int):
        import torch

        self.torch, self.spec, self.product = torch, spec, config.product
        self.width, self.height = width, height
        self.device = resolve_device(config.device)
        self.ctx = gl.create_context()
        self.gbuffer = GBufferPass(self.ctx, scene, width, height, max_steps=config.max_steps)
        self.net = TorchNetwork(network, spec, self.device)
        kd, ks, shininess = material_table(scene)
        self.kd, self.ks, self.shininess = (torch.as_tensor(a, device=self.device)
                                            for a in (kd, ks, shininess))
        self.display = self.ctx.texture((width, height), 4, dtype="f4")
        self._light_key, self._light_matrix, self._gamma = None, None, None
        device_name = (torch.cuda.get_device_name(self.device) if self.device != "cpu"
                       else f"CPU ({torch.get_num_threads()} threads)")
        self.renderer_string = f"{gl.renderer_string(self.ctx)} + torch {device_name}"
        self.weight_bytes = 4 * spec.n_parameters()
        self.light_bytes = 4 * spec.n_outputs ** 2 * 3

    def _matrix(self, light):
        """M (n², n², 3) on the device: kept per light (tpfl) or contracted per frame (tp)."""
        torch, bands = self.torch, self.spec.bands
        if self.product == "tp":

            if self._gamma is None:
                # A writable float32 copy: the tensor of prtbench.transport.sh is a read-only cache.
                gamma = np.array(triple_product_tensor(bands), dtype=np.float32)
                self._gamma = torch.as_tensor(gamma, device=self.device)
            coeffs = torch.as_tensor(light.sh(bands), dtype=torch.float32, device=self.device)
            return torch.einsum("ijk,jc->ikc", self._gamma, coeffs)
        key = light.content_hash()
        if key != self._light_key:

            self._light_matrix = torch.as_tensor(tpfl_matrix_rgb(light.sh(bands), bands),
                                                 device=self.device)
            self._light_key = key
        return self._light_matrix

    def _frame(self, view, light) -> np.ndarray:
        """One frame; returns (H·W, 4) float32 in GL row order (bottom row first)."""

        torch = self.torch
        self.gbuffer.draw(view)
        fbo = self.gbuffer.target.fbo
        host = np.stack([np.frombuffer(fbo.read(components=4, attachment=i, dtype="f4",
                                                alignment=1), np.float32).reshape(-1, 4)
                         for i in range(2)])
        gbuf = torch.from_numpy(host).to(self.device)  # GL -> host -> device
        with torch.no_grad():
            hit = (gbuf[0, :, 3] > 0.5).nonzero()[:, 0]
            packed = gbuf[:, hit]  # pack: the network sees hit pixels only
            p, n = packed[0, :, :3], packed[1, :, :3]
            ids = packed[1, :, 3].round().long().clamp(0, len(self.kd) - 1)
            transfer = self.net.transfer(p, n)
            wo = torch.as_tensor(np.asarray(view.eye, np.float32), device=self.device) - p
            wo = wo / wo.norm(dim=1, keepdim=True)
            radiance = shade_torch(torch, transfer, self._matrix(light), self.kd[ids],
                                   self.ks[ids], self.shininess[ids], n, wo, self.spec.bands)
            frame = torch.zeros((self.width * self.height, 4), device=self.device)
            frame[hit, :3] = radiance  # unpack
            frame[:, 3] = 1.0
            image = frame.cpu().numpy()  # device -> host
        self.display.write(image.tobytes())  # host -> GL, where a viewer would show it
        return image

    def render(self, view, light) -> np.ndarray:
        image = self._frame(view, light).reshape(self.height, self.width, 4)
        return np.ascontiguousarray(image[::-1, :, :3])

    def frame_time(self, view, light, *, warmup: int, frames: int) -> FrameTimes:
        """Host wall time of whole frames (trace, copies, network, shading), synchronised: GL
        timer queries would see only the G-buffer pass."""
        torch = self.torch

        def frame() -> None:
            self._frame(view, light)
            self.ctx.finish()
            if self.device != "cpu":
                torch.cuda.synchronize()

        if int(warmup) < 1 or int(frames) < 1:
            raise InvalidInputError(f"warmup={warmup!r}, frames={frames!r}; accepted: "
                                    "integers >= 1 (the first frame is never timed)")
        return wall_frame_times(frame, warmup=int(warmup), frames=frames,
                                renderer=self.renderer_string, source="wall+sync")

    def memory_bytes(self) -> int:
        # Resident weights (float32) and the light matrix, as the GLSL path counts them.
        return int(self.weight_bytes + self.light_bytes)

    def release(self) -> None:
        self.gbuffer.release()
        self.display.release()
