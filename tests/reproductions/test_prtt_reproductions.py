"""PRTT reproductions (thesis tables 3.1, 3.2, figures 3.4–3.6): sweeps, store-only formatting,
memory closed forms, and small end-to-end runs on ``plants`` in the smoke profile."""

from __future__ import annotations

import csv
import math
import sqlite3

import numpy as np
import pytest

import methods.texture  # noqa: F401 - registers texture-tp / texture-tpfl
from prtbench.api.errors import AssetMissingError
from prtbench.bench.reproduction import TABLES, run_table
from prtbench.render.prt_shading import gamma_entries, tpfl_buffer_data
from prtbench.scene.registry import get_scene
from prtbench.store.results import load
from reproductions import figure_3_4 as f34
from reproductions import plots, shared
from reproductions import table_3_1 as t31
from reproductions import table_3_2 as t32

PAPER_COLUMNS_31 = ["paper tris", "paper FPS", "paper TPFL/TP", "paper fragment/vertex"]


# --- sweeps ------------------------------------------------------------------------------------

def test_table_3_1_sweeps_four_methods_on_four_stand_ins_per_profile():
    methods = ["vertex-tp", "vertex-tpfl", "texture-tp", "texture-tpfl"]
    for profile, scenes in (("paper", ["dragon", "trm", "room", "plants"]),
                            ("quick", ["dragon-lo", "trm", "room", "plants"])):
        cells = t31.TABLE.cells(profile)
        assert [(c.scene, c.method) for c in cells] == [(s, m) for s in scenes for m in methods]
        assert all(c.variant == "glossy" and c.reference == "path" for c in cells)
        assert [c.label["paper_scene"] for c in cells[::4]] == ["Dragon", "TRM", "Room", "Plants"]
    assert all(c.views is None for c in t31.TABLE.cells("paper"))  # the profile's 30 views
    # TRM uses texture sets for the texture methods only (PRTT Fig. 3), the same scene for all.
    for profile, overrides, params in (
            ("paper", {"texture_sets": True, "texture_resolution": 512}, {}),
            ("quick", {"texture_sets": True}, {"resolution": "lo"})):
        trm = [c for c in t31.TABLE.cells(profile) if c.scene == "trm"]
        assert [dict(c.overrides) for c in trm] == [{}, {}, overrides, overrides]
        assert all(dict(c.scene_params) == params for c in trm)
    # The paper's table, copied once: TPFL/TP on Plants' vertex shader is 2597.6 / 363.2.
    assert t31.PAPER_FPS[("Plants", "vertex-tpfl")] / t31.PAPER_FPS[("Plants", "vertex-tp")] == \
        pytest.approx(7.152, abs=1e-3)
    assert len(t31.PAPER_FPS) == 16


# --- closed forms ------------------------------------------------------------------------------

def test_memory_closed_forms_match_the_papers_magnitudes():
    # McKenzie: a 1024² texture of 25×25 float32 matrices is 2.62e9 B (the paper's "2.5GB").
    assert t32.mckenzie_texture_bytes(1024, 5) == 1024**2 * 625 * 4 == 2_621_440_000
    # Ours: 25 coefficients in 7 RGBA float32 layers (112 MiB) + the 25×25 RGB TPFL matrix.
    tpfl = len(tpfl_buffer_data(np.zeros((25, 3)), 5))
    assert tpfl in (625 * 3 * 4, 625 * 4 * 4)  # packed, or one std140 vec4 per entry
    assert t32.transfer_texture_bytes(1024, 5) == 1024**2 * 7 * 4 * 4 + tpfl
    assert t32.transfer_texture_bytes(1024, 5, with_tpfl=False) / 2**20 == 112.0
    assert t32.transfer_texture_bytes(512, 5, sets=4, storage="float16", with_tpfl=False) == \
        4 * 512**2 * 7 * 4 * 2
    # One bounce texture holds RGB H: 75 values in 19 RGBA layers.
    assert t32.transfer_texture_bytes(256, 5, bounces=1, with_tpfl=False) == 256**2 * (7 + 19) * 16
    # Sloan per vertex on the full dragon: 436,582 vertices × 625 × 4 B ≈ 1.09 GB.
    assert t32.sloan_vertex_bytes(436_582, 5) == 1_091_455_000
    assert t32.ng_vertex_bytes(1000, 5, with_gamma=False) == 100_000
    assert t32.gamma_bytes(5) == 8 * len(gamma_entries(5))


