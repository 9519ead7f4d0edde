"""Ambient occlusion and bent normals (the engines' cheapest relightable sky term):
``ao-bent-normal`` per vertex and ``ao-bent-normal-texture`` per texel of the transfer-texture
atlas. :mod:`.method`; GLSL in ``shaders/``.
"""

from pathlib import Path

SHADER_DIR = Path(__file__).resolve().parent / "shaders"
