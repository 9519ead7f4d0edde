"""Where the probes are, and where each lives in the GPU pool: a uniform grid, or 4×4×4 bricks
that are denser near geometry (Unity's adaptive probe volumes).

Uniform: N³ probes on the padded scene bounds, probe (i, j, k) at origin + (i, j, k)·cell, in
an N × N × N pool texture at texel (i, j, k); id ((i·N) + j)·N + k.

Bricks: the padded bounds are split into cubic cells, C along the longest axis, C the smallest
multiple of 3^L at or above N − 1 (``levels`` L). A brick of level l spans 3^(l+1) cells with 4 probes per axis
(the brick's 3 cells at 3^l cells' spacing; neighbouring bricks repeat their shared face, as
Unity's do, so a lookup never leaves its brick). The domain starts as level L − 1 bricks, and a
brick of level l > 0 is replaced by its 27 children where geometry comes within a cell of it
(its triangles sampled at half a finest cell), down to level 0. The pool holds the leaves in
(a, b, c) slots of 4³ texels; slot s sits at 4·(s mod a, (s div a) mod b, s div ab), and brick
probe (i, j, k) of slot s has id 64·s + (i·4 + j)·4 + k. An index texture over the finest
bricks (a third of the cells per axis) holds, for each, ``slot | level << 24`` of the leaf that covers it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Probes per brick side, and cells per brick side.
BRICK_PROBES, BRICK_CELLS = 4, 3


@dataclass(frozen=True, eq=False)
class ProbeLayout:
    """Probe positions and their place in the pool.

    Attributes
    ----------
    kind : {"uniform", "bricks"}
    origin, cell : ndarray, shape (3,)
        Position of the lattice's corner and the finest spacing per axis.
    positions : ndarray, shape (P, 3), float64
        Lookup positions (before any virtual offset), by id.
    spacing : ndarray, shape (P, 3), float64
        The spacing of each probe's own lattice (its brick's level).
    texel : ndarray, shape (P, 3), int64
        Pool texel of each probe.
    pool_shape : tuple of int
        Pool texture size (x, y, z) in texels; padding slots beyond the probes stay empty.
    grid : int
        N (uniform) or C, the finest cells along the longest axis (bricks).
    index : ndarray, shape (Bx, By, Bz), uint32, or None
        Bricks: ``slot | level << 24`` per finest brick (x, y, z).
    pool_bricks : tuple of int
        Bricks: slots (a, b, c) of the pool.
    levels : int
    """

    kind: str
    origin: np.ndarray
    cell: np.ndarray
    positions: np.ndarray
    spacing: np.ndarray
    texel: np.ndarray
    pool_shape: tuple[int, int, int]
    grid: int
    index: np.ndarray | None = None
    pool_bricks: tuple[int, int, int] = (1, 1, 1)
    levels: int = 1

    @property
    def probes(self) -> int:
        return int(len(self.positions))

    @property
    def pool_probes(self) -> int:
        """Probe slots the pool textures hold (padding included)."""
        return int(np.prod(self.pool_shape))


def padded_bounds(scene, padding: float) -> tuple[np.ndarray, np.ndarray]:
    """Scene bounds grown by ``padding`` × diagonal on each side, and every side at least
    10⁻³ of the diagonal (a flat scene still gets a volume)."""
    lo, hi = scene.bounds()
    diagonal = max(float(np.linalg.norm(hi - lo)), 1e-6)
    lo, hi = lo - padding * diagonal, hi + padding * diagonal
    thin = np.maximum(1e-3 * diagonal - (hi - lo), 0.0) / 2
    return lo - thin, hi + thin


def uniform_layout(scene, *, resolution: int, padding: float) -> ProbeLayout:
    """N³ probes (N = ``resolution``) on the padded bounds."""
    lo, hi = padded_bounds(scene, padding)
    n = int(resolution)
    cell = (hi - lo) / (n - 1)
    idx = np.stack(np.meshgrid(*(np.arange(n),) * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    return ProbeLayout("uniform", lo, cell, lo + idx * cell, np.broadcast_to(cell, idx.shape).copy(),
                       idx.astype(np.int64), (n, n, n), n)


def occupied_cells(scene, origin: np.ndarray, cell: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """(Cx, Cy, Cz) bool: cells (x, y, z) that a triangle's surface passes through.

    Each triangle is sampled on a barycentric grid fine enough for half a cell (capped at 64
    steps per edge: larger triangles are exact on the ground planes the scenes use, whose
    triangles are few).
    """
    positions, _, faces, _ = scene.merged()
    corners = positions.astype(np.float64)[faces]  # (F, 3, 3)
    edge = np.max(np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2), axis=1)
    steps = np.clip(np.ceil(edge / (0.5 * float(cell.min()))), 1, 64).astype(int)
    cells = np.asarray(cells, np.int64)
    occupied = np.zeros(tuple(cells), bool)
    for k in np.unique(steps):
        tri = corners[steps == k]
        i, j = np.meshgrid(np.arange(k + 1), np.arange(k + 1), indexing="ij")
        keep = i + j <= k
        bary = np.stack([i[keep], j[keep], k - i[keep] - j[keep]], axis=1) / k  # (S, 3)
        points = np.einsum("sc,fcd->fsd", bary, tri).reshape(-1, 3)
        at = np.clip(np.floor((points - origin) / cell).astype(np.int64), 0, cells - 1)
        occupied[at[:, 0], at[:, 1], at[:, 2]] = True
    return occupied


def _grow(occupied: np.ndarray) -> np.ndarray:
    """``occupied`` dilated by one cell (26-neighbourhood)."""
    out = occupied.copy()
    shape = occupied.shape
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            for dz in (-1, 0, 1):
                src = tuple(slice(max(-d, 0), c - max(d, 0)) for d, c in zip((dx, dy, dz), shape))
                dst = tuple(slice(max(d, 0), c - max(-d, 0)) for d, c in zip((dx, dy, dz), shape))
                out[dst] |= occupied[src]
    return out


def _pool(count: int) -> tuple[int, int, int]:
    """Slots (a, b, c) for ``count`` bricks: near a cube, little padding."""
    a = max(1, math.ceil(count ** (1.0 / 3.0)))
    b = max(1, math.ceil(math.sqrt(count / a)))
    return a, b, max(1, math.ceil(count / (a * b)))


def brick_layout(scene, *, resolution: int, levels: int, padding: float) -> ProbeLayout:
    """4×4×4 bricks of cubic cells, ``levels`` levels of 3× refinement towards the geometry.

    The longest axis of the padded bounds gets C cells (C the smallest multiple of 3^L at or
    above ``resolution`` − 1); the other axes as many cells of that size as cover them,
    rounded up to whole coarsest bricks (the volume grows on their far side).
    """
    lo, hi = padded_bounds(scene, padding)
    top = BRICK_CELLS ** int(levels)  # cells per coarsest brick
    longest = top * max(1, math.ceil((int(resolution) - 1) / top))
    size = float((hi - lo).max()) / longest
    cells = top * np.maximum(1, np.ceil((hi - lo) / size / top - 1e-9)).astype(np.int64)
    cell = np.full(3, size)
    near = _grow(occupied_cells(scene, lo, cell, cells))
    leaves: list[tuple[int, np.ndarray]] = []  # (level, brick coordinate in its level's units)
    todo = [(levels - 1, b) for b in np.argwhere(np.ones(tuple(cells // top), bool))]
    while todo:
        level, b = todo.pop()
        span = BRICK_CELLS ** (level + 1)
        region = near[tuple(slice(int(v) * span, (int(v) + 1) * span) for v in b)]
        if level > 0 and region.any():
            todo += [(level - 1, b * 3 + c) for c in np.argwhere(np.ones((3, 3, 3), bool))]
        else:
            leaves.append((level, b))
    leaves.sort(key=lambda leaf: (leaf[0], tuple(int(v) for v in leaf[1])))
    a, bb, c = _pool(len(leaves))
    local = np.stack(np.meshgrid(*(np.arange(BRICK_PROBES),) * 3, indexing="ij"),
                     axis=-1).reshape(-1, 3)
    positions, spacing, texel = [], [], []
    index = np.zeros(tuple(cells // BRICK_CELLS), np.uint32)
    for slot, (level, b) in enumerate(leaves):
        step = BRICK_CELLS ** level  # finest cells between the brick's probes
        corner_cells = b * BRICK_CELLS ** (level + 1)
        positions.append(lo + (corner_cells + local * step) * cell)
        spacing.append(np.broadcast_to(cell * step, (len(local), 3)))
        base = BRICK_PROBES * np.array([slot % a, (slot // a) % bb, slot // (a * bb)])
        texel.append(base + local)
        span = BRICK_CELLS ** level  # finest bricks per axis this leaf covers
        index[tuple(slice(int(v) * span, (int(v) + 1) * span) for v in b)] = slot | (level << 24)
    return ProbeLayout("bricks", lo, cell, np.concatenate(positions), np.concatenate(spacing),
                       np.concatenate(texel).astype(np.int64),
                       (BRICK_PROBES * a, BRICK_PROBES * bb, BRICK_PROBES * c), longest, index,
                       (a, bb, c), int(levels))


def corners(layout: ProbeLayout, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The numpy twin of ``probe_cell`` in ``probe_volume.frag``: the 8 probes around each
    point and their trilinear weights.

    Returns
    -------
    ids : ndarray, shape (N, 8), int64
        Probe ids of corner c = (c & 1, c >> 1 & 1, c >> 2 & 1).
    weights : ndarray, shape (N, 8), float64
    """
    p = np.asarray(points, np.float64).reshape(-1, 3)
    bits = np.array([[c & 1, (c >> 1) & 1, (c >> 2) & 1] for c in range(8)])
    if layout.kind == "uniform":
        n = layout.grid
        g = np.clip((p - layout.origin) / layout.cell, 0.0, n - 1.0)
        base = np.minimum(np.floor(g).astype(np.int64), n - 2)
        f = g - base
        at = base[:, None, :] + bits[None]
        ids = (at[..., 0] * n + at[..., 1]) * n + at[..., 2]
    else:
        side = np.array(layout.index.shape)
        brick = np.clip(np.floor((p - layout.origin) / (layout.cell * BRICK_CELLS)), 0, side - 1)
        entry = layout.index[tuple(brick.astype(np.int64).T)]
        slot, level = entry & 0xFFFFFF, entry >> 24
        span = BRICK_CELLS ** level.astype(np.int64)
        brick_origin = layout.origin + (brick // span[:, None]) * span[:, None] * (
            layout.cell * BRICK_CELLS)
        step = layout.cell * span[:, None]
        g = np.clip((p - brick_origin) / step, 0.0, BRICK_CELLS)
        base = np.minimum(np.floor(g).astype(np.int64), BRICK_CELLS - 1)
        f = g - base
        at = base[:, None, :] + bits[None]
        ids = 64 * slot.astype(np.int64)[:, None] + (at[..., 0] * 4 + at[..., 1]) * 4 + at[..., 2]
    w3 = np.where(bits[None] == 1, f[:, None, :], 1.0 - f[:, None, :])
    return ids, w3.prod(axis=2)
