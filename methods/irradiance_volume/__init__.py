"""The irradiance volume (Greger et al. 1998): an SH probe grid, ``irradiance-volume``."""

from pathlib import Path

SHADER_DIR = Path(__file__).resolve().parent / "shaders"
