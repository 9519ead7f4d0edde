"""Baking per-texel values into the atlas: the texel points a per-texel method precomputes at,
and the dilated textures it stores (shared by the AO / bent-normal textures and lightmaps).

The steps are those of the transfer textures (PRTT Algorithms 1 and 2, :mod:`methods.texture`):
the scene's UV atlas, its conservative texel-space G-buffer, the world points and shading
normals of the covered texels, and after the method's bake, dilation by whole rings that never
mixes charts (:func:`methods.common.atlas.texels.dilate`).
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field

import numpy as np

from methods.common.atlas.atlas import AtlasMesh, GBuffer, render_gbuffer
from methods.common.atlas.shading import ShadingInputs, distinct_normal_maps
from methods.common.atlas.texels import dilate
from methods.common.materials import check_diffuse_constant_kd
from prtbench.api import config as config_mod
from prtbench.api.config import check_memory
from prtbench.api.errors import InvalidInputError

#: Bytes per texel of every bake: the G-buffer (29 B) and the float64 points and normals (48 B).
GBUFFER_TEXEL_BYTES = 80


def validate_diffuse_atlas(method: str, scene, *, texture_resolution: int, padding: int,
                           texture_sets: bool, bytes_per_texel: float) -> None:
    """Refuse what a diffuse per-texel bake cannot take, before any work.

    Constant diffuse materials (normal maps allowed, on meshes with uvs, at most one map per
    scene: one sampler in the shaders), a padding the atlas can pack, and a texture set whose
    bake fits this machine's memory at ``bytes_per_texel`` (besides the G-buffer's).

    Raises
    ------
    InvalidInputError
        One line naming the value and what is accepted.
    """
    check_diffuse_constant_kd(method, scene)
    for obj in scene.objects:
        if obj.material.normal_map is not None and obj.mesh.uvs is None:
            raise InvalidInputError(f"object '{obj.name}' has a normal map but no mesh uvs; "
                                    "accepted: normal maps on meshes with uvs")
    maps = distinct_normal_maps(scene)
    if len(maps) > 1:
        raise InvalidInputError(f"scene '{scene.name}' has {len(maps)} different normal maps; "
                                f"accepted: at most one normal-map texture per scene for method "
                                f"'{method}'")
    if padding * 8 > texture_resolution:
        raise InvalidInputError(f"padding={padding} with texture_resolution={texture_resolution}; "
                                "accepted: padding <= texture_resolution / 8")
    sets = len(scene.objects) if texture_sets else 1
    per_texel = GBUFFER_TEXEL_BYTES + bytes_per_texel
    fits = int(math.sqrt(config_mod.memory_budget() / (sets * per_texel)))
    check_memory(f"method '{method}' texture_resolution={texture_resolution} ({sets} "
                 "texture(s))", sets * texture_resolution**2 * per_texel,
                 accepted=f"texture_resolution <= {fits}")


@dataclass(frozen=True, eq=False)
class AtlasTexels:
    """The covered texels of a scene's atlas, as points to bake at.

    Attributes
    ----------
    atlas : AtlasMesh
    gbuffer : GBuffer
    shading : ShadingInputs
    covered_index : ndarray, shape (N,), int64
        Flat index ``(s·R + j)·R + i`` of each covered texel.
    points, normals : ndarray, shape (N, 3), float64
        World position and unit shading normal (normal maps applied) of each covered texel.
    times : dict of str to float
        Seconds of the atlas (``atlas_s``) and G-buffer (``gbuffer_s``) steps.
    """

    atlas: AtlasMesh
    gbuffer: GBuffer
    shading: ShadingInputs
    covered_index: np.ndarray
    points: np.ndarray
    normals: np.ndarray
    times: dict[str, float] = field(default_factory=dict)

    @classmethod
    def from_scene(cls, scene, *, resolution: int, padding: int, texture_sets: bool,
                   normal_maps: bool = True) -> "AtlasTexels":
        """Pack (or load the cached) atlas, render its G-buffer, list the covered texels.

        ``normal_maps=False`` gives the interpolated vertex normals instead of the shading
        normals: a bake whose renderer applies the normal map per pixel (directional
        lightmaps) works in the frame of the unmapped surface.
        """
        clock = time.perf_counter()
        atlas = AtlasMesh.from_scene(scene, resolution=resolution, padding=padding,
                                     texture_sets=texture_sets)
        times = {"atlas_s": time.perf_counter() - clock}
        clock = time.perf_counter()
        shading = ShadingInputs.from_scene(scene)
        if not normal_maps:
            shading = dataclasses.replace(shading, normal_map=None,
                                          normal_mapped=np.zeros_like(shading.normal_mapped))
        gbuffer = render_gbuffer(scene, atlas, shading)
        times["gbuffer_s"] = time.perf_counter() - clock
        covered_index = np.flatnonzero(gbuffer.covered.reshape(-1))
        points = gbuffer.positions.reshape(-1, 3)[covered_index].astype(np.float64)
        normals = gbuffer.normals.reshape(-1, 3)[covered_index].astype(np.float64)
        return cls(atlas, gbuffer, shading, covered_index, points, normals, times)

    @property
    def shape(self) -> tuple[int, int, int]:
        """(S, R, R): textures and their side."""
        return self.gbuffer.covered.shape

    def texture(self, values: np.ndarray, *, rings: int, dtype=np.float64) -> np.ndarray:
        """Per-texel ``values`` (N, C) as dilated textures (S, R, R, C) of ``dtype``.

        Texels neither covered nor reached by the ``rings`` of dilation hold 0. float32 halves
        the footprint of wide textures (dilation sums each texel's neighbours in float64).
        """
        values = np.asarray(values, dtype=dtype).reshape(len(self.covered_index), -1)
        s, r, _ = self.shape
        flat = np.zeros((s * r * r, values.shape[1]), dtype)
        flat[self.covered_index] = values
        return dilate(flat.reshape(s, r, r, -1), self.gbuffer.covered, self.gbuffer.chart,
                      rings=rings)[0]

    def filled(self, *, rings: int) -> tuple[np.ndarray, np.ndarray]:
        """(filled (S, R, R) bool, chart (S, R, R) int32) after ``rings`` of dilation."""
        s, r, _ = self.shape
        _, filled, chart = dilate(np.zeros((s, r, r, 1), np.float32), self.gbuffer.covered,
                                  self.gbuffer.chart, rings=rings)
        return filled, chart

    def arrays(self, *, rings: int) -> dict[str, np.ndarray]:
        """What an artifact stores besides its textures: the atlas mesh (to draw it) and the
        coverage diagnostics (``covered``, ``filled``, ``texel_chart``; never uploaded)."""
        filled, chart = self.filled(rings=rings)
        return {"covered": self.gbuffer.covered.astype(np.uint8),
                "filled": filled.astype(np.uint8), "texel_chart": chart, **self.atlas.arrays()}

    def meta(self) -> dict[str, int]:
        """Counts an artifact records: resolution, sets, covered texels, atlas vertices."""
        s, r, _ = self.shape
        return {"texture_resolution": int(r), "texture_sets": int(s),
                "covered_texels": int(len(self.covered_index)),
                "atlas_vertices": int(len(self.atlas.uvs))}
