"""A 3-D multiresolution hash grid (Müller et al. 2022) in pure torch.

Level ``l`` (0 ≤ l < L) is a grid of resolution ``R_l = ⌊b · s^l⌋`` cells per axis over the unit
cube (``b`` the base resolution, ``s`` the per-level scale), so it has ``(R_l + 1)³`` vertices.
Each level owns a table of ``min(2^T, (R_l + 1)³)`` entries of F features:

* where the level's vertices fit the table, the index is dense:
  ``i = x + (R_l + 1)·y + (R_l + 1)²·z`` (no collisions);
* otherwise it is the usual spatial hash ``(x·1 ⊕ y·2654435761 ⊕ z·805459861) mod 2^T``.

A point's level feature is the trilinear interpolation of its cell's 8 vertex entries; the
output concatenates the L levels, (P, L·F). Points are mapped to the unit cube by the grid's
axis-aligned ``bounds`` and clamped into it, so points on the boundary are valid.

The tables are one flat float32 parameter with per-level offsets; its bytes (and Adam's three
copies while training) are checked against :data:`MAX_TABLE_BYTES` before anything is
allocated.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from prtbench.api.config import format_bytes
from prtbench.api.errors import InvalidInputError

#: Hash primes of Müller et al. 2022 (the first is 1: x enters unchanged).
PRIMES = (1, 2654435761, 805459861)
#: Largest table (all levels, float32) accepted: training keeps 4 copies (weights, gradient and
#: Adam's two moments), so 1 GiB of table is 4 GiB resident while training.
MAX_TABLE_BYTES = 1 << 30


def level_resolutions(*, levels: int, base_resolution: int, per_level_scale: float) -> list[int]:
    """Cells per axis ``⌊b · s^l⌋`` of each level."""
    return [int(math.floor(base_resolution * per_level_scale ** l)) for l in range(levels)]


def level_sizes(*, levels: int, base_resolution: int, per_level_scale: float,
                log2_table: int) -> list[int]:
    """Table entries of each level: ``min(2^T, (R_l + 1)³)``."""
    cap = 1 << int(log2_table)
    return [min(cap, (r + 1) ** 3) for r in level_resolutions(
        levels=levels, base_resolution=base_resolution, per_level_scale=per_level_scale)]


def table_bytes(*, levels: int, features: int, base_resolution: int, per_level_scale: float,
                log2_table: int) -> int:
    """Bytes of all levels' float32 tables."""
    return 4 * features * sum(level_sizes(levels=levels, base_resolution=base_resolution,
                                          per_level_scale=per_level_scale, log2_table=log2_table))


def check_table(*, levels: int, features: int, base_resolution: int, per_level_scale: float,
                log2_table: int, limit: int = MAX_TABLE_BYTES) -> int:
    """The table's bytes, or a one-line InvalidInputError naming them and the limit."""
    for name, value, low in (("levels", levels, 1), ("features", features, 1),
                             ("base_resolution", base_resolution, 1), ("log2_table", log2_table, 1)):
        if isinstance(value, bool) or int(value) != value or value < low:
            raise InvalidInputError(f"hash grid {name}={value!r}; accepted: integers >= {low}")
    if not per_level_scale >= 1.0:
        raise InvalidInputError(f"hash grid per_level_scale={per_level_scale!r}; accepted: >= 1")
    if log2_table > 40 or levels > 256:
        raise InvalidInputError(f"hash grid levels={levels}, log2_table={log2_table}; "
                                "accepted: levels <= 256, log2_table <= 40")
    need = table_bytes(levels=levels, features=features, base_resolution=base_resolution,
                       per_level_scale=per_level_scale, log2_table=log2_table)
    if need > limit:
        raise InvalidInputError(
            f"hash grid levels={levels} features={features} log2_table={log2_table} "
            f"(base_resolution={base_resolution}, per_level_scale={per_level_scale:g}) needs "
            f"{need} bytes ({format_bytes(need)}) of tables; accepted: at most {limit} bytes "
            f"({format_bytes(limit)}): fewer levels or features, or a smaller log2_table")
    return need


