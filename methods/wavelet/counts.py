"""Operation counts of a wavelet frame: the pieces the four methods' ``op_counts`` compose.

A frame of ``wavelet-vertex``, ``wavelet-texture`` and ``wavelet-tp`` is CPU work (vectorised
numpy), an upload of its result and a raster draw; ``wavelet-image`` is the CPU work alone.
The counts follow the code, in the units of :mod:`prtbench.render.ops`:

* ``madds``: one add, multiply, comparison or integer step of a numpy pass; a division, square
  root or power counts :data:`~prtbench.render.ops.TRANSCENDENTAL_MADDS`;
* ``fetches``: indexed loads (gathers): a stored sparse entry, a selected column's start, a
  binary-search probe, a light coefficient gathered per entry;
* ``bytes``: resident data read, and the per-frame arrays a numpy pass streams through (read
  and written: float64 accumulators, the dense texels of a BRDF projection), the copy made for
  an upload and the bytes uploaded.

Per light, not per frame: the lat-long → cubemap resampling (cached by
:meth:`methods.wavelet.relight.Relighter.light_cube`, outside the timed frame, as the SH
methods' light projection is): not counted. Per frame: the light's Haar transform
(:func:`haar_counts`) and the selection of its k terms (:func:`selection_counts`).

A row's stored facts (config, vertex and triangle counts, covered pixels, resolution, resident
bytes) do not tell how many stored entries the k selected columns hold, so the bound the code
allows is counted: a point stores at most ``kept`` coefficients and each selected column at
most one of them, so at most min(k, kept) per point (:func:`entries_per_point`). Exact zeros
(the transport below a point's horizon) are not stored, so the true count is lower: on
sphere-over-plane (3075 vertices, cubemap 32, keep 0.25) ``wavelet-vertex`` touched 0.4 to 0.65
of the bound for k = 10 … 1000 under ``sky`` and ``sun`` (area and magnitude selection).
"""

from __future__ import annotations

import math

from prtbench.render.ops import TRANSCENDENTAL_MADDS, add_counts, scaled
from prtbench.transport.wavelet.sparse import VALUE_BYTES, row_dtype

#: Bytes per RGB float64 value (light coefficients, accumulators).
RGB64_BYTES = 24
#: Bytes per RGB float32 value (per-point results, uploads).
RGB32_BYTES = 12


def coefficients(cubemap: int) -> int:
    """6·N²: Haar coefficients of one cubemap signal."""
    return 6 * int(cubemap) ** 2


def kept_per_point(keep: float, m: int) -> int:
    """Coefficients kept per point, as :func:`prtbench.transport.wavelet.transport.keep_count`
    computes them for a valid ``keep``, clamped to 1..m (a stored row's knobs never raise here).
    """
    kept = round(keep * m) if keep <= 1.0 else int(keep)
    return int(min(max(kept, 1), m))


def entries_per_point(terms: int, kept: int) -> int:
    """Bound on the stored entries of the k selected columns at one point: min(k, kept)."""
    return int(min(terms, kept))


def search_probes(entries: float) -> float:
    """Probes of one binary search (``np.searchsorted``) among ``entries`` sorted keys."""
    return float(math.ceil(math.log2(max(entries, 1.0) + 1.0)))


def haar_counts(*, signals: int, n: int, value_bytes: int) -> dict[str, float]:
    """:func:`prtbench.transport.wavelet.haar.forward` of ``signals`` N×N faces.

    The copy in (read and write N²), then per level s = N, N/2, …, 2 the pair sums and
    differences along columns then rows (2·s² adds) and the ½ scaling (s²), the three passes
    reading and writing the s×s block (6·s² values moved).

    Parameters
    ----------
    signals : int
        N×N faces transformed (3 channels × 6 faces for an RGB light; 6 per BRDF point).
    n : int
        Face resolution N, a power of two.
    value_bytes : int
        8 (float64, the light) or 4 (float32, the BRDF factor).
    """
    level_values = sum((n >> j) ** 2 for j in range(max(int(n).bit_length() - 1, 0)))
    return {"madds": 3.0 * level_values * signals, "fetches": 0.0,
            "bytes": float(signals * value_bytes * (2 * n * n + 6 * level_values))}


