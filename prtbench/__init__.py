"""prtbench: a benchmark and reproduction harness for Precomputed Radiance Transfer.

The core package knows nothing about any particular method, scene or paper table: those live
in the ``methods``, ``scenes`` and ``reproductions`` packages and register themselves into the
core's registries (see :mod:`prtbench.registry`).
"""

__version__ = "0.1.0"
