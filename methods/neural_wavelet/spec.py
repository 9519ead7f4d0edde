"""Neural wavelet PRT: the methods this folder registers (read by prtbench.api.plugins)."""

from prtbench.api.plugins import MethodSpec

METHODS = (
    MethodSpec("neural-wavelet", ".method:NeuralWavelet",
               "neural wavelet PRT: hash grid x wavelet grid (CP) + MLP -> Haar transport of glossy indirect light, k lighting terms per frame (direct: importance-sampled shadow rays + denoiser)"),
)
