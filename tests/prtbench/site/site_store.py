"""A small results store for the site tests: a smoke sweep (three configurations of two
methods on plants) and the smoke tessellation table, measured in the test session's cache,
and (:func:`add_protocol_rows`) stored rows in two more panels of the ranking protocol."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

from prtbench.api import config as config_mod
from prtbench.api.method import METHODS
from prtbench.bench.job import Job
from prtbench.bench.reproduction import TABLES, run_table
from prtbench.store.results import ResultsStore
from prtbench.tradeoff.sweep import run_cells

CELLS = [Job(method="vertex", scene="plants", light="sky", label={"sh_bands": b},
              overrides={"sh_bands": b}) for b in (2, 3)] + \
        [Job(method="irradiance-volume", scene="plants", light="sky", label={})]


def make_store(folder: Path, *, table: bool = True) -> Path:
    """The store at ``folder/store.sqlite`` (sweep cells, then the tessellation table)."""
    path = folder / "store.sqlite"
    outcome = run_cells(CELLS, profile="smoke", results_path=path, workers=0, progress=False)
    assert [c.status for c in outcome.results] == ["done"] * len(CELLS), outcome
    if table:
        run_table(TABLES.get("tessellation"), profile="smoke", results_path=path,
                  reports_dir=folder / "reports", progress=False)
    return path


#: Stored stability rows for the site tests, one per outcome class (and an imported one).
STABILITY_ROWS = [
    {"method": "vertex", "case": "moderate", "group": "moderate", "outcome": "ok",
     "reason": "the moderate setting", "scene": "sphere-over-plane", "psnr_masked": 31.25,
     "flip_masked": 0.0625, "precompute_s": 1.5, "peak_rss_bytes": 3 * 2**20, "load_1m": 0.5},
    {"method": "vertex", "case": "sh_bands=1", "group": "knob", "outcome": "degraded",
     "reason": "masked PSNR 16 dB vs 31 moderate", "advice": "use 3-5 bands",
     "psnr_masked": 16.125, "psnr_vs_moderate": 17.5, "overflow": 0},
    {"method": "vertex", "case": "scale=1e-04", "group": "scene", "outcome": "refused",
     "reason": "scene diagonal 0.000585; accepted: 0.00894..1e+06"},
    {"method": "vertex", "case": "light=black", "group": "light", "outcome": "failed",
     "reason": "NaN in the image", "imported_from": "table-stability.csv sha256:0123456789ab"},
]


def add_stability(path: Path) -> None:
    """Store :data:`STABILITY_ROWS` as one complete smoke stability run in ``path``."""
    from prtbench.stability.matrix import TABLE
    from prtbench.store import measurements

    run_id = measurements.new_run_id()
    measurements.record(TABLE, STABILITY_ROWS, results_path=path, run_id=run_id, profile="smoke",
                        renderer="llvmpipe", device="test machine")
    measurements.complete_report("table", TABLE, profile="smoke", run_id=run_id, members={},
                                 results_path=path)


#: Two more panels of plants under sky against a one-bounce reference (docs/PROTOCOL.md): a
#: two-view panel, and a fixed-view panel (a per-pixel method on the second camera of the
#: first), which also takes every other row on that camera.
PANEL_TWO_VIEWS = "plants/diffuse sky 64x48 views=2:0badc0de ref=path/b1/32spp"
PANEL_FIXED_VIEW = "plants/diffuse sky 64x48 views=1:feedface ref=path/b1/32spp"
CAMERAS = ({"eye": [0.0, 1.5, 4.0], "target": [0.0, 0.5, 0.0], "fov_y": 40.0},
           {"eye": [3.0, 1.5, 2.0], "target": [0.0, 0.5, 0.0], "fov_y": 40.0})
#: Display noise RMSE of those references: a 46 dB ceiling, above every PSNR below.
PROTOCOL_NOISE = 10.0 ** (-46.0 / 20.0)


@dataclasses.dataclass(frozen=True)
class ProtocolCell:
    """One configuration's stored rows in a protocol panel.

    ``views`` holds (view index, camera index in :data:`CAMERAS`, split, masked PSNR, half
    width of its interval); ``light_change_ms`` None: the method does no per-light work.
    """

    method: str
    overrides: dict
    panel: str
    frame_ms: float
    views: tuple
    light_change_ms: float | None = 1.5


PROTOCOL_CELLS = (
    # The sweep's two vertex configurations again: sh_bands=3 costs more for an error within
    # the intervals of sh_bands=2's (a tie, in both panels).
    ProtocolCell("vertex", {"sh_bands": 2}, PANEL_TWO_VIEWS, 5.0,
                 ((0, 0, "held-out", 24.0, 0.3), (1, 1, "held-out", 24.4, 0.3))),
    ProtocolCell("vertex", {"sh_bands": 3}, PANEL_TWO_VIEWS, 7.0,
                 ((0, 0, "held-out", 23.9, 0.3), (1, 1, "held-out", 24.3, 0.3))),
    # A baked bounce light: the fixed light class.
    ProtocolCell("texture-tp", {"bounces": 1}, PANEL_TWO_VIEWS, 12.0,
                 ((0, 0, "held-out", 28.0, 0.2), (1, 1, "held-out", 28.4, 0.2)),
                 light_change_ms=None),
    # A family of lights, fitted on the second view's light: that row is trained.
    ProtocolCell("data-driven", {}, PANEL_TWO_VIEWS, 9.0,
                 ((0, 0, "in-family", 26.0, 0.2), (1, 1, "trained", 35.0, 0.2))),
    # Pixels from the reference renderer: a diagnostic, never ranked however good.
    ProtocolCell("neural-wavelet", {"direct": "offline-reference"}, PANEL_TWO_VIEWS, 40.0,
                 ((0, 0, "held-out", 40.0, 0.1), (1, 1, "held-out", 40.2, 0.1))),
    # Measured only where it trained: left out.
    ProtocolCell("neural-wavelet", {}, PANEL_TWO_VIEWS, 30.0,
                 ((0, 0, "trained", 33.0, 0.2), (1, 1, "trained", 33.5, 0.2))),
    ProtocolCell("wavelet-image", {}, PANEL_FIXED_VIEW, 20.0,
                 ((0, 1, "held-out", 25.0, 0.2),)),
)


def protocol_config(cell: ProtocolCell) -> dict:
    """The full stored config of ``cell`` (its overrides on the smoke profile's config)."""
    cls = METHODS.get(cell.method)
    return config_mod.to_dict(cls.make_config(dict(cell.overrides), profile="smoke"))


def add_protocol_rows(path: Path) -> None:
    """Store :data:`PROTOCOL_CELLS` in ``path``, beside a stored vertex row of plants under
    sky (its scene parameters, renderer and code version), with run id ``protocol``."""
    store = ResultsStore(path)
    (base, *_) = [r for r in store.query(method="vertex", scene="plants", status="ok")
                  if r.config.get("sh_bands") == 2 and r.reference_kind == "path"]
    rows = []
    for cell in PROTOCOL_CELLS:
        cls = METHODS.get(cell.method)
        config = protocol_config(cell)
        parsed = config_mod.from_dict(cls.Config, config)
        breakdown = {"gpu: transfer": 4096 * (1 + len(cell.method)), "gpu: target": 12288}
        for view, camera, split, psnr, half in cell.views:
            rows.append(dataclasses.replace(
                base, config=config, method=cell.method, view=view,
                view_json=json.loads(json.dumps(CAMERAS[camera])), panel=cell.panel,
                light_class=cls.light_class_of(parsed), split=split, reference_bounces=1,
                reference_spp=32, reference_noise=PROTOCOL_NOISE,
                metrics={"psnr_masked": psnr, "ssim_masked": 0.9, "flip_masked": 0.05 + psnr / 1e3,
                         "psnr": psnr - 1.0},
                psnr_masked_lo=psnr - half, psnr_masked_hi=psnr + half,
                flip_masked_lo=None, flip_masked_hi=None, frame_ms=cell.frame_ms,
                frame_ms_p95=cell.frame_ms * 1.25, workers=1,
                frame_components={"gpu draw": cell.frame_ms * 0.75, "cpu relight": cell.frame_ms * 0.25},
                memory_breakdown=breakdown, memory_bytes=sum(breakdown.values()),
                light_change_ms=cell.light_change_ms, precompute_s=2.5, run_id="protocol",
                cell_key=f"protocol-{cell.method}-{view}", status="ok", status_reason=""))
    store.append(rows)