def quickselect_comparisons(m: int, k: int) -> float:
    """Expected comparisons of selecting the k-th of m values by quickselect (Knuth):
    2m + 2k·ln(m/k) + 2(m−k)·ln(m/(m−k)); 0 for k >= m (nothing to partition)."""
    if k >= m:
        return 0.0
    k = max(int(k), 1)
    return 2.0 * m + 2.0 * k * math.log(m / k) + 2.0 * (m - k) * math.log(m / (m - k))


def partial_sort_counts(*, m: int, k: int, value_bytes: int) -> dict[str, float]:
    """``np.sort(np.argpartition(-scores, k − 1)[:k])`` over m scores (k < m; nothing for k = m,
    where :func:`~prtbench.transport.wavelet.selection.select_terms` returns every index).

    The negation (one pass), the quickselect's comparisons (:func:`quickselect_comparisons`,
    each reading one score), the int64 index array it permutes (written and read), and the
    sort of the k picked indices (k·log2 k comparisons).
    """
    if k >= m:
        return {"madds": 0.0, "fetches": 0.0, "bytes": 0.0}
    comparisons = quickselect_comparisons(m, k)
    sort = k * math.log2(max(k, 2))
    return {"madds": float(m + comparisons + sort), "fetches": 0.0,
            "bytes": float(2 * value_bytes * m + value_bytes * comparisons + 16 * m + 16 * k)}


def selection_counts(*, cubemap: int, terms: int, selection: str) -> dict[str, float]:
    """:func:`~prtbench.transport.wavelet.selection.select_terms` of a frame's RGB light.

    Per coefficient the score: the RGB norm (3 madds and a square root), times the resident
    float32 weight for ``area`` and ``transport`` (1 madd, 4 bytes), the float64 score written;
    then the partial sort of the k largest (:func:`partial_sort_counts`).
    """
    m = coefficients(cubemap)
    weighted = selection != "magnitude"
    score = {"madds": float(m * (3 + TRANSCENDENTAL_MADDS + weighted)), "fetches": 0.0,
             "bytes": float(m * (RGB64_BYTES + 8 + 4 * weighted))}
    return add_counts(score, partial_sort_counts(m=m, k=min(terms, m), value_bytes=8))


def light_counts(*, cubemap: int, terms: int, selection: str) -> dict[str, float]:
    """The light's per-frame work before any product: Haar of its 3 × 6 float64 faces
    (:func:`haar_counts`) and the selection of its k terms (:func:`selection_counts`)."""
    return add_counts(haar_counts(signals=18, n=int(cubemap), value_bytes=8),
                      selection_counts(cubemap=cubemap, terms=terms, selection=selection))


def sparse_product_counts(*, points: int, terms: int, entries_per_point: int,
                          storage: str) -> dict[str, float]:
    """:meth:`~prtbench.transport.wavelet.sparse.SparseTransport.relight` of one frame.

    Per selected column: its two ``indptr`` bounds (2 fetches, 16 bytes) and its RGB float64
    light value (1 fetch, 24 bytes). Per stored entry of those columns: its row index and value
    (2 fetches; the int8 scale a third), the entry's index arithmetic and dequantisation (2
    madds, +1 for the int8 scale), the RGB light value repeated beside it (12 bytes written and
    read) and the RGB madd into its point's accumulator (3). Per point: the (P, 3) float64
    accumulator zeroed, each channel's ``bincount`` written and copied in (24 bytes moved per
    channel), and the float32 result cast from it (24 read, 12 written).

    Parameters
    ----------
    points : int
        Rows of the transport (vertices, texels, pixel lobes).
    terms : int
        k selected columns.
    entries_per_point : int
        Stored entries of the k columns per point (:func:`entries_per_point`).
    storage : {"float32", "float16", "int8"}
    """
    int8 = storage == "int8"
    entry = {"madds": 3.0 + 2.0 + int8, "fetches": 2.0 + int8,
             "bytes": float(row_dtype(points).itemsize + VALUE_BYTES[storage] + 4 * int8
                            + 2 * RGB32_BYTES)}
    per_term = {"madds": 2.0, "fetches": 3.0, "bytes": 16.0 + RGB64_BYTES}
    per_point = {"madds": 3.0, "fetches": 0.0,
                 "bytes": float(RGB64_BYTES + 3 * 24 + RGB64_BYTES + RGB32_BYTES)}
    return add_counts(scaled(per_term, terms), scaled(entry, float(points) * entries_per_point),
                      scaled(per_point, points))


