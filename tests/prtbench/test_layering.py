"""Dependency direction (DESIGN.md §1): the core imports nothing from the plug-in packages.

``prtbench`` may only reach ``methods``, ``scenes`` and ``reproductions`` through its registries
(lazy ``"module:attr"`` entry points); the GLSL it needs lives in ``prtbench/shaders``.
"""

from __future__ import annotations

import ast
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

import prtbench
from prtbench.render import gl

PLUGINS = ("methods", "scenes", "reproductions")
CORE = Path(prtbench.__file__).resolve().parent
ROOT = CORE.parent
METHOD_SHADERS = [p for p in (ROOT / "methods").rglob("shaders") if p.is_dir()]
_INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.MULTILINE)
#: Includes generated at run time and handed to load_program as virtual files.
GENERATED = {"scene_sdf.glsl", "learnt_weights.glsl", "learnt_partition_data.glsl"}


def _plugin_imports(path: Path) -> list[str]:
    found = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names = [node.module]
        else:
            continue
        found += [f"{path.name}:{node.lineno} imports {n}"
                  for n in names if n.split(".")[0] in PLUGINS]
    return found


def test_core_sources_import_no_plugin_package():
    files = sorted(CORE.rglob("*.py"))
    assert len(files) > 20  # the scan really covers the core
    offenders = [hit for path in files for hit in _plugin_imports(path)]
    assert offenders == []


def test_the_scan_sees_an_import(tmp_path):
    # The AST scan above must catch both spellings, including imports inside functions.
    sample = tmp_path / "probe.py"
    sample.write_text("from . import gl\nimport numpy\n\n"
                      "def f():\n    import methods\n    from scenes.plants import build\n")
    hits = _plugin_imports(sample)
    assert [h.split(" imports ")[1] for h in hits] == ["methods", "scenes.plants"]


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
    with pytest.raises(prtbench.api.errors.UnknownNameError, match="vertex_prt.vert"):
        gl.load_program(ctx, "vertex_prt.vert", "interpolated_radiance.frag", defines=defines)
