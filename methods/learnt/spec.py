"""Learnt transfer: the methods this folder registers (read by prtbench.api.plugins)."""

from prtbench.api.plugins import MethodSpec

METHODS = (
    MethodSpec("learnt", ".method:LearntTransfer",
               "thesis ch. 4 learnt transfer: MLP (p, n) -> SH transfer, GLSL or torch, TPFL/TP"),
    MethodSpec("learnt-sdf", ".sdf:LearntSdf",
               "thesis §4.2.2 learnt transfer on SDFs: sphere tracing + MLP (p, n) -> SH transfer, GLSL or torch, TPFL/TP"),
)
