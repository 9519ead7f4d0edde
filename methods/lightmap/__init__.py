"""Directional lightmaps baked in the transfer-texture atlas: ``lightmap``. :mod:`.method` (the
plug-in and the bake), :mod:`.encoding` (SH and H-basis coefficients, 8-bit and half storage),
:mod:`.renderer`; GLSL in ``shaders/``.
"""

from pathlib import Path

SHADER_DIR = Path(__file__).resolve().parent / "shaders"
