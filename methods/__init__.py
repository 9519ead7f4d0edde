"""Built-in PRT methods of prtbench, one folder per family.

Each family folder holds a light ``spec.py`` (method names -> ``"module:Class"`` and one-line
summaries; discovered by :mod:`prtbench.api.plugins`, no ``pyproject.toml`` entry needed), its
code, and its GLSL in ``shaders/``. Code several families share lives in :mod:`methods.common`;
what the harness needs from a method is declared on :class:`prtbench.api.method.Method`.
See ``docs/ADDING_A_METHOD.md``.
"""
