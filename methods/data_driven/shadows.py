"""Shadow maps of the data-driven method's analytic lights, in one R32F atlas.

A point light (or a spot wider than ``MAX_SPOT_TILE_DEG``) renders six 90°+ cube tiles, a spot
one perspective tile around its cone, a directional light one orthographic tile fitted to the
scene's bounding sphere. Tiles store a linear metric (distance to the light, or depth along its
travel direction); receivers compare against it with a normal offset and depth bias scaled to
the shadow texel's world size and filter with 2×2 bilinear PCF (``data_driven_lights.glsl``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from methods.data_driven import SHADER_DIR
from methods.data_driven.lights import (
    DirectionalLight,
    PointLight,
    SpotLight,
    analytic_lights,
    is_environment,
)
from prtbench.api.errors import InvalidInputError
from prtbench.render import gl
from prtbench.scene.model import View

MAX_LIGHTS = 64
MAX_TILES = 96
#: Spot lights wider than this use six cube tiles instead of one perspective tile.
MAX_SPOT_TILE_DEG = 65.0
#: Normal offset and depth bias of shadow lookups, in shadow texels at the receiver.
SHADOW_BIAS = (1.5, 1.0)


def _ortho(half: float, near: float, far: float) -> np.ndarray:
    m = np.eye(4)
    m[0, 0] = m[1, 1] = 1.0 / half
    m[2, 2] = -2.0 / (far - near)
    m[2, 3] = -(far + near) / (far - near)
    return m


def _up_for(forward: np.ndarray) -> tuple[float, float, float]:
    return (0.0, 1.0, 0.0) if abs(forward[1]) < 0.9 else (1.0, 0.0, 0.0)


class ShadowTiles:
    """Tile matrices for a list of analytic lights, and the light uniform arrays.

    Parameters
    ----------
    lights : list of analytic lights
    lo, hi : ndarray, shape (3,)
        Scene bounds.
    resolution : int
        Tile side in texels.
    """

    CUBE = ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1))

    def __init__(self, lights: list, lo: np.ndarray, hi: np.ndarray, *, resolution: int):
        if len(lights) > MAX_LIGHTS:
            raise InvalidInputError(f"{len(lights)} lights; accepted: at most {MAX_LIGHTS}")
        self.resolution = int(resolution)
        centre = (lo + hi) / 2
        radius = max(float(np.linalg.norm(hi - lo)) / 2, 1e-6)
        self.matrices: list[np.ndarray] = []
        self.refs: list[np.ndarray] = []
        self.factors: list[float] = []
        self.light_arrays = np.zeros((4, MAX_LIGHTS, 4), np.float32)
        for i, light in enumerate(lights):
            first = len(self.matrices)
            tiles = 1
            pos_type = np.zeros(4)
            axis_cos = np.array([0.0, 0.0, -1.0, -2.0])
            cone = np.zeros(4)
            if isinstance(light, DirectionalLight):
                d = -np.asarray(light.to_light)
                eye = centre - d * 2.0 * radius
                cam = View(tuple(eye), tuple(centre), _up_for(d)).camera_from_world()
                self._add(_ortho(radius, radius, 3.0 * radius) @ cam, np.append(d, 0.0),
                          2.0 * radius / self.resolution)
                pos_type[:3], pos_type[3] = light.to_light, 0.0
                power = light.irradiance
            else:
                position = np.asarray(light.position)
                far = float(np.max(np.linalg.norm(
                    np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                              for z in (lo[2], hi[2])]) - position, axis=1))) * 1.01 + 1e-3
                near = max(1e-4 * radius, far * 1e-5)
                pos_type[:3] = position
                pos_type[3] = 1.0 if isinstance(light, PointLight) else 2.0
                power = light.intensity
                if isinstance(light, SpotLight) and light.cutoff_deg <= MAX_SPOT_TILE_DEG:
                    fov = min(2.0 * light.cutoff_deg + 4.0, 170.0)
                    self._perspective(position, np.asarray(light.direction), fov, near, far)
                else:
                    # 90° faces widened by two texels so PCF taps at a face's edge stay inside.
                    fov = 2.0 * math.degrees(math.atan(1.0 + 4.0 / self.resolution))
                    for axis in self.CUBE:
                        self._perspective(position, np.asarray(axis, float), fov, near, far)
                    tiles = 6
                if isinstance(light, SpotLight):
                    cutoff, beam = math.radians(light.cutoff_deg), math.radians(light.beam_deg)
                    axis_cos = np.append(light.direction, math.cos(cutoff))
                    cone = np.array([cutoff, math.cos(beam), 1.0 / (cutoff - beam), 0.0])
            cone[3] = tiles
            self.light_arrays[0, i] = pos_type
            self.light_arrays[1, i] = axis_cos
            self.light_arrays[2, i] = np.append(power, first)
            self.light_arrays[3, i] = cone
        self.n_lights = len(lights)
        if len(self.matrices) > MAX_TILES:
            raise InvalidInputError(f"{len(self.matrices)} shadow tiles; accepted: at most {MAX_TILES}")
        self.grid = max(1, int(math.ceil(math.sqrt(max(len(self.matrices), 1)))))

    def _add(self, matrix: np.ndarray, ref: np.ndarray, factor: float) -> None:
        self.matrices.append(matrix)
        self.refs.append(ref)
        self.factors.append(factor)

    def _perspective(self, position, forward, fov, near, far) -> None:
        view = View(tuple(position), tuple(position + forward), _up_for(forward), fov)
        matrix = view.clip_from_camera(1.0, near, far) @ view.camera_from_world()
        self._add(matrix, np.append(position, 1.0),
                  2.0 * math.tan(math.radians(fov) / 2) / self.resolution)

    @property
    def n_tiles(self) -> int:
        return len(self.matrices)

    @property
    def light_scale(self) -> float:
        """The largest power component of the lights (1 when all are black).

        The gamma-space transfer divides the direct light by it before v^(1/γ) and multiplies
        the decoded indirect light by it: the transfer is homogeneous of degree 1 in the light,
        so this changes nothing but keeps float32 finite (a 10⁶ light at γ = 0.1 is 10⁶⁰).
        """
        peak = float(np.max(np.abs(self.light_arrays[2, :self.n_lights, :3]), initial=0.0))
        return peak if peak > 0.0 and math.isfinite(peak) else 1.0

    def offset(self, t: int) -> tuple[int, int]:
        return (t % self.grid) * self.resolution, (t // self.grid) * self.resolution

    def tile_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        mats = np.zeros((MAX_TILES, 4, 4), np.float32)
        rects = np.zeros((MAX_TILES, 4), np.float32)
        refs = np.zeros((MAX_TILES, 4), np.float32)
        for t, (m, r, f) in enumerate(zip(self.matrices, self.refs, self.factors)):
            mats[t] = m.T  # column-major for GLSL
            x, y = self.offset(t)
            rects[t] = (x, y, self.resolution, f)
            refs[t] = r
        return mats, rects, refs


class DirectLighting:
    """Shadow atlas + light uniforms for one GL context and one scene mesh."""

    def __init__(self, ctx, positions: np.ndarray, faces: np.ndarray, *, lo: np.ndarray,
                 hi: np.ndarray, shadow_resolution: int, env_shadow_resolution: int,
                 env_lights: int):
        self.ctx = ctx
        self.lo, self.hi = np.asarray(lo, float), np.asarray(hi, float)
        self.shadow_resolution = int(shadow_resolution)
        self.env_shadow_resolution = int(env_shadow_resolution)
        self.env_lights = int(env_lights)
        self.program = gl.load_program(ctx, "data_driven_shadow.vert", "data_driven_shadow.frag",
                                       search_path=[SHADER_DIR])
        self.vao = gl.upload_mesh(ctx, self.program, positions, faces)
        self.atlas = None
        self.fbo = None
        self.depth = None
        self.side = 0
        self.tiles: ShadowTiles | None = None
        self._light_key: Any = None

    def set_light(self, light: Any) -> None:
        """Derive the analytic lights (median cut for maps) and their tiles; cached per light."""
        key = id(light)
        if self._light_key == key and self.tiles is not None:
            return
        lights = analytic_lights(light, env_lights=self.env_lights)
        resolution = self.env_shadow_resolution if is_environment(light) else self.shadow_resolution
        self.tiles = ShadowTiles(lights, self.lo, self.hi, resolution=resolution)
        side = self.tiles.grid * resolution
        if side != self.side:
            self._release_atlas()
            self.atlas = self.ctx.texture((side, side), 1, dtype="f4")
            self.atlas.filter = (self.ctx.NEAREST, self.ctx.NEAREST)
            self.depth = self.ctx.depth_renderbuffer((side, side))
            self.fbo = self.ctx.framebuffer(color_attachments=[self.atlas],
                                            depth_attachment=self.depth)
            self.side = side
        self._light_key = key
        self._light = light  # keeps id() valid

    def render_shadows(self) -> None:
        """Draw every tile of the current light into the atlas."""
        tiles = self.tiles
        self.fbo.use()
        self.ctx.viewport = (0, 0, self.side, self.side)
        self.fbo.clear(1e30, 1e30, 1e30, 1e30, depth=1.0)
        self.ctx.enable(gl.moderngl.DEPTH_TEST)
        self.ctx.disable(gl.moderngl.CULL_FACE)
        for t in range(tiles.n_tiles):
            x, y = tiles.offset(t)
            self.ctx.viewport = (x, y, tiles.resolution, tiles.resolution)
            self.program["clip_from_world"].write(tiles.matrices[t].T.astype(np.float32).tobytes())
            self.program["ref"].value = tuple(float(c) for c in tiles.refs[t])
            self.vao.render()

    def bind(self, program, *, unit: int) -> None:
        """Write the light/tile uniforms of the current light and bind the atlas to ``unit``."""
        tiles = self.tiles
        program["n_lights"].value = tiles.n_lights
        names = ("light_pos_type", "light_axis_cos", "light_power_tile", "light_cone")
        for name, values in zip(names, tiles.light_arrays):
            program[name].write(np.ascontiguousarray(values).tobytes())
        mats, rects, refs = tiles.tile_arrays()
        program["tile_matrix"].write(mats.tobytes())
        program["tile_rect"].write(rects.tobytes())
        program["tile_ref"].write(refs.tobytes())
        program["shadow_bias"].value = SHADOW_BIAS
        self.atlas.use(unit)
        program["shadow_atlas"].value = unit

    def _release_atlas(self) -> None:
        for obj in (self.fbo, self.atlas, self.depth):
            if obj is not None:
                obj.release()
        self.fbo = self.atlas = self.depth = None
        self.side = 0

    def memory_bytes(self) -> int:
        return int(self.side * self.side * 8)  # R32F + 32-bit depth

    def release(self) -> None:
        self._release_atlas()
        buffers = (getattr(self.vao, "extra", None) or {}).get("buffers", [])
        for obj in [self.vao, *buffers, self.program]:
            obj.release()


LIGHT_DEFINES = {"MAX_LIGHTS": MAX_LIGHTS, "MAX_TILES": MAX_TILES}
