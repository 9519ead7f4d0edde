"""`prtbench regress --junit FILE` and `--cases FILE`: the JUnit XML CI systems read, and a team's
own cases (a scene file, any registered method) with a baseline file of their own.

Most tests replace :func:`prtbench.bench.regress.measure` by a fixed measurement (no rendering),
as tests/prtbench/bench/test_regress.py does; one test renders a real case on a box-and-ground
.glb exported by trimesh into the test's folder.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from prtbench.api.errors import InvalidInputError
from prtbench.bench import regress as regress_mod
from prtbench.bench.regress import TOLERANCES, Measurement, RegressionCase, regress
from prtbench.bench.regress_report import Check, junit_tree
from prtbench.bench.trivial import PSNR_MARGIN_DB
from prtbench.cli import main

GOOD = {"psnr_masked": 22.0, "ssim_masked": 0.6, "flip_masked": 0.15, "mae": 0.04}
TRIVIAL = {"flat": {"psnr_masked": 17.0, "flip_masked": 0.40},
           "half": {"psnr_masked": 16.0, "flip_masked": 0.48}}
CASES = ["vertex", "sloan-matrix:cpca"]


@pytest.fixture
def fake(monkeypatch):
    """Replace measure() by a fixed Measurement per case; returns what it will report.

    ``state["metrics"][name]`` overrides one case's metrics, ``state["broken"][name]`` makes it
    raise that exception.
    """
    state = {"metrics": {}, "broken": {}, "measured": []}

    def measure(case):
        name = case.name if isinstance(case, RegressionCase) else case
        state["measured"].append(name)
        if name in state["broken"]:
            raise state["broken"][name]
        record = (dict(case.record) if isinstance(case, RegressionCase)
                  else regress_mod._case_of(name))
        return Measurement(record, dict(state["metrics"].get(name, GOOD)),
                           {k: dict(v) for k, v in TRIVIAL.items()})

    monkeypatch.setattr(regress_mod, "measure", measure)
    return state


def _entry(case, metrics=GOOD):
    return {"case": case, "metrics": {m: {"value": metrics[m], "tolerance": TOLERANCES[m]}
                                      for m in TOLERANCES}}


def _baselines(tmp_path: Path, names=CASES) -> Path:
    path = tmp_path / "metrics.json"
    path.write_text(json.dumps({n: _entry(regress_mod._case_of(n)) for n in names}))
    return path


def _testcases(path: Path) -> dict[tuple[str, str], ET.Element]:
    root = ET.parse(path).getroot()
    assert root.tag == "testsuites"
    return {(c.get("classname"), c.get("name")): c for c in root.iter("testcase")}


def _suite(path: Path) -> dict[str, str]:
    return dict(ET.parse(path).getroot().find("testsuite").attrib)


# --- the XML -------------------------------------------------------------------------------------

def test_a_testcase_per_case_and_metric_plus_the_gate_and_failures_carry_the_numbers(
        fake, tmp_path, capsys):
    path, junit = _baselines(tmp_path), tmp_path / "ci" / "regress.xml"
    drift = GOOD["psnr_masked"] - 1.5 * TOLERANCES["psnr_masked"]
    fake["metrics"]["sloan-matrix:cpca"] = {**GOOD, "psnr_masked": drift}
    assert main(["regress", "--baselines", str(path), "--junit", str(junit), "--workers", "0",
                 *[a for n in CASES for a in ("--method", n)]]) == 1
    out = capsys.readouterr().out
    assert "sloan-matrix:cpca: psnr_masked = 20.5000 (baseline 22.0000 ± 1.0) FAIL" in out

    cases = _testcases(junit)
    assert set(cases) == {(f"prtbench.regress.{n}", t) for n in CASES
                          for t in ["trivial-images", *TOLERANCES]}
    suite = _suite(junit)
    assert (suite["tests"], suite["failures"], suite["errors"]) == ("10", "1", "0")
    failure = cases[("prtbench.regress.sloan-matrix:cpca", "psnr_masked")].find("failure")
    assert failure is not None
    assert "20.5000" in failure.get("message") and "22.0000 ± 1.0" in failure.get("message")
    assert "value: 20.5" in failure.text and "baseline: 22.0" in failure.text
    assert "tolerance: 1.0" in failure.text
    props = {p.get("name"): float(p.get("value"))
             for p in cases[("prtbench.regress.sloan-matrix:cpca", "psnr_masked")].iter("property")}
    assert props == {"value": drift, "baseline": 22.0, "tolerance": 1.0}
    passed = cases[("prtbench.regress.vertex", "psnr_masked")]
    assert passed.find("failure") is None and passed.find("error") is None
    assert "within the tolerance" in passed.find("system-out").text
    gate = cases[("prtbench.regress.vertex", "trivial-images")]
    assert gate.find("failure") is None
    assert "trivial flat: psnr_masked=17.0000" in gate.find("system-out").text


def test_a_gate_failure_names_the_trivial_image_not_beaten(fake, tmp_path):
    weak = {**GOOD, "psnr_masked": TRIVIAL["flat"]["psnr_masked"] + 0.5 * PSNR_MARGIN_DB}
    path, junit = tmp_path / "metrics.json", tmp_path / "regress.xml"
    path.write_text(json.dumps({"vertex": _entry(regress_mod._case_of("vertex"), weak)}))
    fake["metrics"]["vertex"] = weak
    assert regress(methods=["vertex"], baseline_path=path, junit_path=junit) is False
    cases = _testcases(junit)
    failure = cases[("prtbench.regress.vertex", "trivial-images")].find("failure")
    assert "does not beat the flat image" in failure.get("message")
    assert "half" not in failure.get("message")  # 17.5 dB beats the half image's 16 dB
    assert all(cases[("prtbench.regress.vertex", m)].find("failure") is None for m in TOLERANCES)


def test_a_case_that_could_not_run_is_an_error_on_each_of_its_testcases(fake, tmp_path, capsys):
    path, junit = _baselines(tmp_path), tmp_path / "regress.xml"
    # An ANSI colour escape, as worker logs carry: XML 1.0 cannot hold it raw.
    fake["broken"]["vertex"] = RuntimeError("\x1b[31mGL context lost\x1b[0m")
    assert regress(methods=CASES, baseline_path=path, junit_path=junit) is False
    out = capsys.readouterr().out
    assert out.count("vertex: FAIL the case could not run: RuntimeError:") == 1
    cases = _testcases(junit)
    errors = [cases[("prtbench.regress.vertex", t)].find("error")
              for t in ["trivial-images", *TOLERANCES]]
    assert all(e is not None and "GL context lost" in e.get("message") for e in errors)
    assert (_suite(junit)["errors"], _suite(junit)["failures"]) == ("5", "0")
    assert cases[("prtbench.regress.sloan-matrix:cpca", "mae")].find("error") is None


def test_a_missing_baseline_is_a_failing_baseline_testcase(fake, tmp_path):
    path, junit = _baselines(tmp_path, ["vertex"]), tmp_path / "regress.xml"
    assert regress(methods=CASES, baseline_path=path, junit_path=junit) is False
    cases = _testcases(junit)
    failure = cases[("prtbench.regress.sloan-matrix:cpca", "baseline")].find("failure")
    assert "no baseline" in failure.get("message")
    assert ("prtbench.regress.vertex", "baseline") not in cases


def test_update_writes_the_gate_and_baseline_testcases(fake, tmp_path):
    path, junit = tmp_path / "new.json", tmp_path / "update.xml"
    assert regress(update=True, methods=["vertex"], baseline_path=path, junit_path=junit)
    cases = _testcases(junit)
    assert set(cases) == {("prtbench.regress.vertex", "trivial-images"),
                          ("prtbench.regress.vertex", "baseline")}
    assert _suite(junit)["failures"] == "0"
    assert ET.parse(junit).getroot().find(".//property[@name='mode']").get("value") == "update"
    # One case below the flat image: nothing is written, and the XML says so for the other.
    fake["metrics"]["sloan-matrix:cpca"] = {**GOOD, "psnr_masked": 16.5}
    before = path.read_text()
    assert not regress(update=True, methods=CASES, baseline_path=path, junit_path=junit)
    assert path.read_text() == before
    cases = _testcases(junit)
    assert cases[("prtbench.regress.sloan-matrix:cpca", "trivial-images")].find("failure") \
        is not None
    passed = cases[("prtbench.regress.vertex", "baseline")]
    assert passed.find("failure") is None
    assert "not written, as sloan-matrix:cpca failed" in passed.find("system-out").text
    assert ET.parse(junit).getroot().find("testsuite").get("failures") == "1"


@pytest.mark.parametrize("where", ["folder", "under-a-file"])
def test_junit_on_a_folder_is_a_one_line_error_before_any_work(fake, tmp_path, capsys, where):
    path = _baselines(tmp_path)
    (tmp_path / "file").write_text("x")
    junit = tmp_path if where == "folder" else tmp_path / "file" / "regress.xml"
    assert main(["regress", "--method", "vertex", "--baselines", str(path),
                 "--junit", str(junit)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("prtbench: error: --junit") and len(err.strip().splitlines()) == 1
    assert fake["measured"] == []  # no work done
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file", "metrics.json"]


def test_the_junit_file_is_written_atomically_only_at_the_end(fake, tmp_path, monkeypatch):
    path, junit = _baselines(tmp_path), tmp_path / "regress.xml"
    junit.write_text("previous run")
    seen = []
    measure = regress_mod.measure  # the fixture's, wrapped to look at the file while cases run

    def looking(case):
        seen.append(junit.read_text())
        return measure(case)

    monkeypatch.setattr(regress_mod, "measure", looking)
    assert regress(methods=["vertex"], baseline_path=path, junit_path=junit)
    assert seen == ["previous run"] and fake["measured"] == ["vertex"]
    assert ET.parse(junit).getroot().tag == "testsuites"
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


def test_junit_tree_counts_and_nan():
    checks = [Check("a", "mae", "fail", "mae = nan", lines=("mae = nan FAIL",),
                    value=float("nan"), baseline=0.1, tolerance=0.01),
              Check("a", "trivial-images", "ok", "beats flat", lines=("gate ok",), seconds=2.5)]
    root = junit_tree(checks, seconds=3.0).getroot()
    suite = root.find("testsuite")
    assert (suite.get("tests"), suite.get("failures"), suite.get("errors")) == ("2", "1", "0")
    assert root.find(".//testcase[@name='mae']/properties/property[@name='value']").get(
        "value") == "nan"
    assert root.find(".//testcase[@name='trivial-images']").get("time") == "2.500"
    with pytest.raises(ValueError, match="check status 'passed'"):
        Check("a", "mae", "passed", "")


# --- cases files ----------------------------------------------------------------------------------

def _cases_file(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "cases.toml"
    path.write_text(text)
    return path


def test_a_cases_file_replaces_the_built_in_cases(fake, tmp_path, capsys):
    cases = _cases_file(tmp_path, """
