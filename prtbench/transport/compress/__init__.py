"""Compression of stored transfer (DESIGN.md §17): PCA, VQ and CPCA (Sloan et al. 2003).

:mod:`.cpca` fits the clustered-PCA form of a set of signals and renders from it;
:mod:`.knobs` is the ``compress`` / ``clusters`` / ``pca_vectors`` knob set that stored-transfer
methods share. No heavy imports at module level (scikit-learn is imported by the fit).
"""

from prtbench.transport.compress.cpca import Cpca, check_request, stored_bytes
from prtbench.transport.compress.fit import fit_cpca, rmse

__all__ = ["Cpca", "check_request", "fit_cpca", "rmse", "stored_bytes"]