def upload_counts(*, values: int) -> dict[str, float]:
    """A float32 array of ``values`` sent to the GPU: ``tobytes`` copies it (read and
    written) and the driver copies the bytes into the buffer or texture."""
    return {"madds": 0.0, "fetches": 0.0, "bytes": 3.0 * 4 * values}


def lookup_counts(*, entries: float, value_bytes: int = 4) -> dict[str, float]:
    """One ``SparseRows.lookup``: the key (1 madd), a binary search among ``entries`` keys
    (one comparison and one 8-byte probe each), the equality test, the value load."""
    probes = search_probes(entries)
    return {"madds": probes + 2.0, "fetches": probes + 1.0,
            "bytes": 8.0 * probes + value_bytes}


def parent_mean_counts(*, levels: int, entries: float) -> dict[str, float]:
    """:func:`~prtbench.transport.wavelet.triple.parent_means` of one wavelet at its deepest
    ``levels`` − 1 (the bound: the k terms may sit at any level): its decode (12 integer
    steps), the face mean (1 lookup and a division), then per ancestor the node and quadrant
    arithmetic (6), its three wavelets' lookups, the signed sum (3) and the division by the
    ancestor's side."""
    ancestors = max(int(levels) - 1, 0)
    lookup = lookup_counts(entries=entries)
    per_ancestor = add_counts(scaled(lookup, 3),
                              {"madds": 6.0 + 3.0 + TRANSCENDENTAL_MADDS + 1.0})
    face = add_counts(lookup, {"madds": 12.0 + TRANSCENDENTAL_MADDS})
    return add_counts(face, scaled(per_ancestor, ancestors))


def mean_pyramid_counts(*, cubemap: int, channels: int = 3) -> dict[str, float]:
    """:func:`~prtbench.transport.wavelet.triple.mean_pyramid` of the frame's truncated light.

    The (C, 6, N, N) float64 copy of the light and the zeroed output; per level h = 1, 2, …,
    N/2 and face and channel the three detail blocks read (3h²) and written as the level's
    means (3h²), and for each of the 4h² children its mean: 3 madds for the signed details,
    a division by the side and the parent's mean added.
    """
    n = int(cubemap)
    nodes = sum((1 << (2 * j)) for j in range(max(n.bit_length() - 1, 0)))  # Σ h²
    signals = 6 * channels
    return {"madds": float(signals * nodes * 4 * (3 + TRANSCENDENTAL_MADDS + 1)),
            "fetches": 0.0,
            "bytes": float(signals * 8 * (3 * n * n + 10 * nodes))}


