"""Sparse wavelet transport: quantised, column-major storage and the k-term relighting product.

Ng 2003 renders B = T·L with the transport matrix T (points × 6N² Haar coefficients) truncated
per point and the light L truncated to the k terms chosen this frame (non-linear
approximation). Storing T by *coefficient* (compressed sparse columns) makes a frame's cost the
number of stored entries in the k selected columns, not the size of T: the product gathers
those columns only.

Storage, all of it counted by :attr:`SparseTransport.nbytes`:

* ``indptr`` (6N² + 1,) int64: column starts;
* ``rows`` (nnz,): the point of each entry, uint16 when the points fit, else uint32;
* ``values`` (nnz,): float32, float16, or int8 with a per-point float32 ``scale``
  (value = q · scale[point], scale = max |T_pi| / 127 over the point's kept entries).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from prtbench.api.errors import InvalidInputError

STORAGE_DTYPES = ("float32", "float16", "int8")
#: Bytes per stored value, for memory estimates before any work.
VALUE_BYTES = {"float32": 4, "float16": 2, "int8": 1}


def row_dtype(n_points: int) -> np.dtype:
    """Smallest unsigned integer dtype holding point indices 0..n_points − 1."""
    return np.dtype(np.uint16) if n_points <= 1 << 16 else np.dtype(np.uint32)


def as_float16(values: np.ndarray) -> np.ndarray:
    """``values.astype(np.float16)``, bit for bit, several times faster for float32 values.

    numpy's cast costs ~25 ns a value whose result is a float16 subnormal (a third of a
    truncated transport's values are below 2⁻¹⁴), so float32 is rounded here in integer
    arithmetic on its bits, to nearest with ties to even like the cast: normal results drop 13
    mantissa bits and rebias the exponent; subnormal ones (|x| < 2⁻¹⁴) are the low bits of
    |x| + 0.5, whose float32 rounding is onto float16's subnormal grid (steps of 2⁻²⁴).
    Overflow, infinities and NaN (|x| >= 2¹⁶) go through numpy's cast. Other dtypes: the cast.

    Parameters
    ----------
    values : ndarray

    Returns
    -------
    ndarray, float16, the shape of ``values``
    """
    values = np.asarray(values)
    if values.dtype != np.float32:
        return values.astype(np.float16)
    bits = np.ascontiguousarray(values).view(np.uint32)
    magnitude = bits & np.uint32(0x7FFF_FFFF)
    half = magnitude >> np.uint32(13)
    half &= np.uint32(1)  # round half to even: + 0xFFF, + 1 if the kept bits are odd
    half += magnitude
    half += np.uint32(0xC800_0FFF)  # exponent bias 127 -> 15 (mod 2³²) and the rounding
    half >>= np.uint32(13)
    with np.errstate(invalid="ignore"):  # signalling NaNs: their result is numpy's, below
        subnormal = (magnitude.view(np.float32) + np.float32(0.5)).view(np.uint32)
    subnormal -= np.uint32(0x3F00_0000)  # the bits of 0.5
    np.copyto(half, subnormal, where=magnitude < np.uint32(113 << 23))  # |x| < 2⁻¹⁴
    out = half.astype(np.uint16)
    out |= (bits >> np.uint32(16)).astype(np.uint16) & np.uint16(0x8000)
    large = magnitude >= np.uint32(143 << 23)  # |x| >= 2¹⁶: inf, NaN, or rounds to inf
    if large.any():
        out[large] = values[large].astype(np.float16).view(np.uint16)
    return out.view(np.float16)


@dataclass
class SparseTransport:
    """Transport matrix (points × coefficients) in compressed sparse columns.

    Attributes
    ----------
    indptr : ndarray, shape (M + 1,), int64
    rows : ndarray, shape (nnz,), uint16 or uint32
    values : ndarray, shape (nnz,), float32, float16 or int8
    scale : ndarray, shape (P,), float32, or None
        Per-point dequantisation scale (int8 storage only).
    n_points : int
    """

    indptr: np.ndarray
    rows: np.ndarray
    values: np.ndarray
    scale: np.ndarray | None
    n_points: int

    @property
    def n_coeffs(self) -> int:
        return len(self.indptr) - 1

    @property
    def nnz(self) -> int:
        return len(self.values)

    @property
    def nbytes(self) -> int:
        """Bytes actually stored (indices, values, scales)."""
        parts = [self.indptr, self.rows, self.values] + ([self.scale] if self.scale is not None else [])
        return int(sum(p.nbytes for p in parts))

    @classmethod
    def from_entries(cls, points: np.ndarray, coeffs: np.ndarray, values: np.ndarray, *,
                     n_points: int, n_coeffs: int, storage: str) -> "SparseTransport":
        """Build from (point, coefficient, value) triples (any order; no duplicates).

        Parameters
        ----------
        points, coeffs : ndarray, shape (nnz,), int
        values : ndarray, shape (nnz,), float
        n_points, n_coeffs : int
        storage : {"float32", "float16", "int8"}
        """
        if storage not in STORAGE_DTYPES:
            raise InvalidInputError(f"storage '{storage}'; accepted: {', '.join(STORAGE_DTYPES)}")
        points, coeffs, values = np.asarray(points), np.asarray(coeffs), np.asarray(values)
        if points.dtype.kind not in "iu" or coeffs.dtype.kind not in "iu":
            raise InvalidInputError("sparse transport entries need integer point and "
                                    "coefficient indices")
        if len(points) > 1 and np.any(points[1:] < points[:-1]):
            by_point = np.argsort(points, kind="stable")
            points, coeffs, values = points[by_point], coeffs[by_point], values[by_point]
        return cls.from_rows(np.bincount(points, minlength=n_points), coeffs, values,
                             n_coeffs=n_coeffs, storage=storage)

    @classmethod
    def from_rows(cls, counts: np.ndarray, coeffs: np.ndarray, values: np.ndarray, *,
                  n_coeffs: int, storage: str) -> "SparseTransport":
        """Build from entries listed point by point (compressed sparse rows, no duplicates).

        Parameters
        ----------
        counts : ndarray, shape (P,), int
            Entries of each point; point p's are ``coeffs``/``values`` of the p-th run.
        coeffs : ndarray, shape (nnz,), int
            Coefficient of each entry, in any order within a point's run.
        values : ndarray, shape (nnz,), float
        n_coeffs : int
        storage : {"float32", "float16", "int8"}
        """
        if storage not in STORAGE_DTYPES:
            raise InvalidInputError(f"storage '{storage}'; accepted: {', '.join(STORAGE_DTYPES)}")
        counts, coeffs, values = np.asarray(counts), np.asarray(coeffs), np.asarray(values)
        if coeffs.dtype.kind not in "iu":
            raise InvalidInputError("sparse transport entries need integer coefficient indices")
        if values.dtype.kind != "f":
            values = values.astype(np.float64)
        n_points = len(counts)
        if int(counts.sum()) != len(coeffs) or len(coeffs) != len(values):
            raise InvalidInputError(f"{int(counts.sum())} entries counted, {len(coeffs)} "
                                    f"coefficients and {len(values)} values; accepted: equal")
        # By coefficient, then point: scipy's CSR -> CSC conversion, a counting sort in C that
        # keeps the point order within each coefficient, permutes the entries' positions
        # (~2× faster than a stable argsort and the gathers after it).
        from scipy.sparse import csr_matrix

        point_ptr = np.zeros(n_points + 1, dtype=np.int64)
        np.cumsum(counts, out=point_ptr[1:])
        positions = np.arange(len(coeffs), dtype=np.int32 if len(coeffs) < 1 << 31 else np.int64)
        by_coeff = csr_matrix((positions, coeffs, point_ptr), shape=(n_points, n_coeffs)).tocsc()
        order = by_coeff.data
        scale = None
        if storage == "int8":
            peak = np.zeros(n_points)
            filled = np.flatnonzero(counts)
            if len(filled):  # the largest |value| of each point, from its run of entries
                peak[filled] = np.maximum.reduceat(np.abs(values), point_ptr[filled])
            scale = (np.where(peak > 0, peak, 1.0) / 127.0).astype(np.float32)
            points = np.repeat(np.arange(n_points), counts)
            stored = np.clip(np.rint(values / scale[points]), -127, 127).astype(np.int8)
        else:
            # Values already of the stored type (rounded on the precompute threads) are not copied.
            stored = (as_float16(values) if storage == "float16"
                      else values).astype(storage, copy=False)
        return cls(by_coeff.indptr.astype(np.int64), by_coeff.indices.astype(row_dtype(n_points)),
                   stored[order], scale, int(n_points))

    def arrays(self, prefix: str = "") -> dict[str, np.ndarray]:
        """The stored arrays by name (for an :class:`~prtbench.api.method.Artifact`)."""
        out = {f"{prefix}indptr": self.indptr, f"{prefix}rows": self.rows,
               f"{prefix}values": self.values, f"{prefix}n_points": np.array(self.n_points)}
        if self.scale is not None:
            out[f"{prefix}scale"] = self.scale
        return out

    @classmethod
    def from_arrays(cls, arrays, prefix: str = "") -> "SparseTransport":
        """Inverse of :meth:`arrays`."""
        scale = arrays.get(f"{prefix}scale")
        return cls(arrays[f"{prefix}indptr"], arrays[f"{prefix}rows"], arrays[f"{prefix}values"],
                   scale, int(arrays[f"{prefix}n_points"]))

    def dense(self) -> np.ndarray:
        """(P, M) float64 matrix (tests and small cases only)."""
        out = np.zeros((self.n_points, self.n_coeffs))
        cols = np.repeat(np.arange(self.n_coeffs), np.diff(self.indptr))
        out[self.rows.astype(np.int64), cols] = self._dequantised(slice(None))
        return out

    def _dequantised(self, entries) -> np.ndarray:
        v = self.values[entries].astype(np.float32)
        if self.scale is not None:
            v *= self.scale[self.rows[entries]]
        return v

    def column_mean_abs(self) -> np.ndarray:
        """(M,) float32 mean over points of |T_pi|: the ``transport`` selection weights."""
        counts = np.diff(self.indptr)
        cols = np.repeat(np.arange(self.n_coeffs), counts)
        sums = np.bincount(cols, weights=np.abs(self._dequantised(slice(None))),
                           minlength=self.n_coeffs)
        return (sums / max(self.n_points, 1)).astype(np.float32)

    def relight(self, light: np.ndarray, terms: np.ndarray) -> np.ndarray:
        """Σ_{i in terms} T_pi L_i for every point: the frame's sparse product.

        Parameters
        ----------
        light : ndarray, shape (M, C)
            Lighting coefficients (all of them; only ``terms`` are read).
        terms : ndarray, shape (k,), int
            The selected coefficients.

        Returns
        -------
        ndarray, shape (P, C), float64
            Cost: O(stored entries of the k columns), accumulated in float64.
        """
        terms = np.asarray(terms, dtype=np.int64)
        light = np.asarray(light)
        starts = self.indptr[terms]
        counts = self.indptr[terms + 1] - starts
        total = int(counts.sum())
        out = np.zeros((self.n_points, light.shape[1]))
        if total == 0:
            return out
        before = np.cumsum(counts) - counts
        entries = np.repeat(starts - before, counts) + np.arange(total)
        rows = self.rows[entries]
        t = self._dequantised(entries)
        coeff = np.repeat(light[terms].astype(np.float32), counts, axis=0)  # (total, C)
        for c in range(light.shape[1]):
            out[:, c] = np.bincount(rows, weights=t * coeff[:, c], minlength=self.n_points)
        return out