[[case]]
name = "plants-sun"
method = "vertex"
scene = "plants"
light = "sun"
scene_params = { ground_subdivisions = 16 }
overrides = { sh_bands = 3 }

[[case]]
name = "cornell-tpfl"
method = "texture-tpfl"
scene = "cornell"
""")
    path, junit = tmp_path / "mine.json", tmp_path / "regress.xml"
    assert main(["regress", "--cases", str(cases), "--baselines", str(path), "--update",
                 "--workers", "0"]) == 0  # the fake measures in this process only
    stored = json.loads(path.read_text())
    assert set(stored) == {"plants-sun", "cornell-tpfl"}
    assert stored["plants-sun"]["case"] == {
        "method": "vertex", "scene": "plants", "variant": "diffuse", "light": "sun",
        "scene_params": {"ground_subdivisions": 16}, "overrides": {"sh_bands": 3}}
    assert stored["cornell-tpfl"]["case"]["light"] == "sky"  # the default
    assert sorted(fake["measured"]) == ["cornell-tpfl", "plants-sun"]
    capsys.readouterr()
    assert main(["regress", "--cases", str(cases), "--baselines", str(path),
                 "--method", "plants-sun", "--junit", str(junit)]) == 0
    out = capsys.readouterr().out
    assert "plants-sun: psnr_masked = 22.0000 (baseline 22.0000 ± 1.0) ok" in out
    assert {c for c, _ in _testcases(junit)} == {"prtbench.regress.plants-sun"}
    # The file's cases only: a built-in name is unknown here, before any work.
    fake["measured"].clear()
    assert main(["regress", "--cases", str(cases), "--baselines", str(path),
                 "--method", "vertex"]) == 2
    assert "unknown regression case 'vertex'" in capsys.readouterr().err
    assert fake["measured"] == []
    # A changed case makes its baseline stale: a FAIL asking for --update.
    cases.write_text(cases.read_text().replace("sh_bands = 3", "sh_bands = 4"))
    assert main(["regress", "--cases", str(cases), "--baselines", str(path),
                 "--method", "plants-sun"]) == 1
    assert "plants-sun: FAIL baseline recorded on case" in capsys.readouterr().out


def test_cases_need_their_own_baseline_file(fake, tmp_path, capsys):
    cases = _cases_file(tmp_path, '[[case]]\nname = "a"\nmethod = "vertex"\nscene = "plants"\n')
    with pytest.raises(InvalidInputError, match="needs --baselines"):
        regress(cases_path=cases)
    assert main(["regress", "--cases", str(cases)]) == 2
    assert "--cases" in capsys.readouterr().err and fake["measured"] == []


_CASE = 'name = "a"\nmethod = "vertex"\nscene = "plants"\n'
_BAD_FILES = {
    "malformed": ("[[case]\n", "malformed TOML"),
    "top-level-key": (f'profile = "quick"\n[[case]]\n{_CASE}', "unknown top-level key 'profile'"),
    "no-cases": ('[other]\nx = 1\n', "unknown top-level key 'other'"),
    "empty": ("", "no [[case]] tables"),
    "case-key": (f'[[case]]\n{_CASE}views = 2\n', "unknown [[case]] key 'views'"),
    "no-name": ('[[case]]\nmethod = "vertex"\nscene = "plants"\n', "no 'name'"),
    "bad-name": ('[[case]]\nname = "a b"\nmethod = "vertex"\nscene = "plants"\n',
                 "name = 'a b'; accepted: letters"),
    "twice": (f"[[case]]\n{_CASE}[[case]]\n{_CASE}", "case name 'a' appears twice"),
    "no-method": ('[[case]]\nname = "a"\nscene = "plants"\n', "case 'a': no 'method'"),
    "method": ('[[case]]\nname = "a"\nmethod = "vertx"\nscene = "plants"\n',
               "unknown method 'vertx'; did you mean 'vertex'?"),
    "method-type": ('[[case]]\nname = "a"\nmethod = 3\nscene = "plants"\n', "'method' = 3"),
    "scene": ('[[case]]\nname = "a"\nmethod = "vertex"\nscene = "plnts"\n',
              "unknown scene 'plnts'; did you mean 'plants'?"),
    "scene-file": ('[[case]]\nname = "a"\nmethod = "vertex"\nscene = "missing.glb"\n',
                   "missing.glb': no such file"),
    "variant": (f'[[case]]\n{_CASE}variant = "shiny"\n', "unknown variant 'shiny'"),
    "light": (f'[[case]]\n{_CASE}light = "skyy"\n', "unknown light 'skyy'"),
    "light-file": (f'[[case]]\n{_CASE}light = "missing.exr"\n', "missing.exr' does not exist"),
    "knob": (f"[[case]]\n{_CASE}overrides = {{ bands = 3 }}\n", "unknown knob 'bands'"),
    "knob-value": (f"[[case]]\n{_CASE}overrides = {{ sh_bands = 99 }}\n", "sh_bands"),
    "overrides-type": (f'[[case]]\n{_CASE}overrides = "sh_bands=3"\n',
                       "'overrides' = 'sh_bands=3'"),
    "scene-param": (f"[[case]]\n{_CASE}scene_params = {{ leaves = 3 }}\n",
                    "has no parameter 'leaves'"),
    "date": (f"[[case]]\n{_CASE}scene_params = {{ when = 2024-01-01 }}\n", "no dates"),
}


@pytest.mark.parametrize("kind", sorted(_BAD_FILES))
def test_a_bad_cases_file_is_a_one_line_error_naming_the_key_and_nothing_is_written(
        fake, tmp_path, capsys, monkeypatch, kind):
    monkeypatch.setenv("PRTBENCH_CACHE", str(tmp_path / "user-cache"))
    text, expected = _BAD_FILES[kind]
    cases, path = _cases_file(tmp_path, text), tmp_path / "mine.json"
    junit = tmp_path / "regress.xml"
    assert main(["regress", "--cases", str(cases), "--baselines", str(path), "--update",
                 "--junit", str(junit)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"prtbench: error: cases file '{cases}'") and expected in err, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert fake["measured"] == [] and not path.exists() and not junit.exists()
    assert not (tmp_path / "user-cache").exists()


def test_a_missing_cases_file_is_an_error(fake, tmp_path, capsys):
    assert main(["regress", "--cases", str(tmp_path / "absent.toml"), "--baselines",
                 str(tmp_path / "b.json")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("prtbench: error: cases file") and "not found" in err


# --- a team's scene file -----------------------------------------------------------------------

def _export_box_and_ground(path: Path, *, height: float = 1.0) -> None:
    """A 1 m box on a 3 m ground slab, tessellated to 10 cm (vertex PRT shades at vertices)."""
    trimesh = pytest.importorskip("trimesh")
    box = trimesh.creation.box(extents=(1.0, height, 1.0)).subdivide_to_size(max_edge=0.1)
    box.apply_translation((0.0, height / 2, 0.0))
    ground = trimesh.creation.box(extents=(3.0, 0.02, 3.0)).subdivide_to_size(max_edge=0.1)
    ground.apply_translation((0.0, -0.01, 0.0))
    trimesh.Scene({"box": box, "ground": ground}).export(path)


_CRATE = """
[[case]]
name = "crate-vertex"
method = "vertex"
scene = "scenes/crate.glb"        # relative to this file, not to the working directory
"""


def test_an_edited_scene_file_makes_its_baseline_stale(fake, tmp_path, capsys):
    (tmp_path / "scenes").mkdir()
    _export_box_and_ground(tmp_path / "scenes" / "crate.glb")
    cases, path = _cases_file(tmp_path, _CRATE), tmp_path / "baselines.json"
    assert main(["regress", "--cases", str(cases), "--baselines", str(path), "--update"]) == 0
    entry = json.loads(path.read_text())["crate-vertex"]
    assert entry["case"]["scene"] == "scenes/crate.glb" and len(entry["case"]["scene_sha256"]) == 64
    assert main(["regress", "--cases", str(cases), "--baselines", str(path)]) == 0
    _export_box_and_ground(tmp_path / "scenes" / "crate.glb", height=1.5)  # same name
    capsys.readouterr()
    assert main(["regress", "--cases", str(cases), "--baselines", str(path)]) == 1
    assert "crate-vertex: FAIL baseline recorded on case" in capsys.readouterr().out


@pytest.mark.slow  # the CI guide's cases-file test runs a scene-file case in make test
def test_a_scene_file_case_runs_and_writes_its_own_baseline(tmp_path, monkeypatch, capsys):
    """The real thing: a .glb exported here, rendered, referenced, gated and compared."""
    (tmp_path / "scenes").mkdir()
    _export_box_and_ground(tmp_path / "scenes" / "crate.glb")
    cases, path = _cases_file(tmp_path, _CRATE), tmp_path / "baselines.json"
    junit, cache = tmp_path / "out" / "regress.xml", tmp_path / "cache"
    monkeypatch.chdir(tmp_path / "scenes")  # paths in the file are not relative to the cwd
    monkeypatch.setenv("PRTBENCH_CACHE", str(tmp_path / "user-cache"))
    # One cache for both runs: the comparison reuses the update's transfer and reference.
    assert main(["regress", "--cases", str(cases), "--baselines", str(path), "--update",
                 "--cache", str(cache)]) == 0, capsys.readouterr().out
    assert "crate-vertex: gate ok" in capsys.readouterr().out
    entry = json.loads(path.read_text())["crate-vertex"]
    assert entry["case"]["method"] == "vertex" and set(entry["metrics"]) == set(TOLERANCES)
    assert main(["regress", "--cases", str(cases), "--baselines", str(path), "--cache",
                 str(cache), "--junit", str(junit)]) == 0
    out = capsys.readouterr().out
    assert "crate-vertex: psnr_masked = " in out and "FAIL" not in out
    assert set(_testcases(junit)) == {("prtbench.regress.crate-vertex", t)
                                      for t in ["trivial-images", *TOLERANCES]}
    assert (_suite(junit)["failures"], _suite(junit)["errors"]) == ("0", "0")
    assert not (tmp_path / "user-cache").exists()  # validation and runs used --cache only


# --- docs/ci.md: a team's plug-in method and scene, end to end ----------------------------------

ROOT = Path(__file__).resolve().parents[3]
_GUIDE_BLOCK = re.compile(r"```(?:python|glsl)\n(?:#|//) (methods/[^\n]+)\n(.*?)```", re.DOTALL)
_CI_BLOCK = re.compile(r"```(?:python|toml)\n# ([\w./-]+)[^\n]*\n(.*?)```", re.DOTALL)


def _ci_files() -> tuple[dict[str, str], list[tuple[str, str]]]:
    """docs/ci.md's files by path, and its diff of method.py as (old line, new line) pairs."""
    text = (ROOT / "docs" / "ci.md").read_text()
    files = dict(_CI_BLOCK.findall(text))
    diff = re.search(r"```diff\n(.*?)```", text, re.DOTALL).group(1).splitlines()
    removed = [line[1:] for line in diff if line.startswith("-") and not line.startswith("---")]
    added = [line[1:] for line in diff if line.startswith("+") and not line.startswith("+++")]
    assert len(removed) == len(added) == 3
    return files, list(zip(removed, added))


