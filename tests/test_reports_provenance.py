"""Every committed report comes from one clean commit on an idle machine (DESIGN.md §20).

Each Markdown report under ``reports/`` (with the CSV of the same name beside it) must name
exactly one git commit (40 hex digits; reports regenerated at different commits are fine, one
commit per report), no ``+dirty`` tree, a recorded 1-minute load no higher than
:data:`~prtbench.bench.reproduction.BUSY_LOAD_PER_CORE` × the recorded core count (a report
that records no load fails), and no absolute path of a machine. Images are not read. The
checks parse what the generators print; the always-on tests below run them on synthetic good
and bad reports and on the generators' own output, so neither side can drift unnoticed.

``make reports`` (scripts/reports_guard.py) regenerates every report from one clean commit;
its dirty-tree rules are tested here too.
"""

from __future__ import annotations

import csv
import importlib.util
import io
import math
import re
from pathlib import Path

import pytest

from prtbench.bench.reproduction import BUSY_LOAD_PER_CORE

#: The committed reports predate `make reports` (several commits, +dirty trees, loads above
#: the limit or none recorded, a developer's absolute path), so their test is an expected
#: failure. The lead flips this to True after regenerating them with `make reports` at one
#: clean commit; from then on a stale or hand-edited report fails the default test run.
REPORTS_REGENERATED = False

ROOT = Path(__file__).resolve().parents[1]
REPORTS = ROOT / "reports"
#: A commit: 40 hex digits, not part of a longer hex string (a sha256 digest).
COMMIT = re.compile(r"(?<![0-9a-fA-F])[0-9a-f]{40}(?![0-9a-fA-F])")
#: The load ranges the generators print, as (lowest, highest).
LOAD_PATTERNS = (
    # prtbench.bench.reproduction.load_note: tables, figures and the Pareto reports.
    re.compile(r"1-min load average (\d+(?:\.\d+)?) to (\d+(?:\.\d+)?)"),
    # prtbench.stability.report: "Load (1-min average, ...) 0.25-2.02 over the N rows ...".
    re.compile(r"Load \(1-min average[^)]*\) (\d+(?:\.\d+)?)-(\d+(?:\.\d+)?)"),
)
#: CSV columns holding a row's 1-minute load.
LOAD_COLUMNS = ("load_average", "load_1m")
#: "…, 2 cores" (prtbench.bench.runner.device_description).
CORES = re.compile(r"\b(\d+) cores\b")
#: An absolute path of some machine: a home, this project's work folders, a temp folder, or a
#: Windows drive.
MACHINE_PATH = re.compile(r"(?<![\w.~-])(?:/home/|/work/|/tmp/|/Users/|/root/)"
                          r"|(?<![A-Za-z0-9])[A-Za-z]:[\\/](?=[\w.-])")


def _csv_rows(text: str) -> list[dict]:
    return list(csv.DictReader(io.StringIO(text)))


def _number(value) -> float | None:
    try:
        number = float(value)
    except (TypeError, ValueError):
        return None
    return number if math.isfinite(number) else None


def provenance_problems(md_text: str, csv_text: str | None = None) -> list[str]:
    """What a report (its Markdown, and its CSV if it has one) gets wrong; empty when fine.

    Parameters
    ----------
    md_text : str
        The Markdown report.
    csv_text : str, optional
        The CSV of the same name; its ``git_sha``, load and ``device`` columns count too.

    Returns
    -------
    list of str
        One line per problem.
    """
    problems = []
    texts = [md_text] + ([csv_text] if csv_text is not None else [])
    rows = _csv_rows(csv_text) if csv_text else []
    if any("+dirty" in t for t in texts):
        problems.append("names a +dirty tree")
    commits = sorted({sha for t in texts for sha in COMMIT.findall(t)})
    if not commits:
        problems.append("names no git commit")
    elif len(commits) > 1:
        problems.append(f"names {len(commits)} commits ({', '.join(c[:12] for c in commits)})")
    loads = [float(hi) for pattern in LOAD_PATTERNS for _lo, hi in pattern.findall(md_text)]
    loads += [v for r in rows for c in LOAD_COLUMNS if (v := _number(r.get(c))) is not None]
    cores = [int(n) for n in CORES.findall(md_text)]
    cores += [int(n) for r in rows for n in CORES.findall(r.get("device") or "")]
    if not loads:
        problems.append("records no load")
    elif not cores:
        problems.append("records no core count beside its load")
    elif max(loads) > BUSY_LOAD_PER_CORE * min(cores):
        problems.append(f"recorded 1-min load {max(loads):g} is above {BUSY_LOAD_PER_CORE:g} x "
                        f"{min(cores)} cores")
    found = sorted({m.group(0) for t in texts for m in MACHINE_PATH.finditer(t)})
    if found:
        problems.append(f"names an absolute machine path ({', '.join(found)})")
    return problems


