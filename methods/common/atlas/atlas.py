"""The atlas side of transfer textures: the scene's UV atlas as one mesh, and its G-buffer.

The atlas (xatlas, through :func:`prtbench.scene.geometry.scene_atlas`) splits vertices along chart
seams, so transfer textures are drawn with an *atlas mesh*: the scene's merged mesh re-indexed
onto atlas vertices, face order unchanged (face f of ``Scene.merged()`` is atlas face f, which
is how ray hits find their texels).

The G-buffer (PRTT Algorithm 2) is rendered with the atlas UVs as screen positions. Coverage is
conservative: a texel is covered when any triangle touches its square, and it holds the surface
point nearest to its centre (see ``texture_gbuffer.geom``). The texel containing any point
inside a triangle is therefore covered, and a bilinear lookup there reads only that texel and
its 8 neighbours, which one ring of dilation fills.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from methods.common.atlas import SHADER_DIR
from methods.common.atlas.shading import ShadingInputs, normal_map_texture
from prtbench.api.errors import InvalidInputError
from prtbench.render import gl
from prtbench.scene.geometry import scene_atlas
from prtbench.scene.model import Scene


@dataclass(frozen=True, eq=False)
class AtlasMesh:
    """The scene's merged mesh on atlas vertices.

    Attributes
    ----------
    vertex_source : ndarray, shape (V',), int64
        Vertex of ``scene.merged()`` each atlas vertex copies (positions, normals, mesh UVs).
    uvs : ndarray, shape (V', 2), float32
        Atlas coordinates in [0, 1]² (texel (i, j) covers [i, i+1]/R × [j, j+1]/R).
    faces : ndarray, shape (F, 3), int32
        Atlas-vertex indices; face f is face f of ``scene.merged()`` (same corner order).
    texture_set : ndarray, shape (V',), int32
        Texture of each vertex (its object's index with texture sets, else 0).
    chart : ndarray, shape (V',), int32
        Chart id (connected component of atlas faces), unique across the scene.
    resolution : int
        Texture side in texels.
    sets : int
        Number of textures (1, or the object count with texture sets).
    """

    vertex_source: np.ndarray
    uvs: np.ndarray
    faces: np.ndarray
    texture_set: np.ndarray
    chart: np.ndarray
    resolution: int
    sets: int

    @property
    def face_texture_set(self) -> np.ndarray:
        """(F,) int32 texture of each face."""
        return self.texture_set[self.faces[:, 0]]

    def arrays(self) -> dict[str, np.ndarray]:
        """The arrays an artifact stores to rebuild this mesh."""
        return {"atlas_vertex_source": self.vertex_source, "atlas_uvs": self.uvs,
                "atlas_faces": self.faces, "atlas_texture_set": self.texture_set,
                "atlas_chart": self.chart}

    @classmethod
    def from_arrays(cls, arrays, *, resolution: int, sets: int) -> "AtlasMesh":
        return cls(arrays["atlas_vertex_source"], arrays["atlas_uvs"], arrays["atlas_faces"],
                   arrays["atlas_texture_set"], arrays["atlas_chart"], resolution, sets)

    @classmethod
    def from_scene(cls, scene: Scene, *, resolution: int, padding: int,
                   texture_sets: bool) -> "AtlasMesh":
        """Pack (or load the cached) atlas of every object and merge it in object order."""
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components

        try:
            atlases = scene_atlas(scene, resolution=resolution, padding=padding,
                                  per_object=texture_sets)
        except InvalidInputError as exc:
            raise InvalidInputError(f"{exc} for scene '{scene.name}' "
                                    f"({scene.n_triangles} triangles); accepted: a larger "
                                    "texture_resolution, a smaller padding, or texture_sets=true"
                                    ) from None
        sources, uvs, faces, sets = [], [], [], []
        vertex_offset = atlas_offset = 0
        for obj, atlas in zip(scene.objects, atlases):
            if len(atlas.faces) != obj.mesh.n_triangles or not np.array_equal(
                    atlas.vertex_map[atlas.faces], obj.mesh.faces):
                raise InvalidInputError(  # pragma: no cover - xatlas keeps faces and corners
                    f"atlas of object '{obj.name}' does not keep the mesh's faces")
            sources.append(atlas.vertex_map + vertex_offset)
            uvs.append(atlas.uvs)
            faces.append(atlas.faces.astype(np.int64) + atlas_offset)
            sets.append(np.full(len(atlas.uvs), atlas.texture, np.int32))
            vertex_offset += obj.mesh.n_vertices
            atlas_offset += len(atlas.uvs)
        faces_all = np.concatenate(faces).astype(np.int32)
        n = atlas_offset
        edges = np.concatenate([faces_all[:, [0, 1]], faces_all[:, [1, 2]]])
        graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
        _, chart = connected_components(graph, directed=False)
        return cls(np.concatenate(sources).astype(np.int64), np.concatenate(uvs).astype(np.float32),
                   faces_all, np.concatenate(sets), chart.astype(np.int32), int(resolution),
                   len(scene.objects) if texture_sets else 1)


# --- G-buffer -------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class GBuffer:
    """Texel-space surface samples of every texture of a set (row j is v-texel j).

    Attributes
    ----------
    positions, normals : ndarray, shape (S, R, R, 3), float32
        World position and unit shading normal of each covered texel.
    covered : ndarray, shape (S, R, R), bool
    chart : ndarray, shape (S, R, R), int32
        Chart of the triangle that covered the texel, −1 where uncovered.
    """

    positions: np.ndarray
    normals: np.ndarray
    covered: np.ndarray
    chart: np.ndarray


def render_gbuffer(scene: Scene, atlas: AtlasMesh, shading: ShadingInputs) -> GBuffer:
    """Rasterise the atlas mesh in texel space (PRTT Algorithm 2, conservative coverage)."""

    positions, normals, _, _ = scene.merged()
    src = atlas.vertex_source
    attributes = {
        "in_atlas_uv": atlas.uvs, "in_position": positions[src], "in_normal": normals[src],
        "in_mesh_uv": shading.mesh_uvs[src], "in_tangent": shading.tangents[src],
        "in_chart": atlas.chart.astype(np.float32), "in_normal_mapped": shading.normal_mapped[src],
    }
    ctx = gl.create_context()
    program = gl.load_program(ctx, "texture_gbuffer.vert", "texture_gbuffer.frag",
                              geometry="texture_gbuffer.geom", search_path=[SHADER_DIR])
    r, sets = atlas.resolution, atlas.sets
    out_pos = np.zeros((sets, r, r, 3), np.float32)
    out_nrm = np.zeros((sets, r, r, 3), np.float32)
    covered = np.zeros((sets, r, r), bool)
    chart = np.full((sets, r, r), -1, np.int32)
    normal_map = normal_map_texture(ctx, shading.normal_map)
    target = gl.RenderTarget(ctx, r, r, attachments=2)
    buffers = [ctx.buffer(np.ascontiguousarray(v, np.float32).tobytes()) for v in attributes.values()]
    formats = {"in_atlas_uv": "2f", "in_position": "3f", "in_normal": "3f", "in_mesh_uv": "2f",
               "in_tangent": "4f", "in_chart": "1f", "in_normal_mapped": "1f"}
    bindings = [(buf, formats[name], name) for buf, name in zip(buffers, attributes)
                if name in program]
    face_set = atlas.face_texture_set
    try:
        program["resolution"].value = float(r)
        if "normal_map" in program:
            program["normal_map"].value = 0
        normal_map.use(location=0)
        for s in range(sets):
            faces = atlas.faces[face_set == s]
            if len(faces) == 0:
                continue
            index = ctx.buffer(np.ascontiguousarray(faces, np.uint32).tobytes())
            vao = ctx.vertex_array(program, bindings, index_buffer=index, index_element_size=4)
            target.use()
            target.clear()
            ctx.enable(gl.moderngl.DEPTH_TEST)
            ctx.disable(gl.moderngl.CULL_FACE)
            ctx.depth_func = "<"
            vao.render(gl.moderngl.TRIANGLES)
            # RenderTarget.read puts GL's row 0 (v = 0) last; texture rows start at v = 0.
            g_pos = target.read(0)[::-1]
            g_nrm = target.read(1)[::-1]
            vao.release()
            index.release()
            hit = g_pos[..., 3] > 0.5
            covered[s] = hit
            out_pos[s][hit] = g_pos[..., :3][hit]
            out_nrm[s][hit] = g_nrm[..., :3][hit]
            chart[s][hit] = np.rint(g_nrm[..., 3][hit]).astype(np.int32)
    finally:
        for buf in buffers:
            buf.release()
        target.release()
        normal_map.release()
        program.release()
    length = np.linalg.norm(out_nrm, axis=-1, keepdims=True)
    out_nrm = np.where(length > 1e-12, out_nrm / np.maximum(length, 1e-30), [0.0, 1.0, 0.0])
    return GBuffer(out_pos, out_nrm.astype(np.float32), covered, chart)
