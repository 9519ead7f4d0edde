"""SH probe volumes as engines ship them (Unity's adaptive probe volumes, DDGI's visibility
test, Half-Life 2's ambient cube): ``probe-volume``. :mod:`.placement` (uniform grid or
bricks), :mod:`.bake` (validity, virtual offset, dilation, depth moments), :mod:`.encoding`
(the pool's texel layouts), :mod:`.method`, :mod:`.renderer`; GLSL in ``shaders/``.
"""

from pathlib import Path

SHADER_DIR = Path(__file__).resolve().parent / "shaders"
