"""The claims ledger (reproductions/claims, prtbench/bench/claims.py, `prtbench claims`).

The ledger's shape (≥ 45 claims, unique ids, five sources, a measure and a rule or a reason),
its rules on hand-made cases, and its verdicts on results stores built here with the rows and
report runs the reproductions store: reproduced, direction only, contradicted (explained and
unexplained), device-bound, not measurable here (and "not measured in this store" where the store
cannot answer). Then the command: its files, provenance, counts and one-line errors.
"""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest

from prtbench.api import config as config_mod
from prtbench.api.method import METHODS
from prtbench.bench import claims, claims_page
from prtbench.bench.claims import Estimate, Measured
from prtbench.bench.reproduction import FIGURES, TABLES
from prtbench.cli import main
from prtbench.store import measurements
from prtbench.store.results import ResultRow, ResultsStore
from reproductions.claims import SOURCES
from reproductions.claims.rules import (
    in_range,
    ratio_within,
    same_sign,
    within_tolerance,
)
from reproductions.table_3_1 import PAPER_FPS, PAPER_SCENES
from reproductions.table_3_2 import gamma_bytes, tpfl_bytes
from reproductions.table_4_1 import SCENES, VARIANTS
from reproductions.table_4_2 import SCENE_LABELS as SDF_LABELS
from reproductions.table_nw_common import label_key

LLVMPIPE = "llvmpipe (LLVM 15.0.6, 256 bits) / 4.5 (Core Profile) Mesa 22.3.6"
GPU = "NVIDIA GeForce RTX 3090/PCIe/SSE2"


@pytest.fixture(scope="module")
def ledger():
    return claims.all_claims()


def _by_id(assessments) -> dict:
    return {a.claim.id: a for a in assessments}


def _evaluate(store, ledger, *ids):
    chosen = [c for c in ledger if c.id in ids] if ids else list(ledger)
    return _by_id(claims.evaluate(chosen, results_path=store))


# --- the ledger -------------------------------------------------------------------------------

def test_the_ledger_has_45_claims_with_unique_ids_from_the_five_sources(ledger):
    assert claims.ledger_targets() == ["reproductions.claims:CLAIMS"]
    ids = [c.id for c in ledger]
    assert len(ids) >= 45 and len(set(ids)) == len(ids)
    assert {c.source for c in ledger} == set(SOURCES)  # every source, and only those five
    for c in ledger:
        assert c.quote and c.paper and c.section, c.id
        if c.report is not None:
            kind, name = c.kind_and_name
            assert name in (TABLES if kind == "table" else FIGURES).names(), c.id
        if c.not_measurable:
            continue
        assert c.measure is not None and c.rule is not None, c.id
    # The claims the issue names are in it.
    required = {"nw-t6-hashgrid-vertex-sh-order-indirect", "nw-t3-table-size-peaks-at-2^19",
                "nw-t4-sh-encoding-of-reflection", "nw-t5-learned-encodings-worse",
                "nw-t7-mirror-bathroom", "nw-t1-better-than-neural-prt",
                "prtt-3.1-fragment-faster-dragon-trm", "prtt-3.1-tpfl-faster-than-tp",
                "thesis-4.1-psnr-vs-texture-baseline", "thesis-4.2.2-sdf-diffuse-faster",
                "thesis-4.4-glsl-beats-cuda-at-64", "thesis-4.2.4-network-bytes",
                "thesis-4.1.5-sponza-200fps", "thesis-4.3.1-living-room-fps",
                "ddprt-t1-transfer-independent-of-basis", "ddprt-fig8-out-of-distribution-departs",
                "prtt-6.1-interreflections-slightly-slower", "lecture-48-haar-tripling-n-log-n",
                "lecture-48-sh-tripling-n-5-2", "lecture-41-factored-brdf-low-gloss"}
    assert required <= set(ids)


# --- rules ---------------------------------------------------------------------------------------

def _verdict(rule, *cases):
    return rule(Measured(list(cases))).verdict


def test_same_sign_needs_the_interval_and_the_band():
    rule = same_sign(band=(1.0, None))
    assert _verdict(rule, Estimate(2.0, 1.5, 2.5)) == claims.REPRODUCED
    assert _verdict(rule, Estimate(2.0, -0.1, 4.1)) == claims.DIRECTION  # not beyond 0
    assert _verdict(rule, Estimate(0.5, 0.4, 0.6)) == claims.DIRECTION  # below the band
    assert _verdict(rule, Estimate(-2.0, -2.5, -1.5), Estimate(2.0, 1.5, 2.5)) == \
        claims.CONTRADICTED  # half the cases the other way
    assert _verdict(rule, Estimate(-2.0), Estimate(2.0), Estimate(3.0)) == claims.DIRECTION
    decision = same_sign()(Measured([Estimate(-0.2, -1.0, 0.6)]))
    assert decision.verdict == claims.CONTRADICTED and "not resolved" in decision.why
    assert _verdict(same_sign(resolution=0.1), Estimate(0.05)) == claims.DIRECTION
    # A point value without an interval is never "reproduced" on its own ...
    assert _verdict(same_sign(), Estimate(5.0)) == claims.DIRECTION
    assert _verdict(same_sign(), Estimate(-5.0)) == claims.CONTRADICTED
    # ... only beyond a stated resolution.
    assert _verdict(same_sign(resolution=0.1), Estimate(0.5)) == claims.REPRODUCED