def test_sloan_refusal_names_the_knob_or_the_gl_limit(monkeypatch):
    from prtbench.api.method import METHODS

    scene = get_scene("plants", variant="glossy")
    sloan = METHODS.get("sloan-matrix")
    assert t32.sloan_refusal(scene, sloan.make_config(profile="smoke")) is None
    refused = t32.sloan_refusal(scene, sloan.make_config({"max_bytes": 1000}, profile="smoke"))
    assert refused.startswith("refused by the method") and "max_bytes" in refused
    monkeypatch.setattr(t32, "gl_storage_block_limit", lambda: 1 << 20)
    too_big = t32.sloan_refusal(scene, sloan.make_config(profile="smoke"))
    assert "GL_MAX_SHADER_STORAGE_BLOCK_SIZE = 1 MiB" in too_big


# --- small end-to-end runs ---------------------------------------------------------------------

class _Plants31(t31.Table31):
    def cells(self, profile):
        return [c for c in super().cells(profile)
                if c.scene == "plants" and c.method in ("vertex-tpfl", "texture-tpfl")]


class _Plants32(t32.Table32):
    def cells(self, profile):
        return [c for c in super().cells(profile)
                if c.scene == "plants" and c.method in ("vertex-tp", "texture-tpfl")]


def _only_plants(monkeypatch):
    # Table 3.2's sweep builds every stand-in scene to ask whether Sloan matrices fit; the
    # asset-backed ones (dragon-lo, trm) are not fetched on a fresh machine.
    choices = t32.scene_choices
    monkeypatch.setattr(t32, "scene_choices",
                        lambda profile: tuple(c for c in choices(profile) if c.scene == "plants"))


def _csv(path):
    with open(path) as fh:
        reader = csv.reader(fh)
        header = next(reader)
        return header, [dict(zip(header, row)) for row in reader]


def test_table_3_1_from_the_store_with_paper_columns_apart(tmp_path):
    results = tmp_path / "results.sqlite"
    md, csv_path = run_table(_Plants31(), profile="smoke", results_path=results,
                             reports_dir=tmp_path, progress=False)
    header, rows = _csv(csv_path)
    # Paper columns form one block at the end, and only they are headed "paper".
    assert header[-len(PAPER_COLUMNS_31):] == PAPER_COLUMNS_31
    assert not any("paper" in h for h in header[:-len(PAPER_COLUMNS_31)])
    assert [r["method"] for r in rows] == ["vertex-tpfl", "texture-tpfl"]
    stored = load(results)
    for row in rows:
        part = stored[stored["method"] == row["method"]]
        ours = float(row["FPS (ours)"])
        assert math.isfinite(ours) and ours > 0
        assert ours == pytest.approx(1000.0 / float(np.median(part["frame_ms"])), rel=1e-3)
        assert float(row["PSNR masked (dB)"]) == pytest.approx(
            float(part["metric_psnr_masked"].mean()), rel=1e-9)
        assert 0 < float(row["SSIM masked"]) <= 1 and 0 <= float(row["FLIP masked"]) <= 1
        assert int(row["our tris"]) == int(part["scene_triangles"].iloc[0]) == 16890
        assert row["timing"] == part["timing_source"].iloc[0]
    assert float(rows[0]["paper FPS"]) == 2597.6 and float(rows[1]["paper FPS"]) == 168.3
    # Fragment/vertex for TPFL: ours is the ratio of our two FPS, the paper's of its two.
    assert float(rows[1]["fragment/vertex (ours)"]) == pytest.approx(
        float(rows[1]["FPS (ours)"]) / float(rows[0]["FPS (ours)"]), rel=1e-3)
    assert float(rows[1]["paper fragment/vertex"]) == pytest.approx(168.3 / 2597.6, rel=1e-6)
    text = md.read_text()
    assert "not comparable to an RTX 3090" in text and "Plants: our `plants`" in text
    assert str(stored["renderer"].iloc[0]) in text

    # The formatter reads nothing but the store: without the rows there is no table.
    with sqlite3.connect(results) as conn:
        conn.execute("DELETE FROM renders")
    frame = load(results)
    assert len(frame) == 0
    assert t31.TABLE.format(frame, profile="smoke")[1] == []


