"""Shared rasterisation plumbing for GL methods: scene upload, camera, draw, read, timing.

A method's renderer subclasses :class:`RasterRenderer` and names its own shader folder in
``shader_dirs``; the core's shaders (``interpolated_radiance.frag``, ``brdf.glsl``, ...) are
always found after them.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from prtbench.api.method import FrameTimes, Renderer
from prtbench.render import gl


def kd_per_vertex(scene) -> np.ndarray:
    """(V, 3) float32 constant diffuse albedo of each vertex's object, merged order."""
    return np.concatenate([np.broadcast_to(np.asarray(o.material.kd, np.float32),
                                           (o.mesh.n_vertices, 3)) for o in scene.objects])


def clip_planes(scene, view) -> tuple[float, float]:
    """Near/far planes enclosing the scene from ``view`` (far generous, near not too small)."""
    lo, hi = scene.bounds()
    centre, radius = (lo + hi) / 2, np.linalg.norm(hi - lo) / 2
    dist = float(np.linalg.norm(np.asarray(view.eye) - centre))
    far = dist + radius * 1.01 + 1e-3
    near = max(dist - radius * 1.01, far * 1e-4)
    return near, far


def draw_after_depth_prepass(ctx, target, depth_vao, vao) -> None:
    """Clear ``target``, write ``depth_vao``'s depth only, then draw ``vao`` with an early depth
    test (``<=``) and no depth writes, so each pixel's visible fragment is shaded once. Back
    faces are not culled: they occlude and are shaded black, as in the reference."""
    fbo = target.fbo
    target.use()
    fbo.color_mask = (True, True, True, True)
    fbo.depth_mask = True
    target.clear()
    ctx.enable(gl.moderngl.DEPTH_TEST)
    ctx.disable(gl.moderngl.CULL_FACE)
    ctx.depth_func = "<"
    fbo.color_mask = (False, False, False, False)
    depth_vao.render()
    fbo.color_mask = (True, True, True, True)
    fbo.depth_mask = False
    ctx.depth_func = "<="
    vao.render()
    fbo.depth_mask = True
    ctx.depth_func = "<"


class TargetFrames:
    """``render`` and ``frame_time`` of a renderer that draws a frame with ``_draw(view, light)``
    into ``self.target`` (timed by ``self.timer``), after ``_check_light`` refused what it
    cannot render (the default accepts every light)."""

    def _check_light(self, light) -> None:
        """Raise for a light this renderer cannot render (e.g. not the baked one)."""

    def render(self, view, light) -> np.ndarray:
        self._check_light(light)
        self._draw(view, light)
        return np.ascontiguousarray(self.target.read()[..., :3])

    def frame_time(self, view, light, *, warmup: int, frames: int) -> FrameTimes:
        self._check_light(light)
        times = self.timer.time_frames(lambda: self._draw(view, light), warmup=warmup,
                                       frames=frames)
        return FrameTimes(times.median_ms, times.p95_ms, times.mean_ms, frames,
                          self.renderer_string, times.source)


class RasterRenderer(TargetFrames, Renderer):
    """Draws the merged scene mesh with one program into a float32 target.

    Subclasses bind their data in :meth:`_bind` (called before each draw), may add vertex
    attributes via ``extra_attributes``, and name the folders of their shader stages in
    :attr:`shader_dirs`.
    """

    #: Folders searched for the stages and includes before the core's ``render/shaders``.
    shader_dirs: ClassVar[Sequence[Path]] = ()

    def __init__(self, scene, *, width: int, height: int, vertex_shader: str, fragment_shader: str,
                 defines: dict[str, Any], extra_attributes: dict[str, np.ndarray] | None = None):
        self.scene, self.width, self.height = scene, width, height
        self.ctx = gl.create_context()
        self.renderer_string = gl.renderer_string(self.ctx)
        self.program = gl.load_program(self.ctx, vertex_shader, fragment_shader, defines=defines,
                                       search_path=list(self.shader_dirs))
        positions, normals, faces, _ = scene.merged()
        attributes = {"normal": normals, "kd": kd_per_vertex(scene), **(extra_attributes or {})}
        self.vao = gl.upload_mesh(self.ctx, self.program, positions, faces, attributes=attributes)
        self.target = gl.RenderTarget(self.ctx, width, height)
        self.timer = gl.GpuTimer(self.ctx)

    def _bind(self, view, light) -> None:  # pragma: no cover - overridden
        raise NotImplementedError

    def _draw(self, view, light) -> None:
        near, far = clip_planes(self.scene, view)
        clip_from_world = view.clip_from_camera(self.width / self.height, near, far) @ view.camera_from_world()
        self.program["clip_from_world"].write(clip_from_world.T.astype(np.float32).tobytes())
        if "eye" in self.program:
            self.program["eye"].value = tuple(float(c) for c in view.eye)
        self._bind(view, light)
        self.target.use()
        self.target.clear()
        self.ctx.enable(gl.moderngl.DEPTH_TEST)
        self.ctx.disable(gl.moderngl.CULL_FACE)  # back faces are shaded black, as in the reference
        self.vao.render()

    def release(self) -> None:
        buffers = (getattr(self.vao, "extra", None) or {}).get("buffers", [])
        for obj in [self.vao, *buffers, self.program, *getattr(self, "_resident", [])]:
            obj.release()
        self.target.release()