def triple_product_counts(*, points: int, cubemap: int, terms: int, visibility_entries: int,
                          brdf_entries: int) -> dict[str, float]:
    """One :func:`~prtbench.transport.wavelet.triple.triple_product` call (Ng 2004's tree
    algorithm) over every point, with bounds per point where the facts do not tell.

    Per point, with |V| = ``visibility_entries``, |ρ| = ``brdf_entries`` stored and k terms:

    * cases 1 and 2c (V and ρ̃ share a coefficient, the light's mean there): a binary search
      of each V entry among ρ̃'s keys; at most min(|V|, |ρ|) hits, each an RGB madd with the
      light's mean gathered (1 fetch, 24 bytes) and its weight (1);
    * case 2a (L and V share a wavelet): the lit test of every V entry (1 fetch); at most
      min(k, |V|) lit ones, each with ρ̃'s parent mean (:func:`parent_mean_counts` among ρ̃'s
      keys), the light gathered and 4 madds;
    * case 2b (L and ρ̃ share a wavelet): the same with the roles of V and ρ̃ swapped;
    * case 3 (three types of one node): the decode of every V entry (12 integer steps), its
      two sibling indices (2 × 6) and their lit tests (2 fetches); at most min(2k, |V|) with
      a lit sibling (each lit wavelet is a sibling of at most two V entries), each with two ρ̃
      lookups, the weight (a division), two light values gathered and 6 + 3 madds.

    Per call: the lit mask over the 6N² RGB light coefficients (4 madds, 24 bytes each) and
    the four ``add`` passes over the (P, 3) float64 output (each channel's ``bincount`` written,
    read and added: 24 bytes per channel).

    These terms are the non-zero tripling coefficients C_ijk the algorithm touches: the parent
    means sum all the strictly coarser ones of a wavelet in 1 + 3·level lookups.
    """
    m = coefficients(cubemap)
    levels = int(cubemap).bit_length() - 1  # wavelet levels 0 … log2 N − 1
    v, r = float(visibility_entries), float(brdf_entries)
    nnz_v, nnz_r = float(points) * v, float(points) * r
    look_r = lookup_counts(entries=nnz_r)
    light_gather = {"madds": 0.0, "fetches": 1.0, "bytes": float(RGB64_BYTES)}
    lit_test = {"madds": 0.0, "fetches": 1.0, "bytes": 1.0}
    shared = add_counts(scaled(look_r, v), scaled(add_counts(light_gather, {"madds": 4.0}),
                                                  min(v, r)))
    case_2a = add_counts(scaled(lit_test, v), scaled(
        add_counts(parent_mean_counts(levels=levels, entries=nnz_r), light_gather,
                   {"madds": 4.0}), min(terms, v)))
    case_2b = add_counts(scaled(lit_test, r), scaled(
        add_counts(parent_mean_counts(levels=levels, entries=nnz_v), light_gather,
                   {"madds": 4.0}), min(terms, r)))
    case_3 = add_counts(
        scaled(add_counts({"madds": 12.0 + 12.0}, scaled(lit_test, 2)), v),
        scaled(add_counts(scaled(look_r, 2), scaled(light_gather, 2),
                          {"madds": 1.0 + TRANSCENDENTAL_MADDS + 6.0 + 3.0}),
               min(2 * terms, v)))
    per_point = add_counts(shared, case_2a, case_2b, case_3,
                           {"bytes": 4.0 * 3 * 24})  # the four add passes
    per_call = {"madds": 4.0 * m, "fetches": 0.0, "bytes": float(RGB64_BYTES * m + 2 * m)}
    return add_counts(scaled(per_point, points), per_call)


def brdf_projection_counts(*, cubemap: int, samples: int, keep: int) -> dict[str, float]:
    """:func:`~prtbench.transport.wavelet.brdf.project` of one point's glossy factor G.

    Per texel subsample (6N²·S²): n·ω and r·ω (3 madds each, the 12-byte direction read
    twice), two clamps, the Phong power, the three scalings (lobe, (s+1)/2π, area weight)
    and, for S > 1, the sum into its texel: 16 madds, and each of the twelve in-place float32
    passes reading and writing its 4 bytes. Then the float32 Haar of the 6 faces
    (:func:`haar_counts`), the |·| and the partial sort of the ``keep`` largest
    (:func:`partial_sort_counts`), their values gathered (``keep`` fetches) and the non-zero
    filter.
    """
    m = coefficients(cubemap)
    subsamples = m * int(samples) ** 2
    texels = {"madds": float(subsamples * (15 + (samples > 1))), "fetches": 0.0,
              "bytes": float(subsamples * (2 * RGB32_BYTES + 4 + 12 * 8))}
    pick = {"madds": float(m + keep), "fetches": float(keep), "bytes": float(8 * m + 8 * keep)}
    return add_counts(texels, haar_counts(signals=6, n=int(cubemap), value_bytes=4),
                      partial_sort_counts(m=m, k=min(keep, m), value_bytes=4), pick)