def test_table_3_2_measured_memory_equals_the_closed_form_exactly(tmp_path, monkeypatch):
    _only_plants(monkeypatch)
    results = tmp_path / "results.sqlite"
    _, csv_path = run_table(_Plants32(), profile="smoke", results_path=results,
                            reports_dir=tmp_path, progress=False)
    header, rows = _csv(csv_path)
    assert header[-2:] == ["paper tris", "paper"]
    assert not any("paper" in h for h in header[:-2])
    by_scheme = {r["method"]: r for r in rows}
    assert list(by_scheme) == ["sloan-matrix", "vertex-tp", "—", "texture-tpfl"]
    scene = get_scene("plants", variant="glossy")
    n = 4  # smoke profile's SH bands for both methods
    expected = {
        # V·n²·4 transfer floats + the Γ list the TP shader reads (8 B per non-zero).
        "vertex-tp": scene.n_vertices * n * n * 4 + 8 * len(gamma_entries(n)),
        # 128² texels × ⌈16/4⌉ RGBA float32 layers + the 16×16 RGB TPFL matrix as uploaded.
        "texture-tpfl": 128 * 128 * 4 * 4 * 4 + len(tpfl_buffer_data(np.zeros((n * n, 3)), n)),
    }
    stored = load(results)
    for method, size in expected.items():
        row = by_scheme[method]
        assert int(row["measured bytes"]) == size == int(row["closed form bytes"])
        assert float(row["measured / closed form"]) == 1.0 and row["status"] == "measured"
        assert int(stored[stored["method"] == method]["memory_bytes"].iloc[0]) == size
    assert by_scheme["texture-tpfl"]["paper"] == "100MB" and by_scheme["vertex-tp"]["paper"] == "2.5MB"
    # Closed form only: Sloan was not run in this sweep, McKenzie never is.
    assert by_scheme["sloan-matrix"]["measured bytes"] == "—"
    assert int(by_scheme["sloan-matrix"]["closed form bytes"]) == scene.n_vertices * n**4 * 4
    assert by_scheme["—"]["status"].startswith("closed form only")
    assert int(by_scheme["—"]["closed form bytes"]) == 128**2 * n**4 * 4


def test_missing_assets_fail_before_anything_runs(tmp_path, monkeypatch):
    from prtbench.cli import main

    monkeypatch.setenv("PRTBENCH_ASSETS", str(tmp_path / "no-assets"))
    results = tmp_path / "results.sqlite"
    with pytest.raises(AssetMissingError, match="prtbench assets fetch"):
        run_table(t31.TABLE, profile="quick", results_path=results, reports_dir=tmp_path,
                  progress=False)
    if "3.2" not in TABLES:
        TABLES.add_lazy("3.2", "reproductions.table_3_2:TABLE")
    assert main(["table", "3.2", "--profile", "quick", "--results", str(results),
                 "--reports", str(tmp_path)]) == 2
    assert not list(tmp_path.glob("table-*")) and not results.exists()


