"""Data-driven PRT: the methods this folder registers (read by prtbench.api.plugins)."""

from prtbench.api.plugins import MethodSpec

METHODS = (
    MethodSpec("data-driven", ".method:DataDrivenPRT",
               "Belcour 2022 data-driven PRT: shadow-mapped direct + indirect from an SVD lightmap basis driven by a fake G-buffer"),
)
