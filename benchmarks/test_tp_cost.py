"""Growth of the per-vertex triple-product cost with the SH band count (PRTT §3, §6).

The sparse Γ has O(k^{5/2}) non-zeros for k = n² coefficients, so a triple product costs
O(k^{5/2}) per shading point (the PRTT paper quotes O(k^{5/2})–O(k³)); TPFL folds the light in
once per frame and costs k² per point; Sloan's matrices cost k² per point too but store k²
floats per vertex. This times ``vertex-tp``, ``vertex-tpfl`` and ``sloan-matrix`` frames for
n = 3 … 8 on one scene in one run and prints ratios to n = 3 and the fitted exponent of k.
Not collected by the default test run; run with

    .venv/bin/pytest benchmarks/test_tp_cost.py --benchmark-enable -s
    .venv/bin/python benchmarks/test_tp_cost.py          # same table, no pytest

Timings on llvmpipe (a CPU rasteriser; no GPU in this project's CI) are meaningful only as
ratios within one run; it asserts nothing about timing.
"""

from __future__ import annotations

import math

import numpy as np

import methods.vertex.glossy  # noqa: F401  (registers the methods)
from prtbench.api.errors import PrtbenchError
from prtbench.api.method import METHODS, load_or_precompute
from prtbench.render import prt_shading as _triple
from prtbench.scene.registry import get_scene
from prtbench.transport.lights import get_light

BANDS = (3, 4, 5, 6, 7, 8)
METHOD_NAMES = ("vertex-tp", "vertex-tpfl", "sloan-matrix")
WIDTH, HEIGHT = 160, 120  # small: the per-vertex work dominates the frame


def _scene():
    try:
        return get_scene("plants", variant="glossy").with_views(1)
    except (PrtbenchError, ImportError):  # assets not fetched
        return get_scene("sphere-over-plane", variant="glossy", plane_subdivisions=64).with_views(1)


def measure(*, frames: int = 10, warmup: int = 2) -> dict:
    """Median frame ms per (method, bands); None where a method's buffer does not fit."""
    scene = _scene()
    light = get_light("sky")
    view = scene.trajectory.views[0]
    table: dict = {"scene": scene.name, "vertices": scene.n_vertices, "renderer": None,
                   "source": None, "ms": {}}
    for name in METHOD_NAMES:
        cls = METHODS.get(name)
        for bands in BANDS:
            config = cls.make_config({"sh_bands": bands, "rays_per_point": 16})
            try:
                cls.validate(scene, config)
                artifact = load_or_precompute(cls, scene, config, progress=False)
                renderer = cls.renderer(scene, artifact, config, width=WIDTH, height=HEIGHT)
            except PrtbenchError as exc:  # e.g. Sloan matrices over the SSBO size limit
                print(f"[tp cost] {name} n={bands}: skipped ({exc})")
                table["ms"][name, bands] = None
                continue
            try:
                times = renderer.frame_time(view, light, warmup=warmup, frames=frames)
            finally:
                renderer.release()
            table["ms"][name, bands] = times.median_ms
            table["renderer"], table["source"] = times.renderer, times.source
    return table


def format_table(table: dict) -> str:
    lines = [f"[tp cost] scene {table['scene']} ({table['vertices']} vertices), "
             f"{WIDTH}x{HEIGHT}, {table['renderer']}, timing: {table['source']}",
             "n  k   Γ nnz  " + "  ".join(f"{m:>12} ms  ratio" for m in METHOD_NAMES)]
    for bands in BANDS:
        cells = []
        for name in METHOD_NAMES:
            ms, base = table["ms"].get((name, bands)), table["ms"].get((name, BANDS[0]))
            cells.append(f"{ms:15.2f} {ms / base:6.2f}" if ms and base else f"{'—':>15} {'—':>6}")
        lines.append(f"{bands}  {bands * bands:2d} {len(_triple.gamma_entries(bands)):7d}  "
                     + "  ".join(cells))
    k = np.array([b * b for b in BANDS], float)
    nnz = np.array([len(_triple.gamma_entries(b)) for b in BANDS], float)
    lines.append(f"Γ non-zeros grow as k^{np.polyfit(np.log(k), np.log(nnz), 1)[0]:.2f}")
    for name in METHOD_NAMES:
        pairs = [(b * b, table["ms"][name, b]) for b in BANDS if table["ms"].get((name, b))]
        if len(pairs) >= 2:
            slope = np.polyfit(np.log([p[0] for p in pairs]), np.log([p[1] for p in pairs]), 1)[0]
            lines.append(f"{name}: frame time grows as k^{slope:.2f} over n = "
                         f"{int(math.sqrt(pairs[0][0]))}..{int(math.sqrt(pairs[-1][0]))} "
                         "(raw frame times, fixed raster cost included)")
    return "\n".join(lines)


def test_tp_cost_growth(benchmark):
    table = measure()
    text = format_table(table)
    print("\n" + text)
    benchmark.extra_info.update({f"{m}-n{b}": v for (m, b), v in table["ms"].items()})
    benchmark.extra_info["renderer"] = table["renderer"]
    benchmark.pedantic(lambda: None, rounds=1, iterations=1)


if __name__ == "__main__":
    print(format_table(measure()))