def test_the_ci_guides_plug_in_and_scene_run_as_a_cases_file(tmp_path):
    """docs/ci.md section 6: the plug-in (ADDING_A_METHOD.md's method with the page's diff,
    registered by its pyproject's entry point: a dist-info folder on the path stands for
    `pip install`), the scene script and the cases file, run by `prtbench regress --update`."""
    import tomllib

    files, diff = _ci_files()
    guide = dict(_GUIDE_BLOCK.findall((ROOT / "docs" / "ADDING_A_METHOD.md").read_text()))
    site, package = tmp_path / "site", tmp_path / "site" / "acme_prt"
    (package / "shaders").mkdir(parents=True)
    method = guide["methods/ambient/method.py"]
    for old, new in diff:
        assert method.count(old + "\n") == 1, old
        method = method.replace(old + "\n", new + "\n")
    (package / "method.py").write_text(method)
    (package / "__init__.py").write_text(files["acme-prt/acme_prt/__init__.py"])
    (package / "shaders" / "ambient.vert").write_text(guide["methods/ambient/shaders/ambient.vert"])
    project = tomllib.loads(files["acme-prt/pyproject.toml"])["project"]
    info = site / f"{project['name'].replace('-', '_')}-{project['version']}.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {project['name']}\n"
                                   f"Version: {project['version']}\n")
    points = project["entry-points"]["prtbench.methods"]
    (info / "entry_points.txt").write_text(
        "[prtbench.methods]\n" + "".join(f"{k} = {v}\n" for k, v in points.items()))
    (tmp_path / "scenes").mkdir()
    (tmp_path / "scenes" / "make_crate.py").write_text(files["scenes/make_crate.py"])
    (tmp_path / "cases.toml").write_text(files["cases.toml"])
    env = {**os.environ,
           "PYTHONPATH": os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")])}
    subprocess.run([sys.executable, "scenes/make_crate.py"], cwd=tmp_path, env=env, check=True)
    done = subprocess.run([sys.executable, "-m", "prtbench", "regress", "--cases", "cases.toml",
                           "--baselines", "baselines.json", "--update", "--method", "crate-acme",
                           "--workers", "0"], cwd=tmp_path, env=env, capture_output=True, text=True,
                          check=False)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "crate-acme: gate ok" in done.stdout
    entry = json.loads((tmp_path / "baselines.json").read_text())["crate-acme"]
    assert entry["case"]["method"] == "acme-ambient" and entry["case"]["light"] == "sun"