def test_ratio_band_keeps_the_papers_side_of_one():
    rule = ratio_within({"a": 4.0, "b": 0.25}, factor=2.0)
    assert _verdict(rule, Estimate(3.0, label="a"), Estimate(0.2, label="b")) == claims.REPRODUCED
    assert _verdict(rule, Estimate(10.0, label="a"), Estimate(0.2, label="b")) == claims.DIRECTION
    assert _verdict(rule, Estimate(0.5, label="a"), Estimate(3.0, label="b")) == \
        claims.CONTRADICTED


def test_range_and_tolerance_rules():
    rule = in_range(2.3, 2.7, direction=(2.0, 3.0))
    assert [_verdict(rule, Estimate(v)) for v in (2.5, 2.9, 3.5)] == [
        claims.REPRODUCED, claims.DIRECTION, claims.CONTRADICTED]
    rule = within_tolerance(0.5)
    assert _verdict(rule, Estimate(0.2)) == claims.REPRODUCED
    assert _verdict(rule, Estimate(0.8, 0.3, 1.3)) == claims.DIRECTION
    assert _verdict(rule, Estimate(2.0, 1.5, 2.5)) == claims.CONTRADICTED


# --- synthetic stores ----------------------------------------------------------------------------

def _config(method: str, **knobs) -> dict:
    return config_mod.to_dict(METHODS.get(method).make_config(knobs, profile="quick"))


def _row(method: str, *, run_id: str, view: int = 0, psnr: float = 25.0, half: float = 0.3,
         frame_ms: float = 10.0, renderer: str = LLVMPIPE, knobs=None, **fields) -> ResultRow:
    values = dict(method=method, scene="plants", config=_config(method, **(knobs or {})),  # noqa: C408
                  scene_variant="glossy",
                  light="sky", view=view, width=64, height=48,
                  metrics={"psnr_masked": psnr, "ssim_masked": 0.8, "flip_masked": 0.2},
                  frame_ms=frame_ms, frame_ms_p95=frame_ms, memory_bytes=1000, renderer=renderer,
                  timing_source="timer-query" if renderer == GPU else "wall+finish",
                  device="test", profile="quick", run_id=run_id, reference_spp=64,
                  reference_noise=0.01, scene_triangles=2000, scene_vertices=1200,
                  covered_pixels=1500, psnr_masked_lo=psnr - half, psnr_masked_hi=psnr + half)
    values.update(fields)
    return ResultRow(**values)


def _report(store, kind: str, name: str, *, cells=(), tables=None, own_rows=(), images=None,
            git_sha: str | None = None):
    """A complete report run as the reproductions store one: runner cells ``(label, rows)``,
    rows of the table's own harness (one run id, label {}), measurement tables (a row may name
    its cell's run as ``cell_run_id``) and panels."""
    run_id = measurements.new_run_id()
    members = {}
    for label, rows in cells:
        ResultsStore(store).append(rows)
        members[rows[0].run_id] = dict(label)
    if own_rows:
        ResultsStore(store).append(list(own_rows))
        members[own_rows[0].run_id] = {}
    for table, rows in (tables or {}).items():
        measurements.record(table, rows, results_path=store, run_id=run_id, profile="quick",
                            images=images if table == next(iter(tables)) else None,
                            git_sha=git_sha, device="AMD EPYC, 2 cores")
    measurements.complete_report(kind, name, profile="quick", run_id=run_id, members=members,
                                 results_path=store, git_sha=git_sha)


def _tessellation(store, *, coarse: float, fine: float):
    cells = []
    for tris, psnr in ((2, coarse), (8192, fine)):
        rid = f"tess-{tris}-{coarse}"
        cells.append(({"ground_tris": tris}, [
            _row("vertex", run_id=rid, view=v, psnr=psnr + 0.1 * v, frame_ms=5.0 + tris / 1000,
                 scene_variant="diffuse", memory_bytes=1000 + tris) for v in range(4)]))
    _report(store, "table", "tessellation", cells=cells)


def test_reproduced_and_an_unexplained_contradiction(tmp_path, ledger):
    good, bad = tmp_path / "good.sqlite", tmp_path / "bad.sqlite"
    _tessellation(good, coarse=19.0, fine=23.0)
    _tessellation(bad, coarse=23.0, fine=19.0)
    a = _evaluate(good, ledger, "prtt-1-vertex-needs-dense-tessellation")
    assessment = a["prtt-1-vertex-needs-dense-tessellation"]
    assert assessment.verdict == claims.REPRODUCED
    assert "4 dB" in assessment.ours and assessment.interval.startswith("2 → 8192")
    assert assessment.command == "prtbench table tessellation --profile quick"
    b = _evaluate(bad, ledger, "prtt-1-vertex-needs-dense-tessellation")
    assessment = b["prtt-1-vertex-needs-dense-tessellation"]
    assert assessment.verdict == claims.CONTRADICTED
    assert "unexplained" in assessment.explanation  # this claim names no explaining measurement


