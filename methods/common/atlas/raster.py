"""A renderer base for per-texel methods: draws the atlas mesh with an early depth pre-pass and
samples the method's textures per fragment (shared by the AO / bent-normal textures and the
lightmaps; the transfer textures keep their own, :mod:`methods.texture.renderer`).

A subclass names its fragment stage and shader folders, uploads its texture arrays with
:meth:`AtlasRenderer.texture_array` (which counts them, by name, as ``gpu: <name>`` in
:meth:`~AtlasRenderer.memory_breakdown`, beside the mesh buffers and render target the walk of
:mod:`methods.common.residency` finds) and binds its per-light state in ``_bind``. The vertex
stage ``atlas_mesh.vert`` passes the world position, the interpolated normal and tangent frame,
both UVs, the texture set and the object's constant material; ``texture_normal.glsl`` applies
the scene's normal map per fragment.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from methods.common.atlas import SHADER_DIR
from methods.common.atlas.atlas import AtlasMesh
from methods.common.atlas.shading import ShadingInputs, normal_map_texture
from methods.common.residency import named_breakdown
from prtbench.api.errors import InvalidInputError
from prtbench.api.method import Renderer
from prtbench.render import gl
from prtbench.render.raster import TargetFrames, clip_planes, draw_after_depth_prepass

#: moderngl texture dtype of each stored numpy dtype: float32, float16 and 8-bit unorm.
GL_DTYPES = {np.dtype(np.float32): "f4", np.dtype(np.float16): "f2", np.dtype(np.uint8): "f1"}

#: Texture unit of the scene's normal map; a subclass's own textures take units 0 and up.
NORMAL_MAP_UNIT = 7


def upload_atlas_mesh(ctx, scene, atlas: AtlasMesh, shading: ShadingInputs,
                      programs: Sequence[Any]) -> tuple[list, list]:
    """The atlas mesh's vertex attributes (position, normal, atlas and mesh UVs, tangent,
    texture set, normal-mapped flag, each object's kd / ks / shininess) and its indices as GL
    buffers, and one vertex array per program binding the attributes it reads.

    Returns
    -------
    (list of Buffer, list of VertexArray)
        Every buffer made (the index buffer last), and the vertex arrays in ``programs`` order.
    """
    positions, normals, _, _ = scene.merged()
    src = atlas.vertex_source
    object_of_vertex = np.repeat(np.arange(len(scene.objects)),
                                 [o.mesh.n_vertices for o in scene.objects])[src]
    per_object = {
        "in_kd": [o.material.kd for o in scene.objects],
        "in_ks": [o.material.ks for o in scene.objects],
        "in_shininess": [[o.material.shininess] for o in scene.objects],
    }
    attributes = {
        "in_position": positions[src], "in_normal": normals[src], "in_atlas_uv": atlas.uvs,
        "in_mesh_uv": shading.mesh_uvs[src], "in_tangent": shading.tangents[src],
        "in_texture_set": atlas.texture_set.astype(np.float32)[:, None],
        "in_normal_mapped": shading.normal_mapped[src][:, None],
        **{name: np.asarray(v, np.float32)[object_of_vertex] for name, v in per_object.items()},
    }
    attributes = {name: np.asarray(v, np.float32).reshape(len(src), -1)
                  for name, v in attributes.items()}
    buffers = {name: ctx.buffer(np.ascontiguousarray(v).tobytes())
               for name, v in attributes.items()}
    index_buffer = ctx.buffer(np.ascontiguousarray(atlas.faces, np.uint32).tobytes())

    def vao(program):
        bindings = [(buf, f"{attributes[name].shape[1]}f", name)
                    for name, buf in buffers.items() if name in program]
        return ctx.vertex_array(program, bindings, index_buffer=index_buffer,
                                index_element_size=4)

    return [*buffers.values(), index_buffer], [vao(program) for program in programs]


class AtlasRenderer(TargetFrames, Renderer):
    """Draws the atlas mesh: depth-only pre-pass, then shading with depth test LEQUAL.

    Parameters
    ----------
    scene : Scene
    arrays : dict of str to ndarray
        The artifact's arrays with the atlas mesh (:meth:`AtlasMesh.arrays`).
    meta : dict
        The artifact's ``texture_resolution`` and ``texture_sets``.
    fragment_shader : str
    defines : dict
    width, height : int
    """

    #: Folders searched for the fragment stage and its includes (before the atlas folder's).
    shader_dirs: ClassVar[Sequence[Path]] = ()

    def __init__(self, scene, arrays, meta, *, fragment_shader: str, defines: dict[str, Any],
                 width: int, height: int):
        self.scene, self.width, self.height = scene, int(width), int(height)
        self.ctx = ctx = gl.create_context()
        self.renderer_string = gl.renderer_string(ctx)
        search = [*self.shader_dirs, SHADER_DIR]
        self.program = gl.load_program(ctx, "atlas_mesh.vert", fragment_shader, defines=defines,
                                       search_path=search)
        self.depth_program = gl.load_program(ctx, "atlas_depth.vert", "atlas_depth.frag",
                                             search_path=[SHADER_DIR])
        self._parts: dict[str, int] = {}
        self._resident: list = []
        shading = ShadingInputs.from_scene(scene)
        self.normal_map = normal_map_texture(ctx, shading.normal_map)
        atlas = AtlasMesh.from_arrays(arrays, resolution=int(meta["texture_resolution"]),
                                      sets=int(meta["texture_sets"]))
        self._upload_mesh(atlas, shading)
        self.timer = gl.GpuTimer(ctx)
        self.target = gl.RenderTarget(ctx, self.width, self.height)

    # -- setup ------------------------------------------------------------------------------
    def texture_array(self, name: str, layers: np.ndarray, *, filtering: str = "bilinear"):
        """Upload (L, R, R, 4) RGBA ``layers`` (float32, float16 or uint8 read as unorm) as one
        ``sampler2DArray``, clamped to the edge, no mip-maps; counted as ``gpu: <name>``."""
        layers = np.ascontiguousarray(layers)
        if layers.dtype not in GL_DTYPES or layers.ndim != 4 or layers.shape[-1] != 4:
            raise InvalidInputError(f"texture '{name}' of {layers.dtype} {layers.shape}; "
                                    "accepted: (L, R, R, 4) float32, float16 or uint8")
        max_layers = int(self.ctx.info["GL_MAX_ARRAY_TEXTURE_LAYERS"])
        if layers.shape[0] > max_layers:
            raise InvalidInputError(f"texture '{name}' needs {layers.shape[0]} array layers; "
                                    f"accepted: <= {max_layers} (GL_MAX_ARRAY_TEXTURE_LAYERS)")
        n, r = layers.shape[0], layers.shape[1]
        tex = self.ctx.texture_array((r, r, n), 4, layers.tobytes(), dtype=GL_DTYPES[layers.dtype])
        filter_ = self.ctx.LINEAR if filtering == "bilinear" else self.ctx.NEAREST
        tex.filter = (filter_, filter_)
        tex.repeat_x = tex.repeat_y = False  # CLAMP_TO_EDGE: charts never wrap around
        self.count_resident(name, tex, int(layers.nbytes))
        return tex

    def count_resident(self, name: str, obj, nbytes: int) -> None:
        """Count ``obj`` (a GL object a subclass created, ``nbytes`` of it) as ``gpu: <name>``:
        the method's own data (:meth:`memory_bytes`), released with the renderer."""
        self._resident.append(obj)
        key = f"gpu: {name}"
        self._parts[key] = self._parts.get(key, 0) + int(nbytes)

    def _upload_mesh(self, atlas: AtlasMesh, shading: ShadingInputs) -> None:
        self._mesh_buffers, (self.vao, self.depth_vao) = upload_atlas_mesh(
            self.ctx, self.scene, atlas, shading, (self.program, self.depth_program))

    # -- per frame --------------------------------------------------------------------------
    def _bind(self, view, light) -> None:  # pragma: no cover - overridden
        raise NotImplementedError

    def _draw(self, view, light) -> None:
        near, far = clip_planes(self.scene, view)
        clip_from_world = (view.clip_from_camera(self.width / self.height, near, far)
                           @ view.camera_from_world()).T.astype(np.float32).tobytes()
        self.program["clip_from_world"].write(clip_from_world)
        self.depth_program["clip_from_world"].write(clip_from_world)
        if "eye" in self.program:
            self.program["eye"].value = tuple(float(c) for c in view.eye)
        if "normal_map" in self.program:
            self.normal_map.use(location=NORMAL_MAP_UNIT)
            self.program["normal_map"].value = NORMAL_MAP_UNIT
        self._bind(view, light)
        draw_after_depth_prepass(self.ctx, self.target, self.depth_vao, self.vao)

    def memory_breakdown(self) -> dict[str, int]:
        """The textures (and buffers) a subclass uploaded, by the name it gave them, then the
        mesh buffers, normal map, render target and CPU arrays the renderer holds."""
        return named_breakdown(self, self._parts, self._resident)

    def memory_bytes(self) -> int:
        """The method's own data: the textures (and buffers) a subclass uploaded."""
        return int(sum(self._parts.values()))

    def release(self) -> None:
        for obj in [self.vao, self.depth_vao, *self._mesh_buffers, self.program,
                    self.depth_program, self.normal_map, *self._resident]:
            obj.release()
        self.target.release()
        self._resident = []
