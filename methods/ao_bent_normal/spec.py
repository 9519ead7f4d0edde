"""AO and bent normals: the methods this folder registers (read by prtbench.api.plugins)."""

from prtbench.api.plugins import MethodSpec

METHODS = (
    MethodSpec("ao-bent-normal", ".method:AoBentNormal",
               "AO × SH L2 irradiance at the bent normal, per vertex (engine sky baseline)"),
    MethodSpec("ao-bent-normal-texture", ".method:AoBentNormalTexture",
               "AO × SH L2 irradiance at the bent normal, per texel of the atlas"),
)