def test_a_contradiction_names_the_measurement_that_explains_it(tmp_path, ledger):
    store = tmp_path / "r.sqlite"
    rows = [{"case": "in distribution: held-out spot", "light": "spot0", "indirect_rmse": 0.0038,
             "indirect_rmse_relative": 0.574, "projection_rmse": 0.0032,
             "projection_rmse_relative": 0.482},
            {"case": "out of distribution: directional", "light": "sun", "indirect_rmse": 0.0198,
             "indirect_rmse_relative": 0.492, "projection_rmse": 0.0108,
             "projection_rmse_relative": 0.270}]
    _report(store, "figure", "ddprt-8", tables={"figure-ddprt-8": rows})
    assessment = _evaluate(store, ledger, "ddprt-fig8-out-of-distribution-departs")[
        "ddprt-fig8-out-of-distribution-departs"]
    assert assessment.verdict == claims.CONTRADICTED
    assert "Explained by: figure-ddprt-8" in assessment.explanation
    assert "0.482" in assessment.explanation and "×1.83" in assessment.explanation
    # Swap the cases: the out-of-distribution light departs more, as the paper says.
    rows[0]["indirect_rmse_relative"], rows[1]["indirect_rmse_relative"] = 0.3, 0.9
    other = tmp_path / "s.sqlite"
    _report(other, "figure", "ddprt-8", tables={"figure-ddprt-8": rows})
    swapped = _evaluate(other, ledger, "ddprt-fig8-out-of-distribution-departs")[
        "ddprt-fig8-out-of-distribution-departs"]
    # The paper's direction, but one stored number per case and no interval: not "reproduced".
    assert swapped.verdict == claims.DIRECTION and "without a stored interval" in \
        swapped.explanation


def _table_31(store, *, renderer: str):
    """Table 3.1's cells on Dragon and TRM, frame times at the paper's FPS."""
    cells = []
    for scene in ("Dragon", "TRM"):
        for method in ("vertex-tp", "vertex-tpfl", "texture-tp", "texture-tpfl"):
            rid = f"t31-{scene}-{method}-{renderer[:6]}"
            ms = 1000.0 / PAPER_FPS[(scene, method)]
            cells.append(({"paper_scene": scene, "method": method},
                          [_row(method, run_id=rid, frame_ms=ms, renderer=renderer,
                                scene="dragon-lo")]))
    _report(store, "table", "3.1", cells=cells)


def test_a_timing_claim_is_device_bound_on_a_cpu_and_decided_on_a_gpu(tmp_path, ledger):
    cpu, gpu = tmp_path / "cpu.sqlite", tmp_path / "gpu.sqlite"
    _table_31(cpu, renderer=LLVMPIPE)
    _table_31(gpu, renderer=GPU)
    name = "prtt-3.1-fragment-faster-dragon-trm"
    on_cpu = _evaluate(cpu, ledger, name)[name]
    assert on_cpu.verdict == claims.DEVICE_BOUND
    assert "llvmpipe" in on_cpu.explanation and "operation-count model" in on_cpu.explanation
    assert "Dragon TP" in on_cpu.explanation and "(paper 1.44)" in on_cpu.explanation
    on_gpu = _evaluate(gpu, ledger, name)[name]
    assert on_gpu.verdict == claims.REPRODUCED  # the paper's own frame rates, measured on a GPU
    assert "Dragon TPFL 3.67" in on_gpu.ours


def test_direction_only_and_computed_claims(tmp_path, ledger):
    store = tmp_path / "r.sqlite"
    panels = [{"panel": p, "basis": b, "terms": t, "psnr_masked_db": psnr, "frame_ms": ms,
               "cubemap": 64}
              for p, b, t, psnr, ms in (("SH 5", "sh", 25, 23.8, 10.0),
                                        ("SH 14", "sh", 196, 24.6, 10.0),
                                        ("SH 45", "sh", 2025, 25.06, 10.0),
                                        ("w25", "wavelet", 25, 24.8, 0.25),
                                        ("w200", "wavelet", 200, 25.1, 2.0),
                                        ("w2000", "wavelet", 2000, 25.1, 20.0))]
    _report(store, "figure", "lecture-33", tables={"figure-lecture-33": panels})
    found = _evaluate(store, ledger, "lecture-34-wavelet-images-beat-linear-sh",
                      "lecture-50-linear-in-retained-terms", "lecture-48-sh-tripling-n-5-2",
                      "lecture-31-retain-one-percent")
    images = found["lecture-34-wavelet-images-beat-linear-sh"]
    assert images.verdict == claims.DIRECTION and "2 of 3 cases" in images.explanation
    assert found["lecture-50-linear-in-retained-terms"].verdict == claims.REPRODUCED
    # Computed from our own SH tensor, whatever the store holds.
    sh = found["lecture-48-sh-tripling-n-5-2"]
    assert sh.verdict == claims.REPRODUCED and "N=64 12868" in sh.ours
    # The figure's lighting curve was not stored: the run cannot answer that claim.
    curve = found["lecture-31-retain-one-percent"]
    assert curve.verdict == claims.NOT_MEASURABLE and curve.no_data
    assert "cannot answer" in curve.explanation and not curve.interval


