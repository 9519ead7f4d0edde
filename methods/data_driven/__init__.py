"""Data-driven PRT (Belcour et al. 2022), the ``data-driven`` method.

Modules: :mod:`.lights` (point/spot/directional lights, median cut), :mod:`.families` (random
lighting configurations),
:mod:`.measurement` (blue-noise measurement points), :mod:`.lightmap` (UV-atlas texels),
:mod:`.bake` (embree path-traced indirect bake), :mod:`.dataset`, :mod:`.basis` (SVD basis and
transfer matrix), :mod:`.shadows` (shadow-map atlas), :mod:`.runtime` (GL passes), :mod:`.method` (the plug-in), :mod:`.reference`
(Mitsuba references under analytic lights), :mod:`.evaluation` (experiments shared by the
reproductions; their figures are drawn in ``reproductions/``).
"""

from pathlib import Path

SHADER_DIR = Path(__file__).resolve().parent / "shaders"
