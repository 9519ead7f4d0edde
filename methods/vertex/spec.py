"""Per-vertex SH PRT: the methods this folder registers (read by prtbench.api.plugins)."""

from prtbench.api.plugins import MethodSpec

METHODS = (
    MethodSpec("vertex", ".diffuse:VertexPRT",
               "Sloan 2002 diffuse transfer vectors at vertices, shaded per vertex"),
    MethodSpec("vertex-tp", ".glossy:VertexTP",
               "Glossy vertex PRT: transfer vectors × light by SH triple product, per vertex"),
    MethodSpec("vertex-tpfl", ".glossy:VertexTPFL",
               "Glossy vertex PRT: transfer vectors × per-light TPFL matrix, per vertex"),
    MethodSpec("sloan-matrix", ".glossy:SloanMatrix",
               "Sloan 2002 glossy transfer matrices at vertices (n⁴ floats each), per vertex"),
)
