"""Probe volumes: the methods this folder registers (read by prtbench.api.plugins)."""

from prtbench.api.plugins import MethodSpec

METHODS = (
    MethodSpec("probe-volume", ".method:ProbeVolume",
               "engine SH probe volume (Unity APV bricks, DDGI Chebyshev, ambient cube), "
               "relit sky occlusion or baked radiance"),
)
