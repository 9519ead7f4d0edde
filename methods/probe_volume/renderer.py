"""The probe-volume renderer: a depth pre-pass, then per pixel the probe lookup of
``probe_volume.frag`` over the pool textures (:mod:`.encoding`), the validity texture, the
brick index and the depth moments.

The pool is written once from the artifact (relight: the light-independent transfer; fixed
with ``bake_light``: the baked radiance) or, for a fixed volume without a baked light, once per
light from a CPU fold (:func:`methods.probe_volume.bake.fold`), outside the measured frame.
"""

from __future__ import annotations

import numpy as np

from methods.common.residency import named_breakdown
from methods.probe_volume import SHADER_DIR
from methods.probe_volume.bake import fold
from methods.probe_volume.encoding import (
    COEFFICIENTS,
    SH_ENCODING_BANDS,
    bytes_per_probe,
    decode_glsl,
    encode,
    layout,
)
from prtbench.api.errors import InvalidInputError
from prtbench.api.method import Renderer
from prtbench.render import gl
from prtbench.render.prt_shading import TripleProductBuffers
from prtbench.render.raster import (
    TargetFrames,
    clip_planes,
    draw_after_depth_prepass,
    kd_per_vertex,
)
from prtbench.transport.sh import clamped_cosine_zonal

#: Visibility test → the TEST define of probe_volume.frag.
TESTS = {"none": 0, "validity": 1, "chebyshev": 2}
FLOAT16_MAX = float(np.finfo(np.float16).max)


def _volume_texture(ctx, shape_xyz, components: int, data: np.ndarray, dtype: str):
    """A NEAREST 3D texture of ``data`` (z, y, x, components) at ``shape_xyz``."""
    tex = ctx.texture3d(tuple(int(s) for s in shape_xyz), components,
                        np.ascontiguousarray(data).tobytes(), dtype=dtype, alignment=1)
    tex.filter = (ctx.NEAREST, ctx.NEAREST)
    return tex