def _nw_rows(run_id: str, label: dict, indirect: float, *, view_set: str = "far", **metrics):
    """Two views of one neural-wavelet table cell, labelled as table_nw_common labels them."""
    return [_row("neural-wavelet", run_id=run_id, view=v, light="sunrise", psnr=indirect + 4,
                 metrics={"psnr_masked": indirect + 4, "indirect_psnr_masked": indirect + 0.2 * v,
                          **metrics},
                 cell_key=label_key({**label, "views": view_set})) for v in range(2)]


def test_an_explanation_reads_another_report(tmp_path, ledger):
    store = tmp_path / "r.sqlite"
    rows = (_nw_rows("nw1-a", {"config": "hashgrid"}, 15.1)
            + _nw_rows("nw1-a", {"config": "vertex"}, 19.2)
            + _nw_rows("nw1-a", {"config": "sh"}, 23.8))
    _report(store, "table", "nw-1", own_rows=rows)
    name = "nw-t6-hashgrid-vertex-sh-order-indirect"
    assert "unexplained" in _evaluate(store, ledger, name)[name].explanation
    seeds = [r for s, p in ((0, 15.6), (1, 18.5), (2, 17.7))
             for r in _nw_rows("nwseed-a", {"seed": s}, p)]
    _report(store, "table", "nw-seeds", own_rows=seeds)
    assessment = _evaluate(store, ledger, name)[name]
    assert assessment.verdict == claims.CONTRADICTED
    assert "Explained by: table-nw-seeds (quick)" in assessment.explanation
    assert "2.90 dB over 3 training seeds" in assessment.explanation


def test_every_contradiction_carries_an_explanation(tmp_path, ledger):
    store = tmp_path / "r.sqlite"
    _tessellation(store, coarse=23.0, fine=19.0)
    _table_31(store, renderer=LLVMPIPE)
    for assessment in claims.evaluate(ledger, results_path=store):
        if assessment.verdict == claims.CONTRADICTED:
            assert ("Explained by:" in assessment.explanation
                    or "unexplained" in assessment.explanation), assessment.claim.id


# --- the command ---------------------------------------------------------------------------------

SHA = "0123456789abcdef0123456789abcdef01234567"


