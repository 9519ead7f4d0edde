"""The transfer-texture atlas shared by per-texel methods (PRTT §3, Sirikonda 2022).

:mod:`.atlas` (UV atlas and texel-space G-buffer pass), :mod:`.texels` (dilation, lookups,
storage), :mod:`.shading` (tangents and normal maps), :mod:`.bake` (the covered texels as bake
points, dilated textures, the diffuse bakes' checks), :mod:`.raster` (a renderer base drawing
the atlas mesh); GLSL in ``shaders/``.
"""

from pathlib import Path

#: The atlas passes' GLSL (``texture_gbuffer.*``, ``texture_normal.glsl``, ``atlas_mesh.vert``,
#: ``atlas_depth.*``).
SHADER_DIR = Path(__file__).resolve().parent / "shaders"
