"""`prtbench list methods` (name + summary, no heavy import) and `prtbench describe METHOD`."""

from __future__ import annotations

import dataclasses
import re
import subprocess
import sys
import typing

import pytest

from prtbench.api.method import METHODS
from prtbench.api.registry import Registry
from prtbench.cli import main

HEAVY = ("torch", "moderngl", "embreex", "mitsuba", "drjit")


def _subprocess(argv: list[str]) -> subprocess.CompletedProcess:
    code = ("import sys; from prtbench.cli import main\n"
            f"status = main({argv!r})\n"
            f"print('HEAVY', [m for m in {HEAVY!r} if m in sys.modules], 'STATUS', status)")
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)


def _declared_methods() -> set[str]:
    """The methods the family folders' spec modules declare (read as text, not imported)."""
    from pathlib import Path

    root = Path(__file__).resolve().parents[3] / "methods"
    return {m.group(1) for spec in root.glob("*/spec.py")
            for m in re.finditer(r'MethodSpec\(\s*"([a-z0-9-]+)"', spec.read_text())}


def test_list_methods_prints_each_summary_and_imports_no_heavy_backend():
    out = _subprocess(["list", "methods"]).stdout
    assert "HEAVY [] STATUS 0" in out
    lines = out.splitlines()[:-1]
    names = METHODS.names()
    # Every method a family folder declares, and only those.
    declared = _declared_methods()
    assert len(lines) == len(names) == len(declared) and set(names) == declared
    for line, name in zip(lines, names):
        summary = METHODS.get(name).summary
        assert summary and line.split(None, 1) == [name, " ".join(summary.split())]
    # The summaries start in one column.
    assert len({line.index(METHODS.get(n).summary[:8]) for line, n in zip(lines, names)}) == 1


def test_list_methods_imports_no_method_code():
    # The summaries come from the family folders' spec modules alone.
    code = ("import sys; from prtbench.cli import main\n"
            "main(['list', 'methods'])\n"
            "print('LOADED', sorted(m for m in sys.modules if m.startswith('methods.')\n"
            "      and not m.endswith('.spec')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.splitlines()[-1] == "LOADED " + repr(sorted(
        f"methods.{p}" for p in _family_packages()))


def _family_packages() -> list[str]:
    from pathlib import Path

    root = Path(__file__).resolve().parents[3] / "methods"
    return [p.parent.name for p in root.glob("*/spec.py")]


def test_pyproject_declares_no_builtin_method():
    import tomllib
    from pathlib import Path

    with open(Path(__file__).resolve().parents[3] / "pyproject.toml", "rb") as fh:
        entry_points = tomllib.load(fh)["project"]["entry-points"]
    assert "prtbench.methods" not in entry_points
    assert entry_points["prtbench.method_packages"] == {"builtin": "methods"}


@pytest.mark.parametrize("name", METHODS.names())
def test_describe_lists_every_knob_with_type_default_and_range(name, capsys):
    assert main(["describe", name]) == 0
    out = capsys.readouterr().out
    method = METHODS.get(name)
    lines = out.splitlines()
    assert lines[0] == f"{name}: {method.summary}"
    assert lines[1].startswith("paper: ") and len(lines[1]) > 20 and "(none" not in lines[1]
    fields = dataclasses.fields(method.Config)
    assert f"knobs ({len(fields)}," in lines[2]
    hints = typing.get_type_hints(method.Config)
    rows = {line.split()[0]: line for line in lines[4:] if line.startswith("  ")
            and not line.startswith("   ") and ":" not in line.split()[0]}
    assert list(rows) == [f.name for f in fields]
    for f in fields:
        cells = rows[f.name].split(None, 3)
        assert cells[0] == f.name
        if hints[f.name] in (int, float, str, bool):
            assert cells[1] == hints[f.name].__name__
            default = f.default
            assert cells[2] == ("''" if default == "" else str(default))
        meta = f.metadata
        if meta.get("choices"):
            assert rows[f.name].endswith(", ".join(map(str, meta["choices"])))
        elif meta.get("low") is not None and meta.get("high") is not None:
            assert rows[f.name].endswith("]")
        # The docstring follows its row (wrapped and indented).
        doc_words = meta["doc"].split()
        assert " ".join(doc_words[:4]) in " ".join(out.split())


def test_describe_vertex_reads_as_documented(capsys):
    assert main(["describe", "vertex"]) == 0
    out = capsys.readouterr().out
    assert re.search(r"^  sh_bands +int +5 +\[1, 8\]$", out, re.MULTILINE)
    assert re.search(r"^  rays_per_point +int +512 +\[1, 1048576\]$", out, re.MULTILINE)  # not 1e6
    assert re.search(r"^      SH bands n \(n² transfer coefficients per vertex\)\.$", out, re.MULTILINE)
    assert "paper: Sloan, Kautz and Snyder 2002" in out
    assert re.search(r"^  smoke: .*rays_per_point=128", out, re.MULTILINE)


def test_describe_bool_and_choice_knobs(capsys):
    assert main(["describe", "texture-tp"]) == 0
    out = capsys.readouterr().out
    assert re.search(r"^  depth_prepass +bool +True +true, false$", out, re.MULTILINE)
    assert re.search(r"^  storage +str +float32 +float32, float16$", out, re.MULTILINE)
    assert re.search(r"^  bounce_light +str +'' +any$", out, re.MULTILINE)


def test_describe_imports_no_heavy_backend():
    out = _subprocess(["describe", "learnt-sdf"]).stdout
    assert "HEAVY [] STATUS 0" in out and "renderer" in out


def test_describe_unknown_method_is_one_line_exit_2(capsys):
    assert main(["describe", "vertx"]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip()
    assert err.startswith("prtbench: error: unknown method 'vertx'; did you mean 'vertex'?")
    assert "\n" not in err and "data-driven" in err.partition("known: ")[2] and captured.out == ""


def test_summaries_survive_a_broken_plugin():
    METHODS.get("vertex")  # the class takes its summary from its family's spec
    registry = Registry("thing")
    registry.add_lazy("good", "methods.vertex.diffuse:VertexPRT")
    registry.add_lazy("broken", "prtbench_no_such_module:Thing")
    summaries = registry.summaries()
    assert list(summaries) == ["broken", "good"]
    assert summaries["good"] == "Sloan 2002 diffuse transfer vectors at vertices, shaded per vertex"
    assert summaries["broken"].startswith("(cannot import: No module named 'prtbench_no_such_module'")
