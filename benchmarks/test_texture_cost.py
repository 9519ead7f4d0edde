"""Frame cost of transfer textures against a plain textured-diffuse shader (one run).

Target (issue "PRTT family"): ``texture-tpfl`` costs at most 1.5× a plain textured-diffuse
shader drawing the same atlas mesh at the same resolution. Not collected by the default test
run (``testpaths = ["tests"]``); run with

    .venv/bin/pytest benchmarks/test_texture_cost.py --benchmark-enable -s

It prints the ratios and records them in the benchmark's ``extra_info``; it asserts nothing
about timing (machines differ; on llvmpipe, a CPU rasteriser, the numbers are only meaningful
as ratios within one run). The baseline shader is ``texture_baseline.{vert,frag}``: one RGBA32F
lookup at the atlas UV times a constant, single pass with depth test LESS.
"""

from __future__ import annotations

import numpy as np
import pytest

import methods.texture  # noqa: F401 - registers texture-tp / texture-tpfl
from methods.common.atlas.atlas import AtlasMesh
from methods.texture import SHADER_DIR
from prtbench.api.method import METHODS, load_or_precompute
from prtbench.render import gl
from prtbench.render.raster import clip_planes
from prtbench.scene.registry import get_scene
from prtbench.transport.lights import get_light

RESOLUTIONS = [(320, 240), (640, 480)]
WARMUP, FRAMES = 2, 5


class PlainTexturedDiffuse:
    """The baseline: the artifact's atlas mesh, one albedo texture of the same side."""

    def __init__(self, scene, artifact, *, width: int, height: int):
        self.scene, self.width, self.height = scene, width, height
        self.ctx = ctx = gl.create_context()
        self.program = gl.load_program(ctx, "texture_baseline.vert", "texture_baseline.frag",
                                       search_path=[SHADER_DIR])
        res = int(artifact.meta["texture_resolution"])
        atlas = AtlasMesh.from_arrays(artifact.arrays, resolution=res,
                                      sets=int(artifact.meta["texture_sets"]))
        positions = scene.merged()[0][atlas.vertex_source]
        self.vao = gl.upload_mesh(ctx, self.program, positions, atlas.faces,
                                  attributes={"in_atlas_uv": atlas.uvs})
        albedo = np.random.default_rng(0).random((res, res, 4)).astype(np.float32)
        self.albedo = ctx.texture((res, res), 4, albedo.tobytes(), dtype="f4")
        self.albedo.filter = (ctx.LINEAR, ctx.LINEAR)
        self.target = gl.RenderTarget(ctx, width, height)
        self.timer = gl.GpuTimer(ctx)

    def draw(self, view) -> None:
        near, far = clip_planes(self.scene, view)
        clip_from_world = view.clip_from_camera(self.width / self.height, near, far) @ view.camera_from_world()
        self.program["clip_from_world"].write(clip_from_world.T.astype(np.float32).tobytes())
        self.program["irradiance_over_pi"].value = (1.0, 1.0, 1.0)
        self.albedo.use(location=0)
        self.program["albedo"].value = 0
        self.target.use()
        self.target.clear()
        self.ctx.enable(gl.moderngl.DEPTH_TEST)
        self.ctx.disable(gl.moderngl.CULL_FACE)
        self.ctx.depth_func = "<"
        self.vao.render()

    def release(self) -> None:
        for obj in (self.vao, *self.vao.extra["buffers"], self.program, self.albedo):
            obj.release()
        self.target.release()


@pytest.mark.parametrize(("width", "height"), RESOLUTIONS)
def test_texture_tpfl_cost_against_plain_textured_diffuse(benchmark, width, height):
    scene = get_scene("plants", variant="glossy").with_views(1)
    view, light = scene.trajectory.views[0], get_light("sky")
    times = {}
    for method in ("texture-tpfl", "texture-tp"):
        cls = METHODS.get(method)
        config = cls.make_config({}, profile="quick")
        artifact = load_or_precompute(cls, scene, config, progress=False)
        renderer = cls.renderer(scene, artifact, config, width=width, height=height)
        times[method] = renderer.frame_time(view, light, warmup=WARMUP, frames=FRAMES)
        renderer.release()
    baseline = PlainTexturedDiffuse(scene, artifact, width=width, height=height)
    plain = baseline.timer.time_frames(lambda: baseline.draw(view), warmup=WARMUP, frames=FRAMES)
    baseline.release()

    ratio = times["texture-tpfl"].median_ms / plain.median_ms
    info = {"renderer": times["texture-tpfl"].renderer, "timing": plain.source,
            "plain_ms": plain.median_ms, "tpfl_ms": times["texture-tpfl"].median_ms,
            "tp_ms": times["texture-tp"].median_ms, "tpfl_over_plain": ratio,
            "tp_over_plain": times["texture-tp"].median_ms / plain.median_ms,
            "target_tpfl_over_plain": 1.5}
    benchmark.extra_info.update(info)
    benchmark.pedantic(lambda: None, rounds=1, iterations=1)  # the numbers are in extra_info
    print(f"\n{width}x{height} {info['renderer']} ({info['timing']}): plain {plain.median_ms:.1f} ms, "
          f"texture-tpfl {info['tpfl_ms']:.1f} ms ({ratio:.1f}x), texture-tp {info['tp_ms']:.1f} ms "
          f"({info['tp_over_plain']:.1f}x); target tpfl <= 1.5x")