class ProbeVolumeRenderer(TargetFrames, Renderer):
    """Draws the scene shaded from the probe pool (see the module docstring)."""

    def __init__(self, scene, artifact, config, *, width: int, height: int):
        self.scene, self.width, self.height = scene, int(width), int(height)
        arrays, meta = artifact.arrays, artifact.meta
        self.encoding, self.storage = config.encoding, config.storage
        self.relight = "transfer" in arrays
        self.channels = 1 if self.relight else 3
        self.bake_bands = int(config.bake_bands)
        cube = self.encoding == "ambient-cube"
        sh_bands = SH_ENCODING_BANDS.get(self.encoding, 3)  # the cube's light at L2 (relight)
        bricks = "brick_index" in arrays
        self.pool_shape = tuple(int(s) for s in meta["pool_shape"])
        self.texel = np.asarray(arrays["probe_texel"], np.int64)
        test = TESTS[config.visibility_test]
        defines = {"COEFFS": COEFFICIENTS[self.encoding], "CHANNELS": self.channels,
                   "RELIGHT": int(self.relight), "CUBE": int(cube), "SH_BANDS": sh_bands,
                   "BRICKS": int(bricks), "TEST": test}
        if not bricks:
            defines["GRID_N"] = int(meta["grid"])
        depth = arrays.get("depth_moments") if test == 2 else None
        if depth is not None:
            texels = depth.shape[1]
            tiles_x = int(np.ceil(np.sqrt(len(depth))))
            defines.update(DEPTH_TEXELS=texels, DEPTH_TILES_X=tiles_x)
        self.ctx = ctx = gl.create_context()
        self.renderer_string = gl.renderer_string(ctx)
        decode = decode_glsl(self.encoding, self.storage, self.channels)
        self.program = gl.load_program(ctx, "probe_volume.vert", "probe_volume.frag",
                                       defines=defines, search_path=[SHADER_DIR],
                                       sources={"probe_decode.glsl": decode})
        self.depth_program = gl.load_program(ctx, "probe_volume.vert", "probe_depth.frag",
                                             search_path=[SHADER_DIR])
        positions, normals, faces, _ = scene.merged()
        self.vao = gl.upload_mesh(ctx, self.program, positions, faces,
                                  attributes={"normal": normals, "kd": kd_per_vertex(scene)})
        self.depth_vao = gl.upload_mesh(ctx, self.depth_program, positions, faces)
        self.target = gl.RenderTarget(ctx, self.width, self.height)
        self.timer = gl.GpuTimer(ctx)
        self._parts: dict[str, int] = {}
        self._units: list = []  # (texture, unit) bound before each draw
        units = 0
        # The pool: one texture per layout entry, slots beyond the probes left empty.
        self.pool = []
        zeros = {"f2": np.float16, "u1": np.uint8}
        for t, (dtype, _) in enumerate(layout(self.encoding, self.storage, self.channels)):
            data = np.zeros(self.pool_shape[::-1] + (4,), zeros[dtype])
            tex = _volume_texture(ctx, self.pool_shape, 4, data, "f2" if dtype == "f2" else "f1")
            self.pool.append(tex)
            self._bind_unit(f"pool{t}", tex, units)
            units += 1
        textures = layout(self.encoding, self.storage, self.channels)
        halves = sum(dtype == "f2" for dtype, _ in textures)
        what = (f"probe pool ({self.storage}, {self.encoding}, {self.channels}-channel: "
                f"{halves} RGBA16F + {len(textures) - halves} RGBA8 per probe)")
        self._count(what, int(np.prod(self.pool_shape))
                    * bytes_per_probe(self.encoding, self.storage, self.channels))
        valid = np.zeros(self.pool_shape[::-1], np.uint8)
        tx = self.texel
        valid[tx[:, 2], tx[:, 1], tx[:, 0]] = np.where(arrays["valid"] > 0, 255, 0)
        self.valid_texture = _volume_texture(ctx, self.pool_shape, 1, valid, "f1")
        self._count("probe validity (R8)", valid.nbytes)
        self._bind_unit("probe_valid", self.valid_texture, units)
        units += 1
        if bricks:
            index = np.asarray(arrays["brick_index"], np.uint32)
            self.index_texture = _volume_texture(ctx, index.shape, 1, index.transpose(2, 1, 0),
                                                 "u4")
            self._count("brick index (R32UI)", index.nbytes)
            self._bind_unit("brick_index", self.index_texture, units)
            units += 1
            self.program["pool_bricks"].value = tuple(int(b) for b in meta["pool_bricks"])
        if depth is not None:
            self.depth_texture = self._depth_texture(depth, tiles_x)
            self._bind_unit("depth_moments", self.depth_texture, units)
            units += 1
        self.triple = None
        if self.relight and not cube:
            self.triple = TripleProductBuffers(ctx, sh_bands, gamma=True)
            self._count("Γ list (relight triple product)", self.triple.memory_bytes())
        if "zonal" in self.program:  # not read by the baked ambient cube
            self.program["zonal"].write(clamped_cosine_zonal(sh_bands).astype(np.float32)
                                        .tobytes())
        self.program["volume_origin"].value = tuple(float(c) for c in arrays["volume_origin"])
        self.program["cell_size"].value = tuple(float(c) for c in arrays["cell_size"])
        self.program["normal_bias"].value = float(config.normal_bias)
        self.sh_bands = sh_bands
        self.baked_hash, self.baked_name = meta.get("bake_light_hash"), meta.get("bake_light")
        self.bakes_its_light = self.baked_hash is not None  # another light: a new precompute
        self.visibility = arrays.get("visibility")
        self.folded: str | None = None
        if self.relight:
            self._write_pool(np.asarray(arrays["transfer"], np.float64)[:, :, None], light=None)
        elif self.baked_hash is not None:
            self._write_pool(np.asarray(arrays["radiance"], np.float64), light=self.baked_name)
            self.folded = self.baked_hash

    # -- setup ------------------------------------------------------------------------------
    def _count(self, name: str, nbytes: int) -> None:
        key = f"gpu: {name}"
        self._parts[key] = self._parts.get(key, 0) + int(nbytes)

    def _bind_unit(self, name: str, texture, unit: int) -> None:
        self._units.append((texture, unit))
        if name in self.program:  # a sampler the shader does not read is compiled out
            self.program[name].value = unit

    def _depth_texture(self, depth: np.ndarray, tiles_x: int):
        p, d = depth.shape[0], depth.shape[1]
        tiles_y = -(-p // tiles_x)
        image = np.zeros((tiles_y * d, tiles_x * d, 2), np.float16)
        ids = np.arange(p)
        for j in range(d):
            for i in range(d):
                image[(ids // tiles_x) * d + j, (ids % tiles_x) * d + i] = depth[:, j, i]
        tex = self.ctx.texture((tiles_x * d, tiles_y * d), 2, image.tobytes(), dtype="f2")
        tex.filter = (self.ctx.NEAREST, self.ctx.NEAREST)
        self._count(f"depth moments (RG16F, {d}×{d} per probe)", image.nbytes)
        return tex

    def _write_pool(self, values: np.ndarray, *, light: str | None) -> None:
        """Encode per-probe coefficients (P, K, C) and upload them into the pool."""
        textures = layout(self.encoding, self.storage, self.channels)
        if any(dtype == "f2" for dtype, _ in textures) and values.size:
            peak = float(np.abs(values).max())
            if not np.isfinite(peak) or peak > FLOAT16_MAX:
                raise InvalidInputError(
                    f"light '{light}' gives probe radiance {peak:.4g}, beyond the half floats "
                    f"of the pool (±{FLOAT16_MAX:.0f}); accepted: a light whose probe radiance "
                    "fits float16, or light_mode=relight (the light stays out of the pool)")
        tx = self.texel
        for tex, encoded, (dtype, _) in zip(self.pool, encode(values, encoding=self.encoding,
                                                              storage=self.storage), textures):
            data = np.zeros(self.pool_shape[::-1] + (4,), encoded.dtype)
            data[tx[:, 2], tx[:, 1], tx[:, 0]] = encoded
            tex.write(data.tobytes())

    # -- per light --------------------------------------------------------------------------
    def _check_light(self, light) -> None:
        if self.baked_hash is not None and light.content_hash() != self.baked_hash:
            raise InvalidInputError(
                f"this probe volume bakes light '{self.baked_name}', not '{light.name}'; "
                f"accepted: render with light '{self.baked_name}', or precompute with "
                f"bake_light={light.name} (--set bake_light={light.name}), or bake_light empty "
                "(each light baked when rendered), or light_mode=relight")

    def fold_light(self, light) -> None:
        """Fixed volumes without a baked light: fold ``light`` into the pool once per light."""
        key = light.content_hash()
        if self.relight or key == self.folded:
            return
        self._write_pool(fold(self.visibility, light.sh(self.bake_bands),
                              encoding=self.encoding, bake_bands=self.bake_bands),
                         light=light.name)
        self.folded = key

    def _draw(self, view, light) -> None:
        near, far = clip_planes(self.scene, view)
        clip_from_world = (view.clip_from_camera(self.width / self.height, near, far)
                           @ view.camera_from_world()).T.astype(np.float32).tobytes()
        self.program["clip_from_world"].write(clip_from_world)
        self.depth_program["clip_from_world"].write(clip_from_world)
        self.fold_light(light)  # fixed: once per light; later frames of it only bind
        for tex, unit in self._units:
            tex.use(location=unit)
        if self.relight:
            coeffs = np.ascontiguousarray(light.sh(self.sh_bands), np.float32)
            self.program["light_sh"].write(coeffs.tobytes())
            if self.triple is not None:
                self.triple.bind_gamma()
        draw_after_depth_prepass(self.ctx, self.target, self.depth_vao, self.vao)

    def memory_breakdown(self) -> dict[str, int]:
        """The pool, validity, brick index, depth moments and Γ list, by name; then the mesh
        buffers, the render target and the CPU arrays the renderer keeps (a fixed volume
        without a baked light keeps the probes' visibility SH to fold each new light)."""
        return named_breakdown(self, self._parts, [*(tex for tex, _ in self._units),
                                                   self.triple])

    def memory_bytes(self) -> int:
        """The method's own data: pool, validity, brick index, depth moments, Γ list."""
        return int(sum(self._parts.values()))

    def pool_texels(self) -> list[np.ndarray]:
        """The pool textures as uploaded, (P, 4) per texture in probe order (for tests)."""
        out = []
        tx = self.texel
        for tex, (dtype, _) in zip(self.pool, layout(self.encoding, self.storage, self.channels)):
            kind = np.float16 if dtype == "f2" else np.uint8
            data = np.frombuffer(tex.read(), kind).reshape(self.pool_shape[::-1] + (4,))
            out.append(data[tx[:, 2], tx[:, 1], tx[:, 0]])
        return out

    def release(self) -> None:
        for obj in [self.vao, *self.vao.extra["buffers"], self.depth_vao,
                    *self.depth_vao.extra["buffers"], self.program, self.depth_program,
                    *(tex for tex, _ in self._units)]:
            obj.release()
        if self.triple is not None:
            self.triple.release()
        self.target.release()
