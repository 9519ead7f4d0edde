"""The operation-count model of one frame (the ``ops`` cost), and the counts of the GLSL the
methods share, which each method's :meth:`~prtbench.api.method.Method.op_counts` composes.

The ``ops`` scalar combines three counts with stated weights (:data:`OPS_WEIGHTS`)::

    ops = madds + 4 · fetches + 0.5 · bytes

* ``madds``: multiply-adds (one vec3 madd counts 3); a transcendental (sin, cos, exp2, tanh,
  pow, sqrt, inversesqrt, a division) counts :data:`TRANSCENDENTAL_MADDS` = 4.
* ``fetches``: texture lookups and per-thread buffer loads (SSBO reads, ``texelFetch``).
  One fetch = 4 multiply-adds: a bilinear lookup is four taps and three lerps, and GPUs issue
  about one texture instruction per four ALU instructions at full rate. Uniform-block reads
  (the light's SH, the TPFL matrix, hard-coded weights) are the same address for every thread
  (a broadcast from the constant cache) and count as nothing beyond their multiply-adds.
* ``bytes``: bytes read per frame from resident data (vertex attributes, transfer buffers,
  texels, shadow maps and G-buffers, written render targets). One byte = 0.5 multiply-add:
  most reads of a frame hit the caches; a DRAM-bound byte costs several times more, so this
  weight is a compromise, checked against measured times by the rank correlation.

Fixed-function work every raster method pays is counted by :func:`raster_counts`
(vertex transform, triangle setup, varyings interpolated per covered pixel, the colour write).
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import lru_cache

from prtbench.transport.sh import triple_product_sparse

#: One transcendental (sin, cos, exp2, tanh, pow, sqrt, division) in multiply-adds.
TRANSCENDENTAL_MADDS = 4
#: mat4 × vec4: the clip-space transform of one vertex.
VERTEX_TRANSFORM_MADDS = 16
#: Edge and plane equations of one triangle (set-up before rasterisation).
TRIANGLE_SETUP_MADDS = 24
#: Barycentric interpolation of one float varying at one pixel.
VARYING_MADDS = 2
#: RGBA float32 colour target written per covered pixel.
COLOR_BYTES = 16
#: Weights of the ``ops`` scalar: multiply-adds per fetch and per byte (see the module docstring).
OPS_WEIGHTS = {"madds": 1.0, "fetches": 4.0, "bytes": 0.5}



def raster_counts(*, vertices: int, triangles: int, pixels: int, varyings: int,
                  vertex_bytes: int, depth_prepass: bool = False) -> dict[str, float]:
    """Fixed-function work of one indexed draw (and its optional depth pre-pass).

    Parameters
    ----------
    vertices, triangles : int
        Vertex shader invocations and triangles set up.
    pixels : int
        Covered pixels shaded (an early depth pre-pass shades each about once).
    varyings : int
        Float varyings interpolated per shaded pixel.
    vertex_bytes : int
        Attribute bytes read per vertex.
    depth_prepass : bool
        A depth-only pass first: a second transform and set-up, one depth test per pixel.
    """
    passes = 2 if depth_prepass else 1
    madds = (passes * (vertices * VERTEX_TRANSFORM_MADDS + triangles * TRIANGLE_SETUP_MADDS)
             + pixels * (varyings * VARYING_MADDS + (1 if depth_prepass else 0)))
    data = passes * vertices * vertex_bytes + pixels * COLOR_BYTES + (4 * pixels if depth_prepass else 0)
    return {"madds": float(madds), "fetches": 0.0, "bytes": float(data)}


def sh_eval_madds(bands: int) -> float:
    """``sh_eval`` (sh.glsl): the Legendre and (x + iy)^m recurrences, ~4 madds per coefficient."""
    return 4.0 * bands * bands + TRANSCENDENTAL_MADDS  # + the normalize


def shade_transferred_madds(bands: int) -> float:
    """``shade_transferred`` (prt_shading.glsl) for one point of a glossy material.

    Phong zonal coefficients (a ratio per band), the mirror direction, ``sh_eval`` at it and the
    RGB dot product with H (3 madds per coefficient), plus the diffuse term.
    """
    zonal = bands * (2 + TRANSCENDENTAL_MADDS)
    mirror = 6 + 2 * TRANSCENDENTAL_MADDS  # reflect and two normalizes
    return zonal + mirror + sh_eval_madds(bands) + 3.0 * bands * bands + 3 * bands + 9


@lru_cache(maxsize=16)
def triple_product_entries(bands: int) -> int:
    """Non-zeros of Γ for ``bands`` (the length of the list ``triple_product`` loops over)."""

    return int(len(triple_product_sparse(bands)[1]))


def triple_product_counts(bands: int) -> dict[str, float]:
    """``triple_product`` (prt_shading.glsl) at one point: per Γ entry one buffer load, the
    index unpacking (3 integer operations) and ``(Γ·T_i)·L_j`` (1 + 3 madds). Γ itself is read from memory once per
    frame (its 8 bytes per entry are the same for every thread), see :func:`gamma_bytes`."""
    entries = triple_product_entries(bands)
    return {"madds": 4.0 * entries + 3.0 * entries, "fetches": float(entries), "bytes": 0.0}


def gamma_bytes(bands: int) -> float:
    """Bytes of the Γ list, read once per frame by the TP methods."""
    return 8.0 * triple_product_entries(bands)


def tpfl_product_madds(bands: int) -> float:
    """``tpfl_product`` (prt_shading.glsl): H_k += T_i · M_ik, an RGB madd per (i, k)."""
    return 3.0 * bands**4


def add_counts(*parts: Mapping[str, float]) -> dict[str, float]:
    """Sum of count dicts (``madds``, ``fetches``, ``bytes``)."""
    return {key: float(sum(p.get(key, 0.0) for p in parts)) for key in OPS_WEIGHTS}


def scaled(counts: Mapping[str, float], factor: float) -> dict[str, float]:
    """``counts`` times ``factor`` (per-pixel counts × covered pixels, ...)."""
    return {key: float(counts.get(key, 0.0)) * factor for key in OPS_WEIGHTS}