def report_problems(path: Path) -> list[str]:
    """:func:`provenance_problems` of the report at ``path`` (a ``.md``, or a ``.csv`` that has
    no Markdown beside it, which is itself a problem: nothing names its commit and load)."""
    if path.suffix == ".csv":
        return ["no Markdown report of the same name says where it comes from",
                *provenance_problems(path.read_text(), None)[1:]]
    csv_path = path.with_suffix(".csv")
    return provenance_problems(path.read_text(),
                               csv_path.read_text() if csv_path.exists() else None)


def committed_reports() -> list[str]:
    """Every Markdown report under reports/, and every CSV there without one."""
    md = sorted(p.name for p in REPORTS.glob("*.md"))
    stems = {Path(m).stem for m in md}
    return md + sorted(p.name for p in REPORTS.glob("*.csv") if p.stem not in stems)


#: Reports already measured under these rules (one clean commit, an idle machine): their test
#: is an ordinary one now, whatever REPORTS_REGENERATED says.
UNDER_THE_RULES = ("table-engine.md", "table-factored-gloss.md", "table-tessellation.md",
                   "table-volume.md", "table-4.3.md", "table-4.4.md", "figure-3.6.md",
                   "figure-3.5.md")


def _expectation(name: str):
    if REPORTS_REGENERATED or name in UNDER_THE_RULES:
        return name
    return pytest.param(name, marks=pytest.mark.xfail(
        strict=False, reason="the committed reports predate `make reports` (REPORTS_REGENERATED)"))


@pytest.mark.parametrize("name", [_expectation(n) for n in committed_reports()])
def test_committed_report_names_one_clean_commit_an_idle_machine_and_no_machine_path(name):
    problems = report_problems(REPORTS / name)
    assert not problems, f"reports/{name}: " + "; ".join(problems)


# --- the checks themselves, on synthetic reports --------------------------------------------

SHA = "0123456789abcdef0123456789abcdef01234567"
OTHER = "fedcba9876543210fedcba9876543210fedcba98"
GOOD_MD = (f"# Table\n\nProfile: `quick`. GL renderer: llvmpipe. Machine: AMD EPYC, 2 cores. "
           f"Git: {SHA}. Load while measuring: 1-min load average 0.4 to 1.9.\n\n| a |\n|---|\n"
           "| 1 |\n")
GOOD_CSV = "a,b\n1,2\n"


def _write(folder: Path, name: str, md: str | None, csv_text: str | None = None) -> Path:
    if csv_text is not None:
        (folder / f"{name}.csv").write_text(csv_text)
    if md is None:
        return folder / f"{name}.csv"
    (folder / f"{name}.md").write_text(md)
    return folder / f"{name}.md"


def test_a_report_from_one_clean_commit_on_an_idle_machine_passes(tmp_path):
    assert report_problems(_write(tmp_path, "table-x", GOOD_MD, GOOD_CSV)) == []
    assert report_problems(_write(tmp_path, "figure-y", GOOD_MD)) == []  # no CSV
    # Reports regenerated at different commits: one each is fine.
    assert report_problems(_write(tmp_path, "table-z", GOOD_MD.replace(SHA, OTHER))) == []


