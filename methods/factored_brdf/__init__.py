"""Factored BRDF PRT for changing view (Wang 2004 / Sloan 2004): ``factored-brdf``."""

from pathlib import Path

SHADER_DIR = Path(__file__).resolve().parent / "shaders"
