"""Texel arrays of transfer textures: dilation, lookups, storage and GL layer packing.

Layout: a texture set is ``(S, R, R, C)``: S textures of R × R texels with C channels, row j
holding v-texel j (GL's first texture row is t = 0), column i holding u-texel i.
"""

from __future__ import annotations

import numpy as np

from prtbench.api.errors import InvalidInputError

#: 8-neighbourhood offsets (dy, dx): a bilinear lookup in the texel containing a point reads
#: that texel and some of these neighbours.
NEIGHBOURS = [(dy, dx) for dy in (-1, 0, 1) for dx in (-1, 0, 1) if (dy, dx) != (0, 0)]

FLOAT16_MAX = float(np.finfo(np.float16).max)


def dilate(values: np.ndarray, filled: np.ndarray, chart: np.ndarray, *, rings: int,
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Grow each texture's filled texels by ``rings`` rings (PRTT Algorithm 1, line 9).

    Each ring gives every empty texel next to filled ones (8-neighbourhood) the mean of those
    neighbours. Neighbours from different charts are never mixed: the texel takes the mean of
    its neighbours in the lowest-numbered adjacent chart, and joins that chart.

    Parameters
    ----------
    values : ndarray, shape (S, R, R, C)
    filled : ndarray, shape (S, R, R), bool
    chart : ndarray, shape (S, R, R), int
        Chart id of filled texels (ignored elsewhere).
    rings : int
        Dilation rings (0 returns copies).

    Returns
    -------
    values, filled, chart : new arrays, same shapes.
    """
    values = np.array(values, copy=True)
    filled = np.array(filled, dtype=bool, copy=True)
    chart = np.where(filled, chart, -1).astype(np.int64)
    s, r = filled.shape[0], filled.shape[1]
    flat_v = values.reshape(s * r * r, -1)
    flat_f = filled.reshape(-1)
    flat_c = chart.reshape(-1)
    never = np.iinfo(np.int64).max
    for _ in range(int(rings)):
        grown = np.zeros_like(filled)
        for dy, dx in NEIGHBOURS:  # empty texels with a filled neighbour (no wrap-around)
            grown[:, max(dy, 0):r + min(dy, 0), max(dx, 0):r + min(dx, 0)] |= \
                filled[:, max(-dy, 0):r + min(-dy, 0), max(-dx, 0):r + min(-dx, 0)]
        todo = np.flatnonzero(grown.reshape(-1) & ~flat_f)
        if len(todo) == 0:
            break
        t_s, rest = np.divmod(todo, r * r)
        t_y, t_x = np.divmod(rest, r)
        neighbours = []
        best = np.full(len(todo), never)
        for dy, dx in NEIGHBOURS:
            y, x = t_y + dy, t_x + dx
            inside = (y >= 0) & (y < r) & (x >= 0) & (x < r)
            index = (t_s * r + np.clip(y, 0, r - 1)) * r + np.clip(x, 0, r - 1)
            ok = inside & flat_f[index]
            best = np.where(ok, np.minimum(best, flat_c[index]), best)
            neighbours.append((index, ok))
        total = np.zeros((len(todo), flat_v.shape[1]), np.float64)
        count = np.zeros(len(todo))
        for index, ok in neighbours:
            use = ok & (flat_c[index] == best)
            total[use] += flat_v[index[use]]
            count[use] += 1
        flat_v[todo] = (total / count[:, None]).astype(flat_v.dtype)
        flat_f[todo] = True
        flat_c[todo] = best
        filled = flat_f.reshape(filled.shape)
    return values, filled, flat_c.reshape(chart.shape).astype(np.int32)


def texel_lookup(texture: np.ndarray, texture_set: np.ndarray, uv: np.ndarray, *,
                 filtering: str = "bilinear") -> np.ndarray:
    """Sample textures like GL's ``texture()`` with CLAMP_TO_EDGE (numpy, float64).

    Parameters
    ----------
    texture : ndarray, shape (S, R, R, C)
    texture_set : ndarray, shape (N,), int
    uv : ndarray, shape (N, 2)
    filtering : {"bilinear", "nearest"}

    Returns
    -------
    ndarray, shape (N, C), float64
    """
    r = texture.shape[1]
    s = np.asarray(texture_set, np.int64)
    if filtering == "nearest":
        i = np.clip(np.floor(uv[:, 0] * r), 0, r - 1).astype(np.int64)
        j = np.clip(np.floor(uv[:, 1] * r), 0, r - 1).astype(np.int64)
        return texture[s, j, i].astype(np.float64)
    x = uv[:, 0] * r - 0.5
    y = uv[:, 1] * r - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    x0, y0 = x0.astype(np.int64), y0.astype(np.int64)
    xa, xb = np.clip(x0, 0, r - 1), np.clip(x0 + 1, 0, r - 1)
    ya, yb = np.clip(y0, 0, r - 1), np.clip(y0 + 1, 0, r - 1)

    def at(yy, xx):
        return texture[s, yy, xx].astype(np.float64)

    return ((1 - fx) * (1 - fy) * at(ya, xa) + fx * (1 - fy) * at(ya, xb)
            + (1 - fx) * fy * at(yb, xa) + fx * fy * at(yb, xb))


def footprint_texels(texture_set: np.ndarray, uv: np.ndarray, resolution: int, *,
                     filtering: str = "bilinear") -> np.ndarray:
    """Flat indices ``(s·R + j)·R + i`` of every texel a lookup at ``uv`` reads, (N, 4) or (N, 1)."""
    r = int(resolution)
    s = np.asarray(texture_set, np.int64)[:, None]
    if filtering == "nearest":
        i = np.clip(np.floor(uv[:, 0] * r), 0, r - 1).astype(np.int64)[:, None]
        j = np.clip(np.floor(uv[:, 1] * r), 0, r - 1).astype(np.int64)[:, None]
        return (s * r + j) * r + i
    x0 = np.floor(uv[:, 0] * r - 0.5).astype(np.int64)
    y0 = np.floor(uv[:, 1] * r - 0.5).astype(np.int64)
    xs = np.clip(np.stack([x0, x0 + 1, x0, x0 + 1], 1), 0, r - 1)
    ys = np.clip(np.stack([y0, y0, y0 + 1, y0 + 1], 1), 0, r - 1)
    return (s * r + ys) * r + xs


def to_storage(values: np.ndarray, storage: str, *, what: str) -> np.ndarray:
    """``values`` as float16 or float32; values float16 cannot hold are an error, never Inf.

    Raises
    ------
    InvalidInputError
        On non-finite values, or on float16 storage of a value beyond ±65504.
    """
    values = np.asarray(values)
    if not np.all(np.isfinite(values)):
        raise InvalidInputError(f"{what} contains NaN/Inf; accepted: finite values")
    if storage == "float32":
        return values.astype(np.float32)
    if storage != "float16":
        raise InvalidInputError(f"storage '{storage}'; accepted: float16, float32")
    peak = float(np.max(np.abs(values))) if values.size else 0.0
    if peak > FLOAT16_MAX:
        raise InvalidInputError(
            f"{what} reaches {peak:.6g}, outside float16's finite range (±{FLOAT16_MAX:.0f}); "
            "accepted: storage=float32 for this scene and light")
    return values.astype(np.float16)


def layer_count(channels: int) -> int:
    """RGBA layers holding ``channels`` values per texel: ceil(channels / 4)."""
    return -(-int(channels) // 4)


def rgba_layers(texture: np.ndarray) -> np.ndarray:
    """(S, R, R, C) → (S·L, R, R, 4) RGBA layers, zero-padded, texture-major (layer s·L + g)."""
    s, r, _, c = texture.shape
    layers = layer_count(c)
    padded = np.zeros((s, r, r, layers * 4), texture.dtype)
    padded[..., :c] = texture
    return np.ascontiguousarray(padded.reshape(s, r, r, layers, 4).transpose(0, 3, 1, 2, 4)
                                .reshape(s * layers, r, r, 4))