def test_a_stability_style_report_with_per_row_commits_and_loads_passes(tmp_path):
    md = (f"# Stability\n\nProfile `quick`, code `{SHA}` (per row in the CSV), device AMD "
          "EPYC, 2 cores. Load (1-min average, the higher of each case's start and end) "
          "0.25-2.02 over the 3 rows that recorded it.\n")
    csv_text = "method,case,git_sha,device,load_1m\n" + "".join(
        f'vertex,c{i},{SHA},"AMD EPYC, 2 cores",{0.5 + i}\n' for i in range(3))
    assert report_problems(_write(tmp_path, "table-stability", md, csv_text)) == []


@pytest.mark.parametrize("md, csv_text, expected", [
    (GOOD_MD.replace(SHA, f"{SHA}+dirty"), None, "+dirty"),
    (GOOD_MD.replace(f"Git: {SHA}", f"Git: {SHA}, {OTHER}"), None, "2 commits"),
    (GOOD_MD.replace(f"Git: {SHA}", "Git: unknown"), None, "no git commit"),
    (GOOD_MD, f"git_sha,x\n{SHA},1\n{OTHER},2\n", "2 commits"),
    (GOOD_MD, f"git_sha,x\n{SHA}+dirty,1\n", "+dirty"),
    (GOOD_MD.replace(" Load while measuring: 1-min load average 0.4 to 1.9.", ""), None,
     "records no load"),
    (GOOD_MD.replace("0.4 to 1.9", "0.4 to 3.5"), None, "above 1.5 x 2 cores"),
    (GOOD_MD, 'device,load_average\n"AMD EPYC, 2 cores",4.0\n', "above 1.5 x 2 cores"),
    (GOOD_MD.replace(", 2 cores", ""), None, "no core count"),
    (GOOD_MD + "\nGenerated from `/work/wt-pareto/results/prtbench.sqlite`.\n", None,
     "/work/"),
    (GOOD_MD, "path\n/home/someone/cache/x.exr\n", "/home/"),
    (GOOD_MD + "\nRead C:\\Users\\me\\results.sqlite\n", None, "C:\\"),
    (GOOD_MD + "\nFrom /tmp/prtbench-figure-1/cell00.\n", None, "/tmp/"),
])
def test_a_report_that_breaks_a_rule_fails_naming_it(tmp_path, md, csv_text, expected):
    problems = report_problems(_write(tmp_path, "table-x", md, csv_text))
    assert problems and expected in "; ".join(problems), problems


def test_a_csv_without_its_markdown_fails(tmp_path):
    problems = report_problems(_write(tmp_path, "table-orphan", None, GOOD_CSV))
    assert problems[0].startswith("no Markdown report")


def test_ordinary_report_text_is_no_machine_path():
    text = ("ratio k=128/k=64, FPS k=64 (1920×1080), results/reports-0123.sqlite, "
            "frame/work/ratio, https://example.org/x, p95/median, 4:3, a:b")
    assert not MACHINE_PATH.search(text)


def test_a_sha256_digest_is_not_a_commit():
    assert COMMIT.findall("sha256:" + "ab" * 32) == []


# --- the generators write what the checks need -----------------------------------------------

def _rows_frame(*, load: float):
    import pandas as pd

    return pd.DataFrame({"renderer": ["llvmpipe"], "timing_source": ["wall+finish"],
                         "device": ["AMD EPYC, 2 cores"], "git_sha": [SHA],
                         "load_average": [load], "reference_kind": ["path"],
                         "reference_noise": [0.01], "reference_spp": [256]})


@pytest.mark.parametrize("load, ok", [(1.2, True), (3.4, False)])
def test_a_paper_tables_markdown_carries_commit_load_and_cores(load, ok):
    from prtbench.bench.reproduction import Reproduction

    table = Reproduction()
    table.title, table.paper = "T", "P"
    md = table.markdown(["a"], [[1.0]], profile="quick", frame=_rows_frame(load=load))
    assert (provenance_problems(md) == []) is ok


