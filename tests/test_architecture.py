"""The house's rules (docs/ARCHITECTURE.md): the import contract, no method named in the core,
small modules, GLSL beside the code that loads it.

The contract itself is :mod:`tests.import_contract`; the tests here run it on the tree and on
planted faults, so a check that cannot fail is a failing test.
"""

from __future__ import annotations

import ast
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

import prtbench
from prtbench.api.errors import UnknownNameError
from prtbench.api.method import METHODS
from prtbench.render import gl
from tests.import_contract import LAYERS, PLUGINS, violations

CORE = Path(prtbench.__file__).resolve().parent
ROOT = CORE.parent
METHOD_SHADERS = [p for p in (ROOT / "methods").rglob("shaders") if p.is_dir()]
_INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.MULTILINE)
#: Includes generated at run time and handed to load_program as virtual files.
GENERATED = {"scene_sdf.glsl", "learnt_weights.glsl", "learnt_partition_data.glsl",
             "probe_decode.glsl"}
#: Modules allowed past :data:`MAX_LINES`: one noun's catalogue each (docs/ARCHITECTURE.md).
CATALOGUES = {"prtbench/transport/sdf/nodes.py"}
MAX_LINES = 500


def test_the_tree_keeps_the_import_contract():
    assert violations(ROOT) == []


def test_every_core_package_is_a_layer():
    packages = {p.name for p in CORE.iterdir() if (p / "__init__.py").is_file()}
    assert packages == set(LAYERS)
    loose = {p.name for p in CORE.glob("*.py")} - {"__init__.py", "__main__.py"}
    assert loose == set()


def _plant(tmp_path: Path, files: dict[str, str]) -> Path:
    """A copy of the core and plug-ins with ``files`` added or replaced."""
    root = tmp_path / "tree"
    for package in ("prtbench", *PLUGINS):
        shutil.copytree(ROOT / package, root / package,
                        ignore=shutil.ignore_patterns("__pycache__", "*.glsl", "*.vert", "*.frag"))
    for name, text in files.items():
        (root / name).write_text(text)
    return root


def test_a_planted_upward_import_breaks_the_contract(tmp_path):
    root = _plant(tmp_path, {"prtbench/api/planted.py": "from prtbench.bench import runner\n"})
    assert violations(root) == [
        "prtbench.api.planted:1: upward import of prtbench.bench.runner (bench) from the api layer"]


def test_a_planted_cycle_inside_a_function_body_breaks_the_contract(tmp_path):
    root = _plant(tmp_path, {
        "prtbench/store/planted_a.py": "from prtbench.store import planted_b\n",
        "prtbench/store/planted_b.py": "def f():\n    from prtbench.store import planted_a\n"})
    found = violations(root)
    assert "import cycle: prtbench.store.planted_a -> prtbench.store.planted_b -> " \
           "prtbench.store.planted_a" in found
    assert any("planted_b:2: imports prtbench.store.planted_a inside a function" in f
               for f in found)


def test_only_heavy_backends_may_be_deferred(tmp_path):
    root = _plant(tmp_path, {"prtbench/api/planted.py":
                             "def f():\n    import torch\n    import json\n"})
    assert violations(root) == ["prtbench.api.planted:3: imports json inside a function (only "
                                "heavy backends may be deferred)"]


def test_a_method_family_may_not_import_another(tmp_path):
    root = _plant(tmp_path, {"methods/wavelet/planted.py": "from methods.vertex import glossy\n"})
    assert len(violations(root)) == 1 and "family wavelet imports another family" in \
        violations(root)[0]


