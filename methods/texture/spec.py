"""Transfer textures (PRTT): the methods this folder registers (read by prtbench.api.plugins)."""

from prtbench.api.plugins import MethodSpec

METHODS = (
    MethodSpec("texture-tp", ".method:TextureTP",
               "PRTT transfer textures, per-fragment triple product with the light (TP)"),
    MethodSpec("texture-tpfl", ".method:TextureTPFL",
               "PRTT transfer textures, per-fragment fixed-light triple product matrix (TPFL)"),
)