class HashGrid(torch.nn.Module):
    """Multiresolution hash encoding H: (P, 3) world points -> (P, L·F) features.

    Parameters
    ----------
    levels, features, base_resolution, per_level_scale, log2_table
        L, F, b, s and T of the module docstring.
    bounds : (lo, hi)
        World box mapped to the unit cube (each a 3-sequence).
    init_scale : float
        Entries start uniform in ±init_scale (Müller et al.: 1e-4).
    generator : torch.Generator, optional
        For a seeded initialisation.
    """

    def __init__(self, *, levels: int, features: int, base_resolution: int,
                 per_level_scale: float, log2_table: int, bounds, init_scale: float = 1e-4,
                 generator: torch.Generator | None = None):
        super().__init__()
        check_table(levels=levels, features=features, base_resolution=base_resolution,
                    per_level_scale=per_level_scale, log2_table=log2_table)
        self.levels, self.features = int(levels), int(features)
        self.log2_table = int(log2_table)
        self.resolutions = level_resolutions(levels=levels, base_resolution=base_resolution,
                                             per_level_scale=per_level_scale)
        sizes = level_sizes(levels=levels, base_resolution=base_resolution,
                            per_level_scale=per_level_scale, log2_table=log2_table)
        self.dense = [(r + 1) ** 3 <= (1 << self.log2_table) for r in self.resolutions]
        self.sizes = sizes
        self.offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        lo, hi = (np.asarray(b, np.float64).reshape(3) for b in bounds)
        if not np.all(hi > lo):
            raise InvalidInputError(f"hash grid bounds lo={lo.tolist()} hi={hi.tolist()}; "
                                    "accepted: hi > lo on every axis")
        self.register_buffer("lo", torch.as_tensor(lo, dtype=torch.float32))
        self.register_buffer("extent", torch.as_tensor(hi - lo, dtype=torch.float32))
        table = (torch.rand(int(self.offsets[-1]), self.features, generator=generator) * 2 - 1)
        self.table = torch.nn.Parameter(table * init_scale)
        # The 8 cell corners as (dx, dy, dz) offsets.
        corners = torch.tensor([[(c >> 0) & 1, (c >> 1) & 1, (c >> 2) & 1] for c in range(8)])
        self.register_buffer("corners", corners.to(torch.int64))

    @property
    def output_dim(self) -> int:
        return self.levels * self.features

    def nbytes(self) -> int:
        """Resident bytes of the tables (float32)."""
        return int(self.table.numel() * self.table.element_size())

    def index(self, level: int, vertex: torch.Tensor) -> torch.Tensor:
        """Table rows (…,) of integer grid vertices (…, 3) of ``level`` (offset included)."""
        r1 = self.resolutions[level] + 1
        if self.dense[level]:
            i = vertex[..., 0] + r1 * (vertex[..., 1] + r1 * vertex[..., 2])
        else:
            i = (vertex[..., 0] * PRIMES[0]) ^ (vertex[..., 1] * PRIMES[1]) \
                ^ (vertex[..., 2] * PRIMES[2])
            i = i & ((1 << self.log2_table) - 1)
        return i + int(self.offsets[level])

    def forward(self, points: torch.Tensor) -> torch.Tensor:
        """Features (P, L·F) of world points (P, 3)."""
        unit = ((points - self.lo) / self.extent).clamp(0.0, 1.0)
        out = []
        for level, res in enumerate(self.resolutions):
            scaled = unit * res
            cell = scaled.floor().clamp(max=res - 1)
            frac = scaled - cell  # in [0, 1]; 1 only on the grid's far faces
            vertex = cell.to(torch.int64)[:, None, :] + self.corners[None]  # (P, 8, 3)
            rows = self.index(level, vertex)  # (P, 8)
            c = self.corners[None].to(points.dtype)
            weight = torch.where(c > 0, frac[:, None, :], 1.0 - frac[:, None, :]).prod(dim=-1)
            out.append((self.table[rows] * weight[..., None]).sum(dim=1))
        return torch.cat(out, dim=1)