def _strings(path: Path) -> list[tuple[int, str, bool]]:
    """(line, text, is_docstring) of every string constant of a module."""
    tree = ast.parse(path.read_text())
    docs = {id(n.body[0].value) for n in ast.walk(tree)
            if isinstance(n, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
            and n.body and isinstance(n.body[0], ast.Expr)
            and isinstance(n.body[0].value, ast.Constant)}
    return [(n.lineno, n.value, id(n) in docs) for n in ast.walk(tree)
            if isinstance(n, ast.Constant) and isinstance(n.value, str)]


def _method_names_in(path: Path, names: list[str], *, root: Path = ROOT) -> list[str]:
    """A string equal to a method's name, or a docstring naming a hyphenated one."""
    hyphenated = [n for n in names if "-" in n]
    found = []
    for line, text, is_doc in _strings(path):
        if not is_doc and text in names:
            found.append(f"{path.relative_to(root)}:{line}: '{text}'")
        elif is_doc:
            found += [f"{path.relative_to(root)}:{line}: '{n}' in a docstring"
                      for n in hyphenated if re.search(rf"(?<![\w-]){re.escape(n)}(?![\w-])", text)]
    return found


def test_the_core_names_no_registered_method():
    names = METHODS.names()
    assert "vertex" in names and len(names) >= 16
    found = [hit for path in sorted(CORE.rglob("*.py")) for hit in _method_names_in(path, names)]
    assert found == []


def test_the_method_name_scan_sees_a_name(tmp_path):
    sample = tmp_path / "probe.py"
    sample.write_text('"""Uses texture-tpfl."""\nX = ("vertex", "per vertex")\n')
    assert _method_names_in(sample, METHODS.names(), root=tmp_path) == [
        "probe.py:1: 'texture-tpfl' in a docstring", "probe.py:2: 'vertex'"]


def test_importing_every_core_module_loads_no_plugin():
    code = ("import importlib, pkgutil, sys, prtbench\n"
            "mods = [m.name for m in pkgutil.walk_packages(prtbench.__path__, 'prtbench.')]\n"
            "for name in mods: importlib.import_module(name)\n"
            f"bad = sorted(n for n in sys.modules if n.split('.')[0] in {PLUGINS!r})\n"
            "print(len(mods), bad)\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          cwd=ROOT, check=True)
    count, bad = done.stdout.strip().split(" ", 1)
    assert int(count) > 20 and bad == "[]", done.stdout


def test_no_module_is_over_five_hundred_lines_but_the_catalogues():
    long = {str(p.relative_to(ROOT)): len(p.read_text().splitlines())
            for package in ("prtbench", *PLUGINS) for p in (ROOT / package).rglob("*.py")}
    assert {name for name, n in long.items() if n > MAX_LINES} <= CATALOGUES, \
        {name: n for name, n in long.items() if n > MAX_LINES and name not in CATALOGUES}
    architecture = (ROOT / "docs" / "ARCHITECTURE.md").read_text()
    for name in CATALOGUES:
        assert name in architecture  # each exception says why, there


def test_core_shaders_are_package_data_and_resolve_in_the_core():
    assert gl.shader_dir() == CORE / "render" / "shaders"
    shaders = sorted(p for p in (CORE / "render" / "shaders").iterdir() if p.is_file())
    names = {p.name for p in shaders}
    assert {"sh.glsl", "brdf.glsl", "prt_shading.glsl", "sdf_trace.glsl", "sdf_gbuffer.frag",
            "sdf_fullscreen.vert", "sdf_occlusion.frag", "sdf_points.frag"} <= names
    patterns = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"][
        "package-data"]["prtbench"]
    for path in shaders:
        assert any(path.relative_to(CORE).match(p) for p in patterns), path.name
    for path in shaders:  # a core shader never includes a method's file
        missing = set(_INCLUDE.findall(path.read_text())) - names - GENERATED
        assert not missing, f"{path.name} includes {missing}"
    assert not names & {p.name for d in METHOD_SHADERS for p in d.iterdir()}  # moved, not copied


def test_method_shader_includes_resolve_in_method_then_core_folders():
    method_names = {p.name for d in METHOD_SHADERS for p in d.iterdir()}
    core_names = {p.name for p in (CORE / "render" / "shaders").iterdir()}
    uses_core = []
    for path in sorted(p for d in METHOD_SHADERS for p in d.iterdir()):
        includes = set(_INCLUDE.findall(path.read_text()))
        assert not includes - method_names - core_names - GENERATED, path.name
        if includes & core_names:
            uses_core.append(path.name)
    assert {"vertex_prt.vert", "texture_prt.frag", "learnt_sdf.frag"} <= set(uses_core)


@pytest.fixture(scope="module")
def ctx():
    try:
        return gl.create_context()
    except gl.GLUnavailableError as exc:
        pytest.skip(str(exc))


def test_load_program_finds_core_includes_from_a_method_folder(ctx):
    from methods.vertex import SHADER_DIR

    # vertex_prt.vert (methods/vertex/shaders) includes brdf.glsl, which lives in the core.
    defines = {"SH_COEFFS": 9, "TRANSFER_CHANNELS": 1}
    program = gl.load_program(ctx, "vertex_prt.vert", "interpolated_radiance.frag", defines=defines,
                              search_path=[SHADER_DIR])
    assert "light_sh" in program and "clip_from_world" in program
    # Without the method's folder the core does not know the method's stages.
    with pytest.raises(UnknownNameError, match="vertex_prt.vert"):
        gl.load_program(ctx, "vertex_prt.vert", "interpolated_radiance.frag", defines=defines)