def test_figure_3_4_writes_a_labelled_png_from_stored_runs(tmp_path, monkeypatch):
    from prtbench.io import imageio

    monkeypatch.setitem(f34.SCENES, "smoke", ("plants",))
    monkeypatch.setattr(f34, "COLUMNS", (("vertex TPFL", "vertex-tpfl", False),
                                         ("texture TPFL", "texture-tpfl", False)))
    results = tmp_path / "results.sqlite"
    png, md = f34.FIGURE.make(profile="smoke", reports_dir=tmp_path, results_path=results,
                              progress=False)
    image = imageio.read_png(png)
    # One row of 3 panels (2 methods + reference) of 64×48, magnified 3× (nearest neighbour) to
    # at least plots.MIN_PANEL_PX wide, labels above and beside.
    zoom = -(-plots.MIN_PANEL_PX // 64)
    assert image.shape[1] > 3 * 64 * zoom and image.shape[0] > 48 * zoom
    stored = load(results)
    assert sorted(stored["method"]) == ["texture-tpfl", "vertex-tpfl"]
    text = md.read_text()
    for _, row in stored.iterrows():  # caption numbers are the stored ones
        assert f"{1000.0 / row['frame_ms']:.4g}" in text and row["run_id"] in text


def test_grid_and_wireframe_overlay_geometry(tmp_path):
    from prtbench.io import imageio

    a = np.full((10, 20, 3), 0.5, np.float32)
    b = np.zeros((10, 20, 3), np.float32)
    b[..., 0] = 1.0  # pure red: no label or background pixel has this colour
    png = plots.panel_grid(tmp_path / "grid.png", [[a, None], [b, b]], titles=[["x", "y"]])
    out = imageio.read_png(png)
    zoom = -(-plots.MIN_PANEL_PX // 20)
    red = (out[..., 0] > 0.99) & (out[..., 1] < 0.01) & (out[..., 2] < 0.01)
    # Two red panels drawn at zoom × their pixel size (± a line of pixels at the axes' edges).
    assert abs(int(red.sum()) - 2 * 10 * 20 * zoom**2) <= 2 * 2 * (10 + 20) * zoom
    rows, cols = np.nonzero(red)
    assert cols.max() - cols.min() + 1 > 2 * 20 * zoom  # side by side, with a gap
    grey = np.all(np.abs(out - 0.5) < 1.5 / 255, axis=-1)
    assert abs(int(grey.sum()) - 10 * 20 * zoom**2) <= 2 * (10 + 20) * zoom  # the blank cell is white
    # Reproducible bytes: no software version or timestamp text chunk in the PNG.
    assert png.read_bytes() == plots.panel_grid(tmp_path / "again.png", [[a, None], [b, b]],
                                                 titles=[["x", "y"]]).read_bytes()
    data, chunks, at = png.read_bytes(), [], 8
    while at < len(data):
        size = int.from_bytes(data[at:at + 4], "big")
        chunks.append(data[at + 4:at + 8])
        at += 12 + size
    assert chunks[0] == b"IHDR" and chunks[-1] == b"IEND"
    assert not {b"tEXt", b"iTXt", b"zTXt", b"tIME"} & set(chunks), chunks
    panel = np.full((40, 80, 3), 0.5, np.float32)
    edges = np.zeros((80, 160), np.float32)
    edges[46, :] = 1.0  # one horizontal edge at 2×: half of panel row 23's coverage
    out = shared.wireframe_overlay(panel, edges, crop=(0.5, 0.75, 0.25, 0.75), opacity=1.0)
    assert out.shape == panel.shape
    inside = np.asarray(shared.WIRE) * 0.5 + 0.5 * 0.5  # half-covered pixels blend half-way
    assert np.allclose(out[23, 21:59], inside)
    assert np.allclose(out[23, :20], 0.5) and np.allclose(out[23, 60:], 0.5)  # outside the box
    assert np.allclose(out[20, 20:60], shared.INSET_BORDER)  # the box's outline
    assert np.allclose(out[22, 21:59], 0.5)  # no edge, inside the box: the render unchanged
    with pytest.raises(ValueError):
        shared.wireframe_overlay(panel, edges[:, :100], crop=(0.5, 0.75, 0.25, 0.75))


def test_wireframe_edges_of_a_two_triangle_plane():
    scene = get_scene("plane")
    view = scene.trajectory.views[0]
    edges, geometry = shared.render_wireframe(scene, view, width=96, height=72)
    assert edges.shape == geometry.shape == (72, 96)
    assert geometry.any()
    # Two triangles: edges are a thin fraction of the covered pixels, and only where covered.
    assert 0.0 < edges[geometry].mean() < 0.25 and edges[~geometry].max() == 0.0


def test_table_3_2_from_the_store_quotes_the_stored_gl_limit(tmp_path, monkeypatch):
    _only_plants(monkeypatch)
    results = tmp_path / "results.sqlite"
    first, second = tmp_path / "measured", tmp_path / "rebuilt"
    run_table(_Plants32(), profile="smoke", results_path=results, reports_dir=first,
              progress=False)
    measured = t32.gl_storage_block_limit()
    assert measured > 0
    # Rebuilt on "another machine" (a GL with a 1 MiB limit): the report still quotes the
    # limit the sweep ran under, and the Sloan status does not change.
    monkeypatch.setattr(t32, "gl_storage_block_limit", lambda: 1 << 20)
    run_table(_Plants32(), profile="smoke", results_path=results, reports_dir=second,
              progress=False, from_store=True)
    for name in ("table-3.2.md", "table-3.2.csv"):
        assert (second / name).read_bytes() == (first / name).read_bytes()
    assert f"hold at most {measured / 2**20:.0f} MiB" in (first / "table-3.2.md").read_text()
