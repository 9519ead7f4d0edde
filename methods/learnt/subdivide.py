"""Large scenes: sub-scenes with one small MLP each (thesis §4.1.5, figs. 4.5, 4.6, 4.14).

Two ways to split a scene:

* ``grid``: bounding-box cells (thesis fig. 4.6: Sponza in 12 parts). A fragment picks the
  network of the cell containing its world position. Each cell's network also trains on the
  points within δ × its cell size beyond its border (fig. 4.5), so two neighbouring networks
  agree along their shared border and no seam appears.
* ``objects``: semantic groups (fig. 4.14b): objects whose names share the prefix before the
  first '.' form one sub-scene (``sofa.frame`` and ``sofa.cushions`` are the sofa). A fragment
  picks its object's network, which is exact, so no other network is ever evaluated on a
  group's surface and no overlap is needed; each group trains on its own points.

Transfer is always traced against the whole scene (the training samples come from the whole
scene's precompute), so visibility accounts for every occluder. Neighbouring sub-scenes are then
merged greedily, CPCA-style but without principal components: the pair of neighbours whose
union has the smallest transfer variance (total variance of the transfer vectors of their
points) is merged while that variance stays below ``merge_variance`` × the mean variance of the
initial sub-scenes. Simple neighbouring regions thus share one network.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from prtbench.api.errors import InvalidInputError

#: Partition kinds as the shaders number them (LEARNT_PARTITION).
KINDS = {"none": 0, "grid": 1, "objects": 2}


@dataclass
class Partition:
    """How fragments pick a network.

    Attributes
    ----------
    kind : {"none", "grid", "objects"}
    n_groups : int
        Number of networks.
    grid_lo, cell_size : ndarray, shape (3,), float32
        Grid origin and cell extent (grid only).
    grid_cells : ndarray, shape (3,), int32
        Cells along x, y, z (grid only; (1, 1, 1) otherwise).
    group_of_cell : ndarray, shape (cells,), int32
        Network of each cell, x fastest (grid only).
    group_of_object : ndarray, shape (objects,), int32
        Network of each scene object (objects only; zeros otherwise).
    """

    kind: str
    n_groups: int
    grid_lo: np.ndarray
    cell_size: np.ndarray
    grid_cells: np.ndarray
    group_of_cell: np.ndarray
    group_of_object: np.ndarray

    def cell_of_points(self, points: np.ndarray) -> np.ndarray:
        """(N,) flat cell index (x fastest) of world ``points`` (N, 3), clamped to the grid."""
        ijk = np.floor((np.asarray(points, np.float64) - self.grid_lo) / self.cell_size)
        ijk = np.clip(ijk, 0, self.grid_cells - 1).astype(np.int64)
        nx, ny, _ = (int(c) for c in self.grid_cells)
        return ijk[:, 0] + nx * (ijk[:, 1] + ny * ijk[:, 2])

    def group_of_points(self, points: np.ndarray, object_ids: np.ndarray) -> np.ndarray:
        """(N,) network index of each point, as the fragment shader picks it."""
        if self.kind == "grid":
            return self.group_of_cell[self.cell_of_points(points)].astype(np.int32)
        if self.kind == "objects":
            return self.group_of_object[np.asarray(object_ids)].astype(np.int32)
        return np.zeros(len(points), np.int32)

    def to_arrays(self) -> dict[str, np.ndarray]:
        return {"partition_kind": np.array(KINDS[self.kind], np.int32),
                "partition_groups": np.array(self.n_groups, np.int32),
                "grid_lo": self.grid_lo.astype(np.float32),
                "grid_cell_size": self.cell_size.astype(np.float32),
                "grid_cells": self.grid_cells.astype(np.int32),
                "group_of_cell": self.group_of_cell.astype(np.int32),
                "group_of_object": self.group_of_object.astype(np.int32)}

    @classmethod
    def from_arrays(cls, arrays) -> "Partition":
        kind = {v: k for k, v in KINDS.items()}[int(arrays["partition_kind"])]
        return cls(kind, int(arrays["partition_groups"]), np.asarray(arrays["grid_lo"], np.float32),
                   np.asarray(arrays["grid_cell_size"], np.float32),
                   np.asarray(arrays["grid_cells"], np.int32),
                   np.asarray(arrays["group_of_cell"], np.int32),
                   np.asarray(arrays["group_of_object"], np.int32))


def object_prefix_groups(names: list[str]) -> np.ndarray:
    """(objects,) group index from the name prefix before the first '.' (first-seen order)."""
    order: dict[str, int] = {}
    return np.array([order.setdefault(n.split(".", 1)[0], len(order)) for n in names], np.int32)


class _Stats:
    """Count, mean and scatter of transfer vectors, mergeable exactly (parallel Welford)."""

    def __init__(self, transfer: np.ndarray):
        t = np.asarray(transfer, np.float64)
        self.n = len(t)
        self.mean = t.mean(axis=0) if self.n else np.zeros(t.shape[1])
        self.scatter = float(np.sum((t - self.mean) ** 2)) if self.n else 0.0

    @classmethod
    def merged(cls, a: "_Stats", b: "_Stats") -> "_Stats":
        out = cls.__new__(cls)
        out.n = a.n + b.n
        if out.n == 0:
            out.mean, out.scatter = a.mean, 0.0
            return out
        delta = b.mean - a.mean
        out.mean = a.mean + delta * (b.n / out.n)
        out.scatter = a.scatter + b.scatter + float(delta @ delta) * a.n * b.n / out.n
        return out

    @property
    def variance(self) -> float:
        return self.scatter / self.n if self.n else 0.0


def merge_by_variance(stats: list[_Stats], adjacency: set[tuple[int, int]], *,
                      threshold: float) -> np.ndarray:
    """Greedy merging of neighbouring regions by the variance of their union.

    Parameters
    ----------
    stats : list of _Stats
        Transfer statistics of each initial region.
    adjacency : set of (i, j), i < j
        Neighbouring initial regions.
    threshold : float
        Merge while the union's variance ≤ threshold × the mean initial variance (0: never).

    Returns
    -------
    ndarray, shape (regions,), int32
        Group of each initial region, numbered 0..G−1 in first-seen order.
    """
    label = list(range(len(stats)))
    current = {i: s for i, s in enumerate(stats)}
    populated = [s.variance for s in stats if s.n]
    budget = threshold * (float(np.mean(populated)) if populated else 0.0)
    while threshold > 0:
        pairs = {(min(label[i], label[j]), max(label[i], label[j])) for i, j in adjacency}
        pairs = [(a, b) for a, b in pairs if a != b]
        if not pairs:
            break
        unions = [(_Stats.merged(current[a], current[b]), a, b) for a, b in pairs]
        best, a, b = min(unions, key=lambda u: u[0].variance)
        if best.variance > budget:
            break
        current[a] = best
        del current[b]
        label = [a if g == b else g for g in label]
    order: dict[int, int] = {}
    return np.array([order.setdefault(g, len(order)) for g in label], np.int32)


def build_partition(scene, samples, *, kind: str, grid_cells=(2, 1, 2),
                    merge_variance: float = 0.0) -> Partition:
    """The partition of ``scene`` for ``kind``, merged by the variance of ``samples``' transfer.

    Parameters
    ----------
    scene : Scene
    samples : TransferSamples
        Training points of the whole scene (their transfer drives the merging).
    kind : {"none", "grid", "objects"}
    grid_cells : 3 ints
        Cells along x, y, z (grid).
    merge_variance : float
        See :func:`merge_by_variance`.
    """
    n_objects = len(scene.objects)
    ones = np.ones(3, np.int32)
    if kind == "none":
        return Partition("none", 1, np.zeros(3, np.float32), np.ones(3, np.float32), ones,
                         np.zeros(1, np.int32), np.zeros(n_objects, np.int32))
    if kind == "grid":
        cells = np.asarray(grid_cells, np.int64)
        if cells.shape != (3,) or np.any(cells < 1) or np.prod(cells) > 4096:
            raise InvalidInputError(f"grid_cells={tuple(grid_cells)}; accepted: 3 positive "
                                    "integers with at most 4096 cells in all")
        lo, hi = scene.bounds()
        pad = 1e-4 * max(float(np.max(hi - lo)), 1e-6)  # boundary points fall inside the grid
        lo, hi = lo - pad, hi + pad
        size = (hi - lo) / cells
        partition = Partition("grid", int(np.prod(cells)), lo.astype(np.float32),
                              size.astype(np.float32), cells.astype(np.int32),
                              np.arange(int(np.prod(cells)), dtype=np.int32),
                              np.zeros(n_objects, np.int32))
        region = partition.cell_of_points(samples.points)
        n_regions = partition.n_groups
        adjacency = set()
        nx, ny, nz = (int(c) for c in cells)
        for flat in range(n_regions):
            i, j, k = flat % nx, (flat // nx) % ny, flat // (nx * ny)
            for di, dj, dk in ((1, 0, 0), (0, 1, 0), (0, 0, 1)):
                if i + di < nx and j + dj < ny and k + dk < nz:
                    adjacency.add((flat, (i + di) + nx * ((j + dj) + ny * (k + dk))))
    elif kind == "objects":
        initial = object_prefix_groups([o.name for o in scene.objects])
        n_regions = int(initial.max()) + 1
        region = initial[samples.object_ids]
        boxes = []
        for g in range(n_regions):
            pts = np.concatenate([o.mesh.positions for o, gg in zip(scene.objects, initial)
                                  if gg == g])
            boxes.append((pts.min(axis=0), pts.max(axis=0)))
        adjacency = set()
        for a in range(n_regions):
            for b in range(a + 1, n_regions):
                gap = np.maximum(boxes[a][0], boxes[b][0]) - np.minimum(boxes[a][1], boxes[b][1])
                if np.all(gap <= 1e-4 * scene.diagonal()):  # touching or overlapping boxes
                    adjacency.add((a, b))
        partition = Partition("objects", n_regions, np.zeros(3, np.float32),
                              np.ones(3, np.float32), ones, np.zeros(1, np.int32), initial)
    else:
        raise InvalidInputError(f"partition '{kind}'; accepted: {', '.join(KINDS)}")
    stats = [_Stats(samples.transfer[region == r]) for r in range(n_regions)]
    group_of_region = merge_by_variance(stats, adjacency, threshold=merge_variance)
    partition.n_groups = int(group_of_region.max()) + 1
    if kind == "grid":
        partition.group_of_cell = group_of_region
    else:
        partition.group_of_object = group_of_region[partition.group_of_object]
    return partition


def training_rows(partition: Partition, samples, *, overlap: float) -> list[np.ndarray]:
    """Row indices of ``samples`` each network trains on.

    Grid: a group's own points plus those within δ = ``overlap`` × cell size beyond the border
    of any of its cells (fig. 4.5). Objects and none: the group's own points.
    """
    own = partition.group_of_points(samples.points, samples.object_ids)
    if partition.kind != "grid" or overlap <= 0:
        return [np.nonzero(own == g)[0] for g in range(partition.n_groups)]
    rows = []
    p = np.asarray(samples.points, np.float64)
    delta = overlap * partition.cell_size.astype(np.float64)
    nx, ny, _ = (int(c) for c in partition.grid_cells)
    for g in range(partition.n_groups):
        take = own == g
        for flat in np.nonzero(partition.group_of_cell == g)[0]:
            ijk = np.array([flat % nx, (flat // nx) % ny, flat // (nx * ny)], np.float64)
            lo = partition.grid_lo + ijk * partition.cell_size - delta
            hi = partition.grid_lo + (ijk + 1) * partition.cell_size + delta
            take |= np.all((p >= lo) & (p <= hi), axis=1)
        rows.append(np.nonzero(take)[0])
    return rows
