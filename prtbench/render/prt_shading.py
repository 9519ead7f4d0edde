"""GPU-side data for SH triple products, shared by every method including ``prt_shading.glsl``.

``prt_shading.glsl`` reads two std430 storage buffers (bindings in :data:`GAMMA_BINDING`,
:data:`TPFL_BINDING`): the sparse Γ list for the triple product (TP) and the fixed-light matrix
M = ``prtbench.transport.sh.tpfl_matrix(L, n)`` for TPFL. This module builds their bytes and owns the GL
buffers so vertex and texture methods upload them identically.

API (stable)
------------
- ``gamma_entries(bands) -> ndarray`` structured (K,) [("ijk", uint32), ("value", float32)]
- ``gamma_buffer_data(bands) -> bytes``; ``tpfl_buffer_data(light, bands) -> bytes``
- ``TripleProductBuffers(ctx, bands)``: ``.bind_gamma()``, ``.bind_tpfl(light)`` (M cached per
  light content hash), ``.memory_bytes()``, ``.release()``.
"""

from __future__ import annotations

import numpy as np

from prtbench.api.errors import InvalidInputError
from prtbench.transport import sh

#: Storage-buffer binding of the Γ list (``PRT_GAMMA_BINDING`` in prt_shading.glsl).
GAMMA_BINDING = 1
#: Storage-buffer binding of the TPFL matrix (``PRT_TPFL_BINDING`` in prt_shading.glsl).
TPFL_BINDING = 2

GAMMA_DTYPE = np.dtype([("ijk", "<u4"), ("value", "<f4")])


def gamma_entries(bands: int) -> np.ndarray:
    """Non-zeros of Γ_ijk = ∫ Y_i Y_j Y_k dω packed for the shader.

    Parameters
    ----------
    bands : int
        SH bands n (1..8).

    Returns
    -------
    ndarray, shape (K,), dtype :data:`GAMMA_DTYPE`
        ``ijk = i | j << 8 | k << 16`` (each index < n² ≤ 64) and the float32 value.
    """
    ijk, values = sh.triple_product_sparse(bands)
    ijk = np.asarray(ijk, dtype=np.uint32)
    out = np.empty(len(values), dtype=GAMMA_DTYPE)
    out["ijk"] = ijk[:, 0] | (ijk[:, 1] << 8) | (ijk[:, 2] << 16)
    out["value"] = np.asarray(values, dtype=np.float32)
    return out


def gamma_buffer_data(bands: int) -> bytes:
    """Bytes of the Γ storage buffer (8 bytes per non-zero)."""
    return gamma_entries(bands).tobytes()


def tpfl_matrix_rgb(light: np.ndarray, bands: int) -> np.ndarray:
    """M_ik,c = Σ_j Γ_ijk L_j,c as float32 (n², n², 3), the layout the shader reads.

    Parameters
    ----------
    light : ndarray, shape (n², 3)
        RGB light SH coefficients (``EnvironmentLight.sh(n)``).
    """
    light = np.asarray(light, dtype=np.float64)
    if light.shape != (bands * bands, 3):
        raise InvalidInputError(
            f"TPFL light has shape {light.shape}; expected ({bands * bands}, 3) for {bands} bands")
    return np.ascontiguousarray(sh.tpfl_matrix(light, bands), dtype=np.float32)


def tpfl_buffer_data(light: np.ndarray, bands: int, *, ssbo: bool = False) -> bytes:
    """Bytes of the TPFL buffer.

    The default is the std140 uniform-block layout prt_shading.glsl reads (one vec4 per (i, k):
    float32 (n², n², 4), alpha 0); ``ssbo=True`` gives the packed (n², n², 3) layout of its
    ``PRT_TPFL_SSBO`` variant.
    """
    m = tpfl_matrix_rgb(light, bands)
    if ssbo:
        return m.tobytes()
    padded = np.zeros(m.shape[:2] + (4,), dtype=np.float32)
    padded[..., :3] = m
    return padded.tobytes()


class TripleProductBuffers:
    """The Γ buffer and per-light TPFL buffers of one GL context.

    Parameters
    ----------
    ctx : moderngl.Context
    bands : int
    gamma : bool
        Whether to upload the Γ list (needed by ``triple_product``).
    """

    def __init__(self, ctx, bands: int, *, gamma: bool = True):
        self.ctx, self.bands = ctx, int(bands)
        self.gamma_buffer = ctx.buffer(gamma_buffer_data(self.bands)) if gamma else None
        # One matrix per light: recomputed only when the light changes (M is light-dependent,
        # geometry-independent, so the renderer computes it once per light on the CPU).
        self._tpfl_key: str | None = None
        self.tpfl_buffer = None

    def bind_gamma(self) -> None:
        """Bind the Γ list to :data:`GAMMA_BINDING`."""
        if self.gamma_buffer is None:
            raise InvalidInputError("TripleProductBuffers was created with gamma=False")
        self.gamma_buffer.bind_to_storage_buffer(GAMMA_BINDING)

    def bind_tpfl(self, light) -> None:
        """Bind M(light) to :data:`TPFL_BINDING`, computing it on the CPU on a light change.

        Parameters
        ----------
        light : prtbench.transport.lights.EnvironmentLight
        """
        key = light.content_hash()
        if key != self._tpfl_key:
            data = tpfl_buffer_data(light.sh(self.bands), self.bands)
            if self.tpfl_buffer is None:
                self.tpfl_buffer = self.ctx.buffer(data)
            else:
                self.tpfl_buffer.write(data)
            self._tpfl_key = key
        self.tpfl_buffer.bind_to_uniform_block(TPFL_BINDING)

    def memory_bytes(self) -> int:
        """Bytes of the resident Γ and TPFL buffers."""
        return sum(int(b.size) for b in (self.gamma_buffer, self.tpfl_buffer) if b is not None)

    def release(self) -> None:
        for buffer in (self.gamma_buffer, self.tpfl_buffer):
            if buffer is not None:
                buffer.release()
        self.gamma_buffer = self.tpfl_buffer = None
