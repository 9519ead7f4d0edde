"""Transfer textures (Sirikonda, KT and Narayanan 2022, PRTT): ``texture-tp``, ``texture-tpfl``.

:mod:`.method` (the plug-in), :mod:`.renderer`, :mod:`.bounces` (baked interreflection),
:mod:`.compressed` (CPCA textures); the atlas machinery is shared
(:mod:`methods.common.atlas`); GLSL in ``shaders/``.
"""

from pathlib import Path

SHADER_DIR = Path(__file__).resolve().parent / "shaders"
