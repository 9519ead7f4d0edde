"""``prtbench table volume``: the sweep, the geometric leak masks, and a small end-to-end run."""

from __future__ import annotations

import csv

import numpy as np

import methods.irradiance_volume.method as iv  # registers "irradiance-volume"
from prtbench.api.method import METHODS
from prtbench.scene.registry import get_scene
from prtbench.transport.raytrace import Tracer
from reproductions import table_volume as tv


def test_cells_sweep_resolutions_and_registered_baselines():
    cells = tv.TABLE.cells("quick")
    volume = [(c.scene, c.overrides["resolution"]) for c in cells if c.method == "irradiance-volume"]
    assert volume == [(s, n) for s in ("room", "plants") for n in (4, 8, 16, 32)]
    baselines = {(c.scene, c.method) for c in cells if c.method != "irradiance-volume"}
    expected = [m for m in ("vertex", "texture-tpfl") if m in METHODS]
    assert "vertex" in expected
    assert baselines == {(s, m) for s in ("room", "plants") for m in expected}
    assert all(c.variant == "diffuse" and c.light is None and c.reference == "path" for c in cells)


def test_leak_masks_select_walls_and_the_floor_under_the_table():
    scene = get_scene("room")
    view, width, height = scene.trajectory.views[10], 128, 96
    masks = tv.leak_masks(scene, view, width, height)
    walls, under = masks["walls"], masks["under_table"]
    assert walls.sum() > 500 and under.sum() > 20
    assert not (walls & under).any() and np.array_equal(masks["leak"], walls | under)
    # Check the selected hit points against the room's known geometry (builder constants).
    origins, dirs = view.primary_rays(width, height)
    hits = Tracer.from_scene(scene).first_hit(origins.reshape(-1, 3), dirs.reshape(-1, 3))
    points = (origins.reshape(-1, 3) + dirs.reshape(-1, 3) * hits.t[:, None].astype(np.float64))
    on_wall = points[walls.reshape(-1)]
    half = 2.5  # the walls' inner faces are at x = -2.5 and z = -2.5; their tops at y = 2.6
    assert np.all((on_wall[:, 0] < -half + 1e-3) | (on_wall[:, 2] < -half + 1e-3)
                  | (on_wall[:, 1] > 2.6 - 1e-3))
    below = points[under.reshape(-1)]
    # Table top 1.5 × 0.9 centred at (0, ·, −0.4), 0.75 high; floor at 0, rug 0.012 thick.
    assert np.all((np.abs(below[:, 0]) <= 0.75 + 1e-3) & (below[:, 2] >= -0.85 - 1e-3)
                  & (below[:, 2] <= 0.05 + 1e-3) & (below[:, 1] < 0.013))
    # A scene without walls or a table has no leak pixels.
    plants = get_scene("plants")
    assert not tv.leak_masks(plants, plants.trajectory.views[0], 32, 24)["leak"].any()


class _RoomOnly(tv.VolumeTable):
    """The room's coarsest and a finer volume plus vertex PRT: the table's path, but small."""

    def cells(self, profile):
        return [c for c in super().cells(profile)
                if c.scene == "room" and c.label["N"] in (0, 4, 16) and c.method in
                ("irradiance-volume", "vertex")]


def test_small_table_from_the_results_store(tmp_path):
    from prtbench.bench.reproduction import run_table
    from prtbench.store.results import load

    results = tmp_path / "results.sqlite"
    md, csv_path = run_table(_RoomOnly(), profile="smoke", results_path=results,
                             reports_dir=tmp_path, progress=False)
    with open(csv_path) as fh:
        rows = list(csv.DictReader(fh))
    assert [(r["scene"], r["method"], r["N"]) for r in rows] == [
        ("room", "irradiance-volume", "4"), ("room", "irradiance-volume", "16"), ("room", "vertex", "—")]
    by_n = {r["N"]: r for r in rows}
    for n in (4, 16):
        expected = iv.memory_closed_form(resolution=n, sh_bands=3, precision="float32") / 2**20
        assert float(by_n[str(n)]["memory MiB"]) == expected
    leak = {n: float(r["leak MAE (room)"]) for n, r in by_n.items()}
    assert all(0.0 < v < 1.0 for v in leak.values()), leak
    # Probes 1.3 m apart (N = 4) bleed the sky under the table and across the walls far more
    # than probes 0.35 m apart (N = 16); measured 0.117 against 0.074 at this size.
    assert leak["4"] > leak["16"] * 1.2, leak
    # The PSNR column is the stored rows' mean, nothing recomputed.
    stored = load(results)
    assert float(by_n["16"]["PSNR masked (dB)"]) == float(
        stored[stored["config"].str.contains('"resolution": 16')]["metric_psnr_masked"].mean())
    text = md.read_text()
    assert "no paper numbers" in text
    assert all(r["GL renderer"] == stored["renderer"].iloc[0] and r["timing"] for r in rows)
