"""All-frequency Haar-wavelet PRT (Ng, Ramamoorthi and Hanrahan 2003, 2004).

``wavelet-vertex`` (:mod:`.vertex`), ``wavelet-texture`` (:mod:`.texture`), ``wavelet-tp``
(:mod:`.tp`, triple products) and ``wavelet-image`` (:mod:`.image`, fixed view); the per-frame
relighting they share (:mod:`.relight`), compression of the sparse transport
(:mod:`.compressed`) and the per-pixel G-buffer of the fixed-view method (:mod:`.gbuffer`).
The wavelet mathematics (cubemaps, Haar, sparse transport, triple products) is core
(:mod:`prtbench.transport.wavelet`); GLSL in ``shaders/``.
"""

from pathlib import Path

SHADER_DIR = Path(__file__).resolve().parent / "shaders"