def _provenance_checker():
    """tests/test_reports_provenance.py's check of a committed report (loaded by path)."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "test_reports_provenance.py"
    spec = importlib.util.spec_from_file_location("_reports_provenance", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.provenance_problems


def _empty_store(path):
    """A results store with the schema and no rows (what a fresh `prtbench run` folder has)."""
    ResultsStore(path)._connect().close()
    assert path.exists()
    return path


def test_the_command_writes_markdown_and_csv_with_the_counts(tmp_path, ledger, capsys):
    store, reports = tmp_path / "r.sqlite", tmp_path / "reports"
    _tessellation(store, coarse=19.0, fine=23.0)
    assert main(["claims", "--results", str(store), "--reports", str(reports)]) == 0
    with open(reports / "claims.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == len(ledger)
    assert list(rows[0]) == list(claims.CSV_COLUMNS)
    assert {"id", "source", "claim", "paper", "ours", "interval", "verdict", "explanation",
            "report", "command"} <= set(rows[0])
    assert {r["verdict"] for r in rows} <= set(claims.VERDICTS)
    tally = {v: sum(r["verdict"] == v for r in rows) for v in claims.VERDICTS}
    md = (reports / "claims.md").read_text()
    for verdict, n in tally.items():
        assert f"| {verdict} | {n} |" in md
    no_data = sum(r["explanation"].startswith(claims.NO_DATA) for r in rows)
    assert f"| (of which {claims.NO_DATA}) | {no_data} |" in md and no_data > 30
    assert f"{len(ledger)} claims: " in md and tally[claims.REPRODUCED] >= 4
    claim_rows = [line for line in md.splitlines() if line.startswith("| ")
                  and line.split(" | ")[0][2:] in {c.id for c in ledger}]
    assert len(claim_rows) == len(ledger)
    out = capsys.readouterr().out
    assert out.startswith(f"{len(ledger)} claims: ") and "wrote" in out
    tess = next(r for r in rows if r["id"] == "prtt-1-vertex-needs-dense-tessellation")
    assert tess["verdict"] == claims.REPRODUCED and tess["report"] == "table tessellation"
    for row in rows:  # a contradiction always says what explains it, or that nothing does
        if row["verdict"] == claims.CONTRADICTED:
            assert "Explained by:" in row["explanation"] or "unexplained" in row["explanation"]


def test_the_page_names_its_commit_load_and_cores_and_no_absolute_path(tmp_path, ledger,
                                                                      monkeypatch):
    problems_of = _provenance_checker()
    store = tmp_path / "r.sqlite"
    cells = []
    for tris, psnr in ((2, 19.0), (8192, 23.0)):
        rid = f"tess-{tris}"
        cells.append(({"ground_tris": tris}, [
            _row("vertex", run_id=rid, view=v, psnr=psnr + 0.1 * v, scene_variant="diffuse",
                 git_sha=SHA, device="AMD EPYC, 2 cores", load_average=0.4 + 0.1 * v)
            for v in range(3)]))
    _report(store, "table", "tessellation", cells=cells, git_sha=SHA)
    assessed = claims.evaluate(ledger, results_path=store)
    text = claims_page.provenance_text(assessed, ledger_sha=SHA)
    assert "same commit" in text and "1-min load average 0.4 to 0.6" in text
    md = claims_page.markdown_text(assessed, results_path=store, provenance=text)
    assert problems_of(md, claims_page.csv_text(assessed)) == []
    # The store is outside the working folder: only its file name is printed.
    assert "`r.sqlite`" in md and str(tmp_path) not in md
    monkeypatch.chdir(tmp_path)
    assert "`r.sqlite`" in claims_page.markdown_text(assessed, results_path=store, provenance=text)
    # Another commit at the ledger (or a dirty tree) is named, and the check catches it.
    other = claims_page.provenance_text(assessed, ledger_sha="f" * 40)
    assert "2 commits" in "; ".join(problems_of(claims_page.markdown_text(
        assessed, results_path=store, provenance=other)))
    dirty = claims_page.provenance_text(assessed, ledger_sha=SHA + "+dirty")
    assert problems_of(dirty)


def test_an_empty_store_says_not_measured_and_gives_the_commands(tmp_path, ledger):
    store, reports = _empty_store(tmp_path / "results.sqlite"), tmp_path / "reports"
    before = store.stat().st_mtime_ns
    assert main(["claims", "--results", str(store), "--reports", str(reports)]) == 0
    assert store.stat().st_mtime_ns == before  # read only
    with open(reports / "claims.csv", newline="") as fh:
        rows = {r["id"]: r for r in csv.DictReader(fh)}
    for c in ledger:
        row = rows[c.id]
        if c.not_measurable:
            assert row["verdict"] == claims.NOT_MEASURABLE and row["explanation"], c.id
        elif c.report is None:  # computed from our bases: no store needed
            assert row["verdict"] in (claims.REPRODUCED, claims.DIRECTION), c.id
        else:  # nothing invented: no number of ours, the reason, the command
            kind, name = c.kind_and_name
            assert row["verdict"] == claims.NOT_MEASURABLE, c.id
            assert row["explanation"].startswith(claims.NO_DATA) and not row["ours"], c.id
            assert row["command"] == f"prtbench {kind} {name} --profile quick"
    md = (reports / "claims.md").read_text()
    assert "No stored run was read" in md and "1-min load average" in md and " cores" in md


def test_source_selects_claims_and_bad_input_is_one_line_exit_2(tmp_path, ledger, capsys):
    store, reports = _empty_store(tmp_path / "r.sqlite"), tmp_path / "reports"
    assert main(["claims", "--results", str(store), "--reports", str(reports),
                 "--source", "nw", "--source", "Ramamoorthi CSE168 lecture"]) == 0
    with open(reports / "claims.csv", newline="") as fh:
        ids = [r["id"] for r in csv.DictReader(fh)]
    assert ids and all(i.startswith(("nw-", "lecture-")) for i in ids)
    assert len(ids) == sum(c.id.startswith(("nw-", "lecture-")) for c in ledger)
    assert "Only the claims of nw, Ramamoorthi" in (reports / "claims.md").read_text()
    capsys.readouterr()
    (reports / "claims.md").unlink()
    bad = [
        (["--source", "prrt"], "unknown source 'prrt'; did you mean 'prtt'?"),
        (["--results", str(tmp_path / "none.sqlite")], "does not exist"),
        (["--results", str(tmp_path)], "is a folder"),
        (["--profile", "fast"], "profile 'fast'"),
    ]
    for extra, message in bad:
        argv = ["claims", "--results", str(store), "--reports", str(reports), *extra]
        try:
            status = main(argv)
        except SystemExit as exc:  # argparse's own refusals (a bad choice)
            status = exc.code
        err = capsys.readouterr().err
        assert status == 2, extra
        assert err.count("\n") == 1 and err.startswith("prtbench: error:") and message in err, err
        assert not (reports / "claims.md").exists()  # nothing written
    (tmp_path / "not-a-store.sqlite").write_text("hello")
    assert main(["claims", "--results", str(tmp_path / "not-a-store.sqlite"),
                 "--reports", str(reports)]) == 2
    assert capsys.readouterr().err.count("\n") == 1


def test_a_bad_reports_path_is_one_line_and_writes_nothing(tmp_path, capsys):
    blocker = tmp_path / "a-file"
    blocker.write_text("x")
    store = _empty_store(tmp_path / "r.sqlite")
    assert main(["claims", "--results", str(store), "--reports", str(blocker / "sub")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("prtbench: error: --reports")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a-file", "r.sqlite"]


def test_help_explains_the_verdicts_and_the_options(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["claims", "--help"])
    assert exc.value.code == 0
    text = capsys.readouterr().out
    for word in ("--results", "--reports", "--profile", "--source", "reproduced",
                 "device-bound", "not measured in this store", "Examples:"):
        assert word in text


def test_intervals_use_the_reference_noise_and_the_views():
    import pandas as pd

    from reproductions.claims.measures import paired_difference

    a = pd.DataFrame({"view": [0, 1], "light": ["sky", "sky"], "metric_psnr_masked": [22.0, 24.0],
                      "psnr_masked_lo": [21.5, 23.5], "psnr_masked_hi": [22.5, 24.5]})
    b = a.assign(metric_psnr_masked=[20.0, 21.0], psnr_masked_lo=[19.5, 20.5],
                 psnr_masked_hi=[20.5, 21.5])
    d = paired_difference(a, b)
    assert d.value == pytest.approx(2.5)
    half = 12.706 * math.sqrt(0.5) / math.sqrt(2)  # t(1) · sd(diffs) / √n
    assert d.lo == pytest.approx(2.5 - half - 1.0) and d.hi == pytest.approx(2.5 + half + 1.0)


# --- every report's shape ------------------------------------------------------------------------
# One small run of each report, stored the way its reproduction stores it, so that every claim's
# measure is exercised on the columns, labels and measurement tables it really reads.

def _cells(prefix: str, labels, make):
    out = []
    for i, label in enumerate(labels):
        rows = make(label, f"{prefix}-{i}")
        out.append((label, rows if isinstance(rows, list) else [rows]))
    return out


def _shape_31(store):
    scenes = [s for s, _ in PAPER_SCENES]
    methods = ("vertex-tp", "vertex-tpfl", "texture-tp", "texture-tpfl")
    _report(store, "table", "3.1", cells=_cells("s31", [
        {"paper_scene": s, "method": m} for s in scenes for m in methods],
        lambda lab, rid: _row(lab["method"], run_id=rid,
                              frame_ms=1000.0 / PAPER_FPS[(lab["paper_scene"], lab["method"])],
                              psnr=20.0 + 3.0 * lab["method"].startswith("texture"))))


def _shape_32(store):
    vertices = {"Dragon": 23443, "TRM": 63584, "Room": 13458, "Plants": 16296}
    size = {"sloan": lambda v: v * 2500, "ng": lambda v: v * 100 + gamma_bytes(5),
            "ours": lambda v: 256 * 256 * 112 + tpfl_bytes(5)}
    method = {"sloan": "sloan-matrix", "ng": "vertex-tp", "ours": "texture-tpfl"}
    labels = [{"paper_scene": s, "scheme": k} for s in vertices for k in method
              if not (s == "TRM" and k == "sloan")]
    cells = _cells("s32", labels, lambda lab, rid: _row(
        method[lab["scheme"]], run_id=rid, scene_vertices=vertices[lab["paper_scene"]],
        memory_bytes=size[lab["scheme"]](vertices[lab["paper_scene"]])))
    _report(store, "table", "3.2", cells=cells, tables={
        "table-3.2-scenes": [{"cell_run_id": rows[0].run_id, "scene_objects": 2}
                             for _, rows in cells],
        "table-3.2-gl": [{"gl_max_shader_storage_block_size": 2**27}]})


def _shape_figures_3x(store):
    labels = [{"scene": s, "column": c} for s in ("plants", "room") for c in range(5)]
    _report(store, "figure", "3.4", cells=_cells("f34", labels, lambda lab, rid: _row(
        "vertex-tpfl", run_id=rid, psnr=(19.0, 19.0, 25.0, 25.0, 23.0)[lab["column"]])),
        tables={"figure-3.4": [{"scene": "plants", "n_triangles": 100}]})
    cells = _cells("f35", [{"scene": s, "bounces": b} for s in ("lion", "bust") for b in (0, 1)],
                   lambda lab, rid: _row("texture-tpfl", run_id=rid,
                                         frame_ms=100.0 + 20 * lab["bounces"]))
    _report(store, "figure", "3.5", cells=cells, tables={"figure-3.5": [
        {"cell_run_id": rows[0].run_id, "psnr_masked_vs_one_bounce": 24.0 + 3 * lab["bounces"]}
        for lab, rows in cells]})
    panel = np.zeros((4, 4, 3), np.uint8)
    _report(store, "figure", "3.6", cells=_cells("f36", [{"normal_map": False}], lambda lab, rid:
            _row("texture-tpfl", run_id=rid)), tables={"figure-3.6": [{"n_triangles": 2000}]},
            images={"without": panel, "with": panel + 10})


def _shape_tessellation(store):
    _tessellation(store, coarse=19.0, fine=23.0)


def _shape_4x(store):
    labels = [{"variant": v, "scene": s, "k": k, "reference": r}
              for v in VARIANTS for s in SCENES for k in (64, 128)
              for r in ("method:texture-tp", "path")]
    _report(store, "table", "4.1", cells=_cells("s41", labels, lambda lab, rid: [
        _row("learnt", run_id=rid, view=v, knobs={"hidden": lab["k"]},
             frame_ms=100.0 * lab["k"] / 64, memory_bytes=80_000 * lab["k"] // 64,
             metrics={"psnr": 34.0 + lab["k"] / 64 + v, "psnr_masked": 25.0})
        for v in range(2)]))
    _report(store, "table", "4.2", cells=_cells("s42", [
        {"scene": s, "variant": v, "k": k} for s in SDF_LABELS for v in VARIANTS
        for k in (64, 128)], lambda lab, rid: _row("learnt-sdf", run_id=rid,
                                                   frame_ms=100.0 * lab["k"] / 64)))
    _report(store, "table", "4.3", cells=_cells("s43", [
        {"size": z, "variant": v, "k": k} for z in ("small", "large") for v in VARIANTS
        for k in (64, 128)], lambda lab, rid: _row("learnt-sdf", run_id=rid,
                                                   frame_ms=100.0 * (1 + (lab["size"] == "large")))))
    _report(store, "table", "4.4", cells=_cells("s44", [
        {"renderer": r, "k": k} for r in ("glsl", "torch") for k in (64, 128, 256, 512)
        if r == "torch" or k <= 128], lambda lab, rid: _row("learnt", run_id=rid,
                                                            frame_ms=float(lab["k"]))))
    point = {"hidden": 128, "samples": 200000, "rays_per_point": 256, "epochs": 40,
             "heldout_relative_rms": 0.22}
    _report(store, "figure", "4.11", tables={"figure-4.11": [
        {**point, "point": p, "relative_l2": e} for p, e in (("A", 0.1), ("B", 0.4))]})
    _report(store, "figure", "4.13", tables={"figure-4.13": [
        {"network": n, "psnr_masked_vs_traced": p, "heldout_surface_relative_rms": r}
        for n, p, r in (("no PE", 25.3, 0.27), ("PE", 29.1, 0.15))]})


def _shape_volume(store):
    labels = ([{"scene": "room", "method": "irradiance-volume", "N": n} for n in (4, 8, 16)]
              + [{"scene": "room", "method": "texture-tpfl", "N": 0}])
    cells = _cells("svol", labels, lambda lab, rid: _row(
        lab["method"], run_id=rid, knobs={"resolution": lab["N"]} if lab["N"] else None,
        memory_bytes=109 * lab["N"] ** 3 or 7_000_000))
    _report(store, "table", "volume", cells=cells, tables={"table-volume-leak": [
        {"cell_run_id": rows[0].run_id, "leak_mae": 0.05 + 0.1 / (lab["N"] or 1e9)}
        for lab, rows in cells]})


def _shape_ddprt(store):
    rows = []
    for column, scene in (("CORNELL", "cornell"), ("VIKING", "room")):
        for n in (4, 16, 64):
            metrics = {"ms_no_gi": 3.0, "ms_shading": 3.0 + n / 16, "ms_gbuffer": 0.3,
                       "ms_transfer": 0.2 + n / 200, "ms_shadows": 4.0, "ms_frame": 9.0,
                       "bake_s": 2.0, "bytes_basis": 256 * 256 * 16 * (n // 4 or 1),
                       "bytes_transfer_matrix": (n - 1) * 256 * 12}
            rows.append(_row("data-driven", run_id="ddprt1-x", knobs={"basis": n}, scene=scene,
                             metrics=metrics, scene_params={"column": column}))
    _report(store, "table", "ddprt-1", own_rows=rows)
    curves = [{"space": "lightmap", "family": f, "ridge": r, "basis": n,
               "ours_rmse": 0.02 / n, "projection_rmse": 0.015 / n, "reference_rms": 0.03}
              for f in ("env-rotations", "spot") for r in (1e-3, 1e-2) for n in (1, 4, 16, 64)]
    _report(store, "figure", "ddprt-14", tables={"figure-ddprt-14": curves})
    _report(store, "figure", "ddprt-12", tables={"figure-ddprt-12": [
        {"image": i, "psnr_masked_db": p, "unlit_vs_reference": u} for i, p, u in (
            ("Mitsuba reference", None, 1.0), ("data-driven", 33.0, 1.02),
            ("vertex PRT (5 bands)", 17.9, 2.5))]})
    _report(store, "figure", "ddprt-8", tables={"figure-ddprt-8": [
        {"case": c, "indirect_rmse": e, "indirect_rmse_relative": r, "projection_rmse": p,
         "projection_rmse_relative": q} for c, e, r, p, q in (
            ("in distribution: held-out spot", 0.004, 0.3, 0.003, 0.2),
            ("out of distribution: directional", 0.02, 0.6, 0.01, 0.3))]})


def _shape_lecture(store):
    panels = [{"panel": p, "basis": b, "terms": t, "psnr_masked_db": q, "frame_ms": t / 100,
               "cubemap": 64} for p, b, t, q in (("a", "sh", 25, 23.8), ("b", "sh", 196, 24.6),
                                                   ("c", "wavelet", 25, 24.8),
                                                   ("d", "wavelet", 200, 25.1))]
    curve = [{"light": "sun", "basis": b, "terms": t, "rel_l2": e} for b, t, e in (
        ("wavelet-area", 200, 0.01), ("sh", 196, 0.97))]
    _report(store, "figure", "lecture-33", tables={"figure-lecture-33": panels,
                                                  "figure-lecture-33-lighting": curve})
    labels = [{"scene": s, "light": li, "config": c} for s in ("plants", "room")
              for li in ("sun", "sunset") for c in ("wavelet-vertex k=200", "vertex 5 bands")]
    _report(store, "table", "ng03", cells=_cells("sng", labels, lambda lab, rid: _row(
        "vertex", run_id=rid, psnr=20.0 + 2 * (lab["light"] == "sun") * lab["config"].startswith("w"))))
    labels = [{"case": "plants diffuse", "K": k, "n": n} for k, n in ((0, -1), (1, 4), (16, 4))]
    cells = _cells("scp", labels, lambda lab, rid: _row("vertex", run_id=rid))
    _report(store, "table", "cpca", cells=cells, tables={"table-cpca-form": [
        {"cell_run_id": rows[0].run_id, "transfer_rmse": 0.05 / (lab["K"] or 1e9) + 0.001}
        for lab, rows in cells]})


def _shape_nw(store):
    rows = [r for config, p in (("hashgrid", 20.0), ("vertex", 19.0), ("sh", 17.0))
            for r in _nw_rows("nw1-s", {"config": config}, p)]
    rows += _nw_rows("nw1-s", {"config": "hashgrid"}, 20.2, view_set="near")
    _report(store, "table", "nw-1", own_rows=rows)
    _report(store, "table", "nw-2", own_rows=[
        _row("neural-wavelet", run_id="nw2-s", frame_ms=float(k) * (4 if res == "higher" else 1),
             width=640 if res == "higher" else 320, height=480 if res == "higher" else 240,
             cell_key=label_key({"resolution": res, "k": k}))
        for res in ("lower", "higher") for k in (32, 64, 128)])
    _report(store, "table", "nw-3", own_rows=[
        r for t in (16, 18, 19, 20) for r in _nw_rows("nw3-s", {"log2_table": t}, 20.0 - abs(t - 19),
                                                      bytes_field=1000.0 * 1.9 ** t)])
    _report(store, "table", "nw-4", own_rows=[
        r for d in (-1, 2, 4) for r in _nw_rows("nw4-s", {"reflect_degree": d}, 10.0 + 4 * d)])
    stats = [{"panel": p, "series": s, "k": 64, "value": v} for p, s, v in (
        ("light", "sunrise (held-out)", 1.0), ("transport", "ground truth", 0.94),
        ("rendering", "learnt", 0.004))] + [{"panel": "facts", "series": "setup", "k": 1536,
                                             "value": None, "cubemap": 16}]
    _report(store, "figure", "nw-6", tables={"figure-nw-6": stats})


def _shape_factored_gloss(store):
    _factored_gloss(store, lambda s, setup: 24.0 - 0.25 * math.log2(s))


SHAPES = (_shape_31, _shape_32, _shape_figures_3x, _shape_tessellation, _shape_4x,
          _shape_volume, _shape_ddprt, _shape_lecture, _shape_nw, _shape_factored_gloss)


def test_every_claim_reads_the_shape_its_report_stores(tmp_path, ledger):
    store = tmp_path / "all.sqlite"
    for build in SHAPES:
        build(store)
    assessed = claims.evaluate(ledger, results_path=store)
    assert {a.claim.id: a.explanation for a in assessed if a.no_data} == {}
    for a in assessed:
        if a.claim.measure is not None:
            assert a.ours, a.claim.id
        if a.verdict == claims.CONTRADICTED:
            assert "Explained by:" in a.explanation or "unexplained" in a.explanation
    assert {claims.REPRODUCED, claims.DIRECTION, claims.DEVICE_BOUND,
            claims.NOT_MEASURABLE} <= {a.verdict for a in assessed}


def _factored_gloss(store, psnr_of):
    """table factored-gloss as it stores itself: per Phong exponent s and setup, four views."""
    cells = []
    for s in (8, 32, 128, 512):
        for setup, method in (("factored J=1", "factored-brdf"), ("factored J=4", "factored-brdf"),
                              ("sloan-matrix", "sloan-matrix")):
            rid = f"fg-{s}-{setup}-{psnr_of(s, setup)}"
            cells.append(({"setup": setup, "shininess": s}, [
                _row(method, run_id=rid, view=v, psnr=psnr_of(s, setup) + 0.05 * v, half=0.1)
                for v in range(4)]))
    _report(store, "table", "factored-gloss", cells=cells)


def test_factored_brdf_against_gloss_is_decided_from_its_table(tmp_path, ledger):
    # The factored form loses 1.5 dB from s = 8 to s = 512 (beyond ±0.1 dB of noise): the
    # lecture's "only less glossy materials" reproduced; flat, it is not.
    losing, flat = tmp_path / "losing.sqlite", tmp_path / "flat.sqlite"
    _factored_gloss(losing, lambda s, setup: 24.0 - 0.25 * math.log2(s)
                    - (0.5 if setup == "sloan-matrix" else 0.0))
    _factored_gloss(flat, lambda s, setup: 24.0)
    a = _evaluate(losing, ledger, "lecture-41-factored-brdf-low-gloss")
    assessment = a["lecture-41-factored-brdf-low-gloss"]
    assert assessment.verdict == claims.REPRODUCED, assessment
    assert "factored J=1: s=8 − s=512" in assessment.interval
    assert "against the unfactored matrix at s=512: factored J=1 +0.50 dB" in assessment.ours
    assert assessment.command == "prtbench table factored-gloss --profile quick"
    b = _evaluate(flat, ledger, "lecture-41-factored-brdf-low-gloss")
    assert b["lecture-41-factored-brdf-low-gloss"].verdict != claims.REPRODUCED
