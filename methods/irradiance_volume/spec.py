"""The irradiance volume: the methods this folder registers (read by prtbench.api.plugins)."""

from prtbench.api.plugins import MethodSpec

METHODS = (
    MethodSpec("irradiance-volume", ".method:IrradianceVolume",
               "Greger 1998 irradiance volume: N³ SH radiance probes, trilinear lookup per fragment"),
)
