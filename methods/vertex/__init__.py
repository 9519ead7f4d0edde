"""Per-vertex SH PRT (Sloan, Kautz and Snyder 2002): ``vertex`` (diffuse transfer vectors),
``vertex-tp`` / ``vertex-tpfl`` (glossy triple products, PRTT §3) and ``sloan-matrix`` (glossy
transfer matrices). :mod:`.diffuse`, :mod:`.glossy`, :mod:`.bounces` (interreflection of glossy
transfer); GLSL in ``shaders/``.
"""

from pathlib import Path

SHADER_DIR = Path(__file__).resolve().parent / "shaders"
