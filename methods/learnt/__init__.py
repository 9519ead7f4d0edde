"""Learnt transfer (Sirikonda 2023 thesis, ch. 4): ``learnt`` on meshes and ``learnt-sdf`` on
SDF scenes. :mod:`.method` and :mod:`.sdf` (the plug-ins), :mod:`.config`, :mod:`.data`,
:mod:`.network`, :mod:`.model`, :mod:`.subdivide`, :mod:`.glsl`, :mod:`.renderer`,
:mod:`.torch_renderer`, :mod:`.probe`; GLSL in ``shaders/``.
"""

from pathlib import Path

SHADER_DIR = Path(__file__).resolve().parent / "shaders"
