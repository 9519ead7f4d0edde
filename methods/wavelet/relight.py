"""Shared by the wavelet methods: config checks, per-frame k-term relighting, host-clock timing.

A frame of Ng 2003 relighting (:class:`Relighter`): Haar-transform the light's cubemap, select
its k most important coefficients (the set changes with the light), and form the sparse product
with the stored transport of every point (vertex or texel). The lat-long → cubemap resampling
is per light and cached (it is a change of light format, like the SH projection that the SH
methods do not time either).
"""

from __future__ import annotations

import numpy as np

from prtbench.api.config import check_memory
from prtbench.api.errors import InvalidInputError
from prtbench.api.method import FrameTimes, wall_frame_times
from prtbench.transport.wavelet import haar
from prtbench.transport.wavelet.cubemap import check_resolution, light_cubemap
from prtbench.transport.wavelet.selection import select_terms
from prtbench.transport.wavelet.sparse import VALUE_BYTES, SparseTransport, row_dtype
from prtbench.transport.wavelet.transport import keep_count

SELECTIONS = ("magnitude", "area", "transport")
STORAGES = ("float32", "float16", "int8")
#: Memory of a chunk's ray buffers and Haar work arrays on top of the stored transport (bytes).
WORKING_BYTES = 512 << 20
#: Bytes per stored entry while the sparse transport is built: per-chunk int32 point and
#: coefficient and float32 value triples (12 B), their concatenation and sorted copies.
BUILD_BYTES_PER_ENTRY = 48


def check_wavelet_config(method: str, config, *, points: int, what: str) -> tuple[int, int]:
    """(coefficients per point, kept per point); one-line errors for bad values.

    Parameters
    ----------
    method : str
        Method name for messages.
    config
        A config with ``cubemap``, ``light_terms``, ``keep`` and ``storage``.
    points : int
        Points that get a transport (vertices or texels).
    what : str
        What the points are ("vertices", "texels").
    """

    n = check_resolution(config.cubemap, what="cubemap")
    m = 6 * n * n
    if config.light_terms > m:
        raise InvalidInputError(f"light_terms={config.light_terms} exceeds the {m} wavelet "
                                f"coefficients of a cubemap={n} (6·N²); accepted: 1..{m}")
    kept = keep_count(config.keep, m)
    entry = VALUE_BYTES[config.storage] + row_dtype(points).itemsize
    # At most points × kept stored entries, built from per-chunk triples and sorted once.
    need = points * kept * (entry + BUILD_BYTES_PER_ENTRY) + WORKING_BYTES
    check_memory(f"method '{method}' cubemap={n} keep={config.keep:g} ({kept} of {m} "
                 f"coefficients) on {points} {what}", need,
                 accepted="a smaller cubemap or keep")
    return m, kept


class Relighter:
    """Per-frame k-term relighting of a :class:`SparseTransport`.

    Parameters
    ----------
    transport : SparseTransport or None
        None where the product is formed elsewhere (a compressed transport, whose renderer
        uses only :meth:`select`).
    config
        ``cubemap``, ``light_terms`` and ``selection``.
    transport_weight : ndarray, shape (6N²,), optional
        The ``transport`` selection's weights, where they are not ``transport``'s own column
        means (e.g. those of a compressed transport's reconstruction).

    Attributes
    ----------
    weights : ndarray, shape (6N²,), float32, or None
        Per-coefficient weights of the selection rule (support solid angles for ``area``, mean
        |T| for ``transport``): resident, read every frame.
    last_terms : ndarray or None
        The coefficients selected in the last frame.
    """

    def __init__(self, transport: SparseTransport | None, config, *,
                 transport_weight: np.ndarray | None = None):

        self.transport = transport
        self.n, self.k, self.selection = config.cubemap, config.light_terms, config.selection
        if self.selection == "area":
            self.weights = haar.support_solid_angles(self.n).reshape(-1).astype(np.float32)
        elif self.selection == "transport":
            self.weights = (transport.column_mean_abs() if transport_weight is None
                            else np.asarray(transport_weight, np.float32).reshape(-1))
        else:
            self.weights = None
        self._cubes: dict[str, np.ndarray] = {}
        self.last_terms: np.ndarray | None = None

    def light_cube(self, light) -> np.ndarray:
        """(3, 6, N, N) texel-mean radiance of ``light`` (per light, not per frame)."""

        key = light.content_hash()
        if key not in self._cubes:
            self._cubes = {key: np.ascontiguousarray(
                np.moveaxis(light_cubemap(light, self.n), -1, 0))}
        return self._cubes[key]

    def select(self, light) -> tuple[np.ndarray, np.ndarray]:
        """The light's Haar coefficients (6N², 3) float64 and this frame's k terms (k,) int64:
        the per-frame work before the product."""

        coeffs = haar.forward(self.light_cube(light)).reshape(3, -1).T  # (6N², 3)
        rule = {"area": {"support": self.weights},
                "transport": {"transport_weight": self.weights}}.get(self.selection, {})
        terms = select_terms(coeffs, self.k, rule=self.selection, **rule)
        self.last_terms = terms
        return coeffs, terms

    def __call__(self, light) -> np.ndarray:
        """(P, 3) float32 Σ_{i in k} T_pi L_i for ``light``: the frame's CPU work."""
        coeffs, terms = self.select(light)
        return self.transport.relight(coeffs, terms).astype(np.float32)

    @property
    def nbytes(self) -> int:
        """Resident bytes: the sparse transport (if held) and the selection weights."""
        held = 0 if self.transport is None else self.transport.nbytes
        return int(held + (0 if self.weights is None else self.weights.nbytes))


def host_frame_times(ctx, draw, *, warmup: int, frames: int, renderer: str) -> FrameTimes:
    """Host clock around whole frames (``draw`` then glFinish): the CPU relighting is part of
    the frame, which a GPU timer query would not see."""
    if int(warmup) != warmup or warmup < 1 or int(frames) != frames or frames < 1:
        raise InvalidInputError(f"warmup={warmup!r}, frames={frames!r}; accepted: integers >= 1")
    def frame() -> None:
        draw()
        ctx.finish()

    return wall_frame_times(frame, warmup=warmup, frames=frames, renderer=renderer,
                            source="wall+finish")
