"""Factored BRDF: the methods this folder registers (read by prtbench.api.plugins)."""

from prtbench.api.plugins import MethodSpec

METHODS = (
    MethodSpec("factored-brdf", ".method:FactoredBrdf",
               "Factored BRDF for changing view: J SVD terms g_j(ωo)·h_j(ωi), J transfer vectors per vertex"),
)
