"""GL side of SDF scenes: programs with the generated ``scene_sdf.glsl``, the camera, a
sphere-traced G-buffer, point probes and GPU occlusion queries.

Programs are built with :func:`load_sdf_program`, which hands the surface's generated GLSL to
:func:`prtbench.render.gl.load_program` as the virtual include ``scene_sdf.glsl``; a fragment shader
then ``#include``\\ s ``sdf_camera.glsl`` (:func:`bind_camera` sets its uniforms) and
``sdf_trace.glsl`` (``bool trace(vec3 ro, vec3 rd, out vec3 p, out vec3 n, out int material)``)
and is drawn as one full-screen triangle (``sdf_fullscreen.vert``, :func:`fullscreen_vao`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

import numpy as np

from prtbench.api.errors import InvalidInputError
from prtbench.render import gl
from prtbench.scene.model import Material, View
from prtbench.transport.sdf.nodes import SdfNode
from prtbench.transport.sdf.surface import MAX_STEPS, RELAXATION, SdfSurface, as_surface
from prtbench.transport.sdf.trace import OCCLUSION_BACKENDS

#: Fragments per row of the probe/occlusion targets (one fragment per point or ray).
ROW_WIDTH = 1024

#: Rays per occlusion draw (bounds the target and SSBOs to ~48 MB).
GL_CHUNK_RAYS = 1 << 20


def load_sdf_program(ctx, surface: Any, fragment: str, *, vertex: str = "sdf_fullscreen.vert",
                     defines: Mapping[str, object] | None = None,
                     sources: Mapping[str, str] | None = None,
                     search_path: Sequence[str] = (), max_steps: int = MAX_STEPS,
                     relaxation: float = RELAXATION):
    """A program whose stages may ``#include "sdf_trace.glsl"`` for ``surface``'s SDF.

    Parameters
    ----------
    ctx : moderngl.Context
    surface : SdfSurface or Scene with ``sdf``
    fragment, vertex : str
        Stage files (``search_path``, then the core's ``prtbench/render/shaders``).
    defines : dict, optional
        Extra ``#define``\\ s (``SDF_MAX_STEPS`` / ``SDF_RELAXATION`` come from the keywords).
    sources : dict, optional
        More virtual files (e.g. a method's generated network code) beside ``scene_sdf.glsl``.
    search_path : sequence of str
        Extra directories for stage files and includes.

    Returns
    -------
    moderngl.Program
    """
    sdf = as_surface(surface)
    all_defines = {"SDF_MAX_STEPS": int(max_steps), "SDF_RELAXATION": float(relaxation),
                   **(defines or {})}
    return gl.load_program(ctx, vertex, fragment, defines=all_defines,
                           sources={**sdf.glsl_sources(), **(sources or {})},
                           search_path=search_path)


def bind_camera(program, view: View, width: int, height: int) -> None:
    """Set the ``sdf_camera.glsl`` uniforms so ``primary_ray`` equals ``view.primary_rays``."""
    m = view.world_from_camera()
    program["sdf_eye"].value = tuple(float(c) for c in m[:3, 3])
    # GLSL mat3 is column-major: the camera axes (columns of m) are written one after another.
    program["sdf_world_from_camera"].write(
        np.ascontiguousarray(m[:3, :3].T, dtype=np.float32).tobytes())
    program["sdf_tan_half_fov"].value = math.tan(math.radians(view.fov_y) / 2)
    program["sdf_viewport"].value = (float(width), float(height))


def fullscreen_vao(ctx, program):
    """A vertex array drawing one viewport-covering triangle: ``vao.render(vertices=3)``."""
    return ctx.vertex_array(program, [])


class SdfGBuffer(NamedTuple):
    """Sphere-traced G-buffer, row 0 at the top.

    Attributes
    ----------
    positions, normals : ndarray, shape (H, W, 3), float32
        Hit points and unit normals (0 where nothing is hit).
    material : ndarray, shape (H, W), int32
        Material id, -1 where nothing is hit.
    mask : ndarray, shape (H, W), bool
    """

    positions: np.ndarray
    normals: np.ndarray
    material: np.ndarray
    mask: np.ndarray


class GBufferPass:
    """A reusable sphere-traced G-buffer pass (``sdf_gbuffer.frag``) of one surface and size.

    Parameters
    ----------
    ctx : moderngl.Context
    scene_or_sdf : Scene with ``sdf``, or SdfSurface
    width, height : int
    max_steps, relaxation : as :func:`prtbench.transport.sdf.march`

    Attributes
    ----------
    target : prtbench.render.gl.RenderTarget
        Attachment 0: (position, hit); attachment 1: (normal, material id or -1).
    """

    def __init__(self, ctx, scene_or_sdf: Any, width: int, height: int, *,
                 max_steps: int = MAX_STEPS, relaxation: float = RELAXATION):
        self.ctx, self.width, self.height = ctx, int(width), int(height)
        self.program = load_sdf_program(ctx, scene_or_sdf, "sdf_gbuffer.frag",
                                        max_steps=max_steps, relaxation=relaxation)
        self.vao = fullscreen_vao(ctx, self.program)
        self.target = gl.RenderTarget(ctx, self.width, self.height, attachments=2)

    def draw(self, view: View) -> None:
        """Trace ``view`` into :attr:`target` (no readback: what a frame timer should time)."""
        bind_camera(self.program, view, self.width, self.height)
        self.target.use()
        self.target.clear()
        self.ctx.disable(gl.moderngl.DEPTH_TEST)
        self.vao.render(gl.moderngl.TRIANGLES, vertices=3)

    def read(self) -> SdfGBuffer:
        """Read the last drawn G-buffer back (row 0 at the top)."""
        position, normal = self.target.read(0), self.target.read(1)
        mask = position[..., 3] > 0.5
        material = np.where(mask, np.rint(normal[..., 3]), -1).astype(np.int32)
        return SdfGBuffer(np.ascontiguousarray(position[..., :3]),
                          np.ascontiguousarray(normal[..., :3]), material, mask)

    def render(self, view: View) -> SdfGBuffer:
        """:meth:`draw` then :meth:`read`."""
        self.draw(view)
        return self.read()

    def release(self) -> None:
        """Free the GL objects."""
        self.target.release()
        self.vao.release()
        self.program.release()


def sdf_gbuffer(ctx, scene_or_sdf: Any, view: View, width: int, height: int, *,
                max_steps: int = MAX_STEPS, relaxation: float = RELAXATION) -> SdfGBuffer:
    """Sphere-trace the primary rays of ``view`` on the GPU (``sdf_gbuffer.frag``), once.

    Pixel centres are exactly :meth:`prtbench.scene.model.View.primary_rays`; use
    :class:`GBufferPass` to trace many views without recompiling.

    Parameters
    ----------
    ctx : moderngl.Context
    scene_or_sdf : Scene with ``sdf``, or SdfSurface
    view : View
    width, height : int

    Returns
    -------
    SdfGBuffer
        positions (H, W, 3), normals (H, W, 3), material (H, W) int32 (-1: miss), mask (H, W).
    """
    gbuffer = GBufferPass(ctx, scene_or_sdf, width, height, max_steps=max_steps,
                          relaxation=relaxation)
    try:
        return gbuffer.render(view)
    finally:
        gbuffer.release()


def _probe_surface(sdf: Any, points: np.ndarray) -> SdfSurface:
    """``sdf`` as a surface: a bare node gets bounds around ``points`` and grey materials."""
    if isinstance(sdf, SdfNode):
        lo, hi = points.min(axis=0) - 1.0, points.max(axis=0) + 1.0
        ids = sdf.material_ids()
        return SdfSurface(sdf, (tuple(lo), tuple(hi)), (Material(),) * (max(ids, default=0) + 1))
    return as_surface(sdf)


def _grid_rows(n: int) -> int:
    return max(1, -(-n // ROW_WIDTH))


def evaluate_gl(sdf: Any, points: np.ndarray, *, ctx=None,
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Evaluate the generated GLSL at points (``sdf_points.frag``), float32 on the GPU.

    Parameters
    ----------
    sdf : SdfNode, SdfSurface or Scene with ``sdf``
    points : ndarray, shape (N, 3)

    Returns
    -------
    distance (N,) float32, material (N,) int32, normal (N, 3) float32 (``sdf_normal``).
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if len(p) == 0:
        raise InvalidInputError("no points to evaluate; accepted: (N, 3) with N > 0")
    ctx = ctx or gl.create_context()
    surface = _probe_surface(sdf, p)
    program = load_sdf_program(ctx, surface, "sdf_points.frag")
    vao = fullscreen_vao(ctx, program)
    rows = _grid_rows(len(p))
    padded = np.zeros((len(p), 4), dtype=np.float32)
    padded[:, :3] = p
    buffer = ctx.buffer(padded.tobytes())
    target = gl.RenderTarget(ctx, ROW_WIDTH, rows, attachments=2)
    try:
        buffer.bind_to_storage_buffer(0)
        program["n_points"].value = len(p)
        program["row_width"].value = ROW_WIDTH
        target.use()
        target.clear()
        ctx.disable(gl.moderngl.DEPTH_TEST)
        vao.render(gl.moderngl.TRIANGLES, vertices=3)
        # read() puts row 0 at the top; the shader counts rows from the bottom (gl_FragCoord).
        value = target.read(0)[::-1].reshape(-1, 4)[:len(p)]
        normal = target.read(1)[::-1].reshape(-1, 4)[:len(p)]
    finally:
        target.release()
        buffer.release()
        vao.release()
        program.release()
    return value[:, 0].copy(), np.rint(value[:, 1]).astype(np.int32), normal[:, :3].copy()


class GlOcclusion:
    """Batched occlusion queries by sphere tracing in a fragment shader (``sdf_occlusion.frag``).

    Parameters
    ----------
    surface : SdfSurface or Scene with ``sdf``
    max_steps, relaxation : as :func:`prtbench.transport.sdf.march`
    ctx : moderngl.Context, optional
    """

    def __init__(self, surface: Any, *, max_steps: int = MAX_STEPS,
                 relaxation: float = RELAXATION, ctx=None):
        self.ctx = ctx or gl.create_context()
        self.surface = as_surface(surface)
        self.program = load_sdf_program(self.ctx, self.surface, "sdf_occlusion.frag",
                                        max_steps=max_steps, relaxation=relaxation)
        self.vao = fullscreen_vao(self.ctx, self.program)
        self._target: gl.RenderTarget | None = None

    def _target_for(self, rows: int) -> gl.RenderTarget:
        if self._target is None or self._target.height != rows:
            if self._target is not None:
                self._target.release()
            self._target = gl.RenderTarget(self.ctx, ROW_WIDTH, rows)
        return self._target

    def occluded(self, origins: np.ndarray, directions: np.ndarray, *,
                 tmax: float | np.ndarray = np.inf) -> np.ndarray:
        """(N,) bool for rays from (already offset) ``origins`` along ``directions``."""
        o = np.asarray(origins, dtype=np.float32).reshape(-1, 3)
        d = np.asarray(directions, dtype=np.float32).reshape(-1, 3)
        if len(o) != len(d):
            raise InvalidInputError(f"{len(o)} ray origins but {len(d)} directions; "
                                    "accepted: equal counts")
        t_max = np.broadcast_to(np.minimum(np.asarray(tmax, dtype=np.float64), 3.0e38),
                                (len(o),)).astype(np.float32)
        out = np.zeros(len(o), dtype=bool)
        for s in range(0, len(o), GL_CHUNK_RAYS):
            e = min(s + GL_CHUNK_RAYS, len(o))
            out[s:e] = self._draw(o[s:e], d[s:e], t_max[s:e])
        return out

    def _draw(self, o: np.ndarray, d: np.ndarray, t_max: np.ndarray) -> np.ndarray:
        n = len(o)
        if n == 0:
            return np.zeros(0, dtype=bool)
        rows = _grid_rows(n)
        origin_buf = self.ctx.buffer(np.concatenate([o, t_max[:, None]], axis=1).tobytes())
        direction_buf = self.ctx.buffer(np.concatenate([d, np.zeros((n, 1), np.float32)],
                                                       axis=1).tobytes())
        try:
            origin_buf.bind_to_storage_buffer(0)
            direction_buf.bind_to_storage_buffer(1)
            self.program["n_rays"].value = n
            self.program["row_width"].value = ROW_WIDTH
            target = self._target_for(rows)
            target.use()
            target.clear()
            self.ctx.disable(gl.moderngl.DEPTH_TEST)
            self.vao.render(gl.moderngl.TRIANGLES, vertices=3)
            result = target.read(0)[::-1].reshape(-1, 4)[:n, 0]
        finally:
            origin_buf.release()
            direction_buf.release()
        return result > 0.5

    def release(self) -> None:
        """Free the GL objects."""
        if self._target is not None:
            self._target.release()
            self._target = None
        self.vao.release()
        self.program.release()


OCCLUSION_BACKENDS["gl"] = GlOcclusion  # SdfTracer(backend="gl") traces here
