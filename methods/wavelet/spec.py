"""All-frequency Haar-wavelet PRT: the methods this folder registers (read by prtbench.api.plugins)."""

from prtbench.api.plugins import MethodSpec

METHODS = (
    MethodSpec("wavelet-vertex", ".vertex:WaveletVertex",
               "Ng 2003 all-frequency Haar-wavelet transport at vertices, k lighting terms per frame"),
    MethodSpec("wavelet-texture", ".texture:WaveletTexture",
               "all-frequency Haar-wavelet transport per atlas texel (PRTT atlas × Ng 2003), k lighting terms per frame"),
    MethodSpec("wavelet-tp", ".tp:WaveletTP",
               ("Ng 2004 wavelet triple products per vertex: Haar visibility × per-frame Phong "
                "BRDF × k lighting terms, changing view")),
    MethodSpec("wavelet-image", ".image:WaveletImage",
               "Ng 2003 fixed-view image relighting: per-pixel glossy Haar-wavelet transport, k lighting terms per frame"),
)
