"""prtbench: a benchmark and reproduction harness for Precomputed Radiance Transfer.

The core package knows nothing about any particular method, scene or paper table: those live
in the ``methods``, ``scenes`` and ``reproductions`` packages and register themselves into the
core's registries (see :mod:`prtbench.api.registry`).
"""

import os as _os

__version__ = "0.1.0"

# Trained networks must not depend on the thread count (a sweep's workers train on 1 thread, a
# serial run on every core): MKL, torch's CPU BLAS, splits the batch-long reduction of a
# weight gradient (Xᵀ·dY) over its threads, and the last-bit differences grow over training
# (0.04 dB masked PSNR on neural-wavelet's smoke case). Strict conditional numerical
# reproducibility makes MKL's gemm bitwise independent of the thread count (measured here: as
# fast at 128 neurons, within the noise at 32-64). MKL reads it at its first call, so it is set
# on import; a value the user set is kept.
_os.environ.setdefault("MKL_CBWR", "AUTO,STRICT")
