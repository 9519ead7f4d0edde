"""A method is a folder: the example of docs/ADDING_A_METHOD.md, dropped into a copy of
``methods/``, is listed, described and run with no other file edited; the same class from
another distribution registers through the ``prtbench.methods`` entry points."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
GUIDE = ROOT / "docs" / "ADDING_A_METHOD.md"
_BLOCK = re.compile(r"```(?:python|glsl)\n(?:#|//) (methods/[^\n]+)\n(.*?)```", re.S)


def guide_files() -> dict[str, str]:
    """The files the guide shows, by their path under the repository."""
    return {path: body for path, body in _BLOCK.findall(GUIDE.read_text())}


def _prtbench(argv: list[str], *, pythonpath: Path, env: dict[str, str]) -> subprocess.CompletedProcess:
    env = {**os.environ, **env,
           "PYTHONPATH": os.pathsep.join([str(pythonpath), os.environ.get("PYTHONPATH", "")])}
    return subprocess.run([sys.executable, "-m", "prtbench", *argv], capture_output=True,
                          text=True, env=env, cwd=pythonpath)


def test_the_guide_shows_a_whole_folder():
    files = guide_files()
    assert set(files) == {"methods/ambient/__init__.py", "methods/ambient/spec.py",
                          "methods/ambient/method.py", "methods/ambient/shaders/ambient.vert"}
    assert not (ROOT / "methods" / "ambient").exists()  # the example is not a shipped method


@pytest.fixture(scope="module")
def copy_with_the_example(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("house")
    shutil.copytree(ROOT / "methods", root / "methods",
                    ignore=shutil.ignore_patterns("__pycache__"))
    for path, body in guide_files().items():
        (root / path).parent.mkdir(parents=True, exist_ok=True)
        (root / path).write_text(body)
    return root


def test_a_new_folder_is_listed_described_and_run(copy_with_the_example, tmp_path):
    env = {"PRTBENCH_RESULTS": str(tmp_path / "r.sqlite")}
    listed = _prtbench(["list", "methods"], pythonpath=copy_with_the_example, env=env)
    assert listed.returncode == 0, listed.stderr
    line = next(l for l in listed.stdout.splitlines() if l.split()[0] == "ambient")
    assert "unshadowed SH irradiance at vertices" in line
    described = _prtbench(["describe", "ambient"], pythonpath=copy_with_the_example, env=env)
    assert described.returncode == 0, described.stderr
    assert "sh_bands" in described.stdout and "Ramamoorthi and Hanrahan 2001" in described.stdout
    ran = _prtbench(["run", "--method", "ambient", "--scene", "plants", "--profile", "smoke",
                     "--out", str(tmp_path / "out"), "--quiet"],
                    pythonpath=copy_with_the_example, env=env)
    assert ran.returncode == 0, ran.stderr
    psnr = float(re.search(r"^mean\s+([\d.]+)", ran.stdout, re.M).group(1))
    assert psnr > 15.0, ran.stdout  # a real image of plants (no shadows: below vertex PRT)
    assert (tmp_path / "out" / "ambient" / "plants-diffuse" / "sky" / "view00.exr").is_file()


def test_an_outside_distribution_registers_through_entry_points(tmp_path):
    """A plug-in package installed elsewhere (simulated: a dist-info folder on the path)."""
    site = tmp_path / "site"
    package = site / "outside_ambient"
    (package / "shaders").mkdir(parents=True)
    files = guide_files()
    method = files["methods/ambient/method.py"]
    method = method.replace("from methods.ambient import SHADER_DIR\n", "")
    method = method.replace('@register_method("ambient")', '@register_method("outside-ambient")')
    method = method.replace('Artifact("ambient"', 'Artifact("outside-ambient"')
    method = method.replace("class AmbientRenderer(RasterRenderer):",
                            "SHADER_DIR = Path(__file__).resolve().parent / 'shaders'\n\n\n"
                            "class AmbientRenderer(RasterRenderer):")
    method = method.replace("from dataclasses import dataclass\n",
                            "from dataclasses import dataclass\nfrom pathlib import Path\n")
    (package / "__init__.py").write_text("")
    (package / "method.py").write_text(method)
    (package / "shaders" / "ambient.vert").write_text(files["methods/ambient/shaders/ambient.vert"])
    info = site / "outside_ambient-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: outside-ambient\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(
        "[prtbench.methods]\noutside-ambient = outside_ambient.method:Ambient\n")
    env = {"PRTBENCH_RESULTS": str(tmp_path / "r.sqlite")}
    listed = _prtbench(["list", "methods"], pythonpath=site, env=env)
    assert listed.returncode == 0 and "outside-ambient" in listed.stdout, listed.stderr
    ran = _prtbench(["run", "--method", "outside-ambient", "--scene", "plants", "--profile",
                     "smoke", "--out", str(tmp_path / "out"), "--quiet"], pythonpath=site,
                    env=env)
    assert ran.returncode == 0, ran.stderr
    assert "method=outside-ambient" in ran.stdout
