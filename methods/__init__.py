"""methods plug-ins for prtbench (registered through entry points in pyproject.toml)."""

from pathlib import Path

#: The methods' own GLSL stages and includes, passed to ``prtbench.gl.load_program`` as
#: ``search_path`` (the core's shared shaders in ``prtbench/shaders`` are always searched too).
SHADER_DIR = Path(__file__).resolve().parent / "shaders"