def test_a_figures_caption_carries_commit_load_and_cores():
    from prtbench.bench.reproduction import provenance_line

    assert provenance_problems(provenance_line([_rows_frame(load=0.7)], profile="quick")) == []


def test_figures_stamp_their_own_measurement_rows_with_the_load():
    from reproductions.shared import with_load

    rows = with_load([{"a": 1}, {"a": 2, "load_average": 9.0}])
    assert isinstance(rows[0]["load_average"], float) and rows[1]["load_average"] == 9.0


def test_the_stability_report_carries_commit_load_and_cores():
    from prtbench.stability.report import format_csv, format_markdown

    rows = [{"method": "vertex", "case": f"c{i}", "group": "knob", "outcome": "ok",
             "reason": "", "scene": "plants", "git_sha": SHA, "profile": "quick",
             "device": "AMD EPYC, 2 cores", "load_1m": 0.5 + i, "timestamp": f"t{i}",
             "advice": "", "note": ""} for i in range(2)]
    assert provenance_problems(format_markdown(rows), format_csv(rows)) == []
    rows[1]["git_sha"] = OTHER
    assert "2 commits" in "; ".join(provenance_problems(format_markdown(rows), format_csv(rows)))


def test_the_pareto_report_carries_commit_load_and_cores_and_no_absolute_path(monkeypatch,
                                                                              tmp_path):
    from prtbench.tradeoff import pareto_report
    from prtbench.tradeoff.front import ParetoResult, Point

    monkeypatch.setattr(pareto_report, "git_sha", lambda *a, **k: SHA)
    monkeypatch.chdir(tmp_path)
    point = Point(method="vertex", config={}, scene="plants", variant="diffuse", light="sky",
                  profile="quick", width=320, height=240, error=20.0, error_unclipped=20.0,
                  clipped=False, ceiling_db=None, cost=5.0, views=1, rows=1, run_ids=["r1"],
                  timing_workers=[1], devices=["AMD EPYC, 2 cores"], renderers=["llvmpipe"],
                  git_shas=[SHA], loads=[0.8], dominated=False)
    result = ParetoResult(scene="plants", light="sky", error="psnr_masked", cost="frame_ms",
                          profile="quick", points=[point], skipped=[], correlation={}, paths=[])
    for store in (tmp_path / "results" / "prtbench.sqlite", Path("/elsewhere/prtbench.sqlite")):
        md = pareto_report.markdown_text(result, results_path=store,
                                         figure_name="pareto-plants-sky")
        assert provenance_problems(md) == [], md


# --- make reports: what counts as a dirty tree ------------------------------------------------

def _guard():
    spec = importlib.util.spec_from_file_location("reports_guard",
                                                  ROOT / "scripts" / "reports_guard.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_make_reports_ignores_its_outputs_and_scratch_but_not_code_or_new_files():
    guard = _guard()
    porcelain = "\0".join([
        " M reports/table-3.1.md", "?? reports/table-new.md", "?? out/demo/x.json",
        "?? results/prtbench.sqlite", "?? .cache/prtbench/a.npz",
        " M prtbench/bench/runner.py", "?? methods/new_family/spec.py",
        "R  prtbench/new_name.py", "prtbench/old_name.py", "M  Makefile", ""])
    assert guard.dirty_entries(porcelain, cache_folders=[".cache/prtbench"]) == [
        " M prtbench/bench/runner.py", "?? methods/new_family/spec.py",
        "R  prtbench/new_name.py", "M  Makefile"]
    assert guard.dirty_entries("", cache_folders=[]) == []
    # A cache outside the tree ignores nothing extra.
    assert guard.dirty_entries("?? .cache/prtbench/a.npz\0") == ["?? .cache/prtbench/a.npz"]


@pytest.mark.parametrize("flags, dry", [("n", True), ("kn -j2", True), ("k", False),
                                        ("", False), (" -- ALLOW_DIRTY=1", False)])
def test_make_reports_only_plans_under_make_n(monkeypatch, flags, dry):
    monkeypatch.setenv("MAKEFLAGS", flags)
    assert _guard().make_dry_run() is dry
