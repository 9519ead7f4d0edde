"""Directional lightmaps: the methods this folder registers (read by prtbench.api.plugins)."""

from prtbench.api.plugins import MethodSpec

METHODS = (
    MethodSpec("lightmap", ".method:Lightmap",
               "baked directional lightmap per atlas texel: L0, SH L1/L2 or H-basis, one light"),
)
