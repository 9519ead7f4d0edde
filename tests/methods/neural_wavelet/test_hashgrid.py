"""The multiresolution hash grid: known tables, direct evaluation, continuity, gradients, limits."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from methods.neural_wavelet.hashgrid import PRIMES, HashGrid, check_table  # noqa: E402
from prtbench.api.errors import InvalidInputError  # noqa: E402

BOUNDS = ((-1.0, 0.0, -2.0), (1.0, 2.0, 2.0))


def _grid(**kw):
    args = dict(levels=3, features=2, base_resolution=4, per_level_scale=2.0, log2_table=8,
                bounds=BOUNDS, generator=torch.Generator().manual_seed(0))
    args.update(kw)
    return HashGrid(**args)


def _direct(grid: HashGrid, points: np.ndarray) -> np.ndarray:
    """Trilinear interpolation written out per point, corner and level, in float64."""
    table = grid.table.detach().double().numpy()
    lo, hi = np.array(BOUNDS[0]), np.array(BOUNDS[1])
    out = np.zeros((len(points), grid.output_dim))
    for p, x in enumerate(points):
        u = np.clip((x - lo) / (hi - lo), 0, 1)
        for level, res in enumerate(grid.resolutions):
            s = u * res
            cell = np.minimum(np.floor(s), res - 1).astype(int)
            f = s - cell
            acc = np.zeros(grid.features)
            for dz in (0, 1):
                for dy in (0, 1):
                    for dx in (0, 1):
                        v = cell + (dx, dy, dz)
                        if (res + 1) ** 3 <= 2 ** grid.log2_table:
                            i = v[0] + (res + 1) * v[1] + (res + 1) ** 2 * v[2]
                        else:
                            i = ((v[0] * PRIMES[0]) ^ (v[1] * PRIMES[1]) ^ (v[2] * PRIMES[2])) \
                                % 2 ** grid.log2_table
                        w = (f[0] if dx else 1 - f[0]) * (f[1] if dy else 1 - f[1]) \
                            * (f[2] if dz else 1 - f[2])
                        acc += w * table[grid.offsets[level] + i]
            out[p, level * grid.features:(level + 1) * grid.features] = acc
    return out


def test_dense_levels_interpolate_a_linear_table_exactly():
    # Entries set to a linear function of the vertex (a, b, c): trilinear interpolation
    # reproduces a linear function exactly, so the feature is that function of the point.
    grid = _grid(levels=2, base_resolution=3, log2_table=12)  # (3+1)³, (6+1)³ <= 4096: dense
    assert all(grid.dense)
    coeff = np.array([0.5, -2.0, 3.0])
    with torch.no_grad():
        for level, res in enumerate(grid.resolutions):
            r1 = res + 1
            idx = np.arange(r1 ** 3)
            v = np.stack([idx % r1, (idx // r1) % r1, idx // r1 ** 2], axis=1)
            vals = v @ coeff / res  # in unit-cube coordinates
            grid.table[grid.offsets[level]:grid.offsets[level + 1], 0] = torch.as_tensor(vals)
            grid.table[grid.offsets[level]:grid.offsets[level + 1], 1] = 1.0
    rng = np.random.default_rng(1)
    lo, hi = np.array(BOUNDS[0]), np.array(BOUNDS[1])
    pts = lo + rng.random((200, 3)) * (hi - lo)
    got = grid(torch.as_tensor(pts, dtype=torch.float32)).detach().numpy()
    want = ((pts - lo) / (hi - lo)) @ coeff
    for level in range(2):
        np.testing.assert_allclose(got[:, 2 * level], want, atol=2e-5)
        np.testing.assert_allclose(got[:, 2 * level + 1], 1.0, atol=1e-6)  # partition of unity


def test_hashed_levels_match_a_direct_evaluation():
    grid = _grid(levels=4, base_resolution=5, per_level_scale=1.8, log2_table=7)
    assert any(not d for d in grid.dense)  # at least one level is hashed (> 128 vertices)
    rng = np.random.default_rng(2)
    lo, hi = np.array(BOUNDS[0]), np.array(BOUNDS[1])
    pts = lo + rng.random((40, 3)) * (hi - lo)
    pts[0], pts[1] = lo, hi  # the boundary corners
    got = grid(torch.as_tensor(pts, dtype=torch.float32)).detach().double().numpy()
    np.testing.assert_allclose(got, _direct(grid, pts), atol=1e-9, rtol=1e-5)


def test_continuous_across_cell_boundaries():
    grid = _grid(levels=3, base_resolution=4, log2_table=6, init_scale=1.0)
    # x crosses the level-0 cell face at unit coordinate 1/4 (world x = -0.5) and level-1/2
    # faces at the same place; y, z inside cells.
    eps = 1e-5
    base = np.array([-0.5, 0.77, 0.31])
    left, right = base - [eps, 0, 0], base + [eps, 0, 0]
    f = grid(torch.as_tensor(np.stack([left, right]), dtype=torch.float64).float()).detach()
    jump = (f[0] - f[1]).abs().max().item()
    # Slope is at most (max entry difference) · res / extent ≈ 2 · 16 / 2 per world unit.
    assert jump < 2 * eps * 16 / 2 * 2 + 1e-5, jump
    # The gradient is not continuous (trilinear), but the value is: a far step changes it.
    far = grid(torch.as_tensor(np.stack([base, base + [0.3, 0, 0]]), dtype=torch.float32))
    assert (far[0] - far[1]).abs().max().item() > 100 * jump


def test_gradients_flow_and_a_tiny_fit_converges():
    torch.manual_seed(0)
    grid = _grid(levels=4, base_resolution=4, per_level_scale=1.6, log2_table=10)
    head = torch.nn.Linear(grid.output_dim, 1)
    lo, hi = np.array(BOUNDS[0]), np.array(BOUNDS[1])
    pts = torch.as_tensor(lo + np.random.default_rng(3).random((1024, 3)) * (hi - lo),
                          dtype=torch.float32)
    target = torch.sin(2.0 * pts[:, :1]) * torch.cos(1.5 * pts[:, 1:2]) + 0.3 * pts[:, 2:3]
    opt = torch.optim.Adam([*grid.parameters(), *head.parameters()], lr=2e-2)
    first = None
    for _ in range(200):
        loss = torch.mean((head(grid(pts)) - target) ** 2)
        opt.zero_grad()
        loss.backward()
        opt.step()
        first = loss.item() if first is None else first
    assert grid.table.grad is not None and grid.table.grad.abs().sum() > 0
    assert loss.item() < 0.02 * first, (first, loss.item())


def test_table_memory_limit_names_the_bytes():
    assert check_table(levels=2, features=2, base_resolution=4, per_level_scale=2.0,
                       log2_table=8) == 4 * 2 * (125 + 256)
    with pytest.raises(InvalidInputError, match=r"needs \d+ bytes .*accepted: at most"):
        check_table(levels=32, features=8, base_resolution=16, per_level_scale=1.5,
                    log2_table=30)
    with pytest.raises(InvalidInputError, match="levels=0"):
        check_table(levels=0, features=2, base_resolution=4, per_level_scale=2.0, log2_table=8)
