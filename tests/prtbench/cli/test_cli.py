"""The `prtbench` command: instant listing, one-line errors with exit 2, nothing half-written."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from prtbench.cli import main

HEAVY = ("torch", "moderngl", "embreex", "mitsuba", "drjit")


def test_list_is_instant_and_imports_no_heavy_backend():
    code = ("import sys; from prtbench.cli import main\n"
            "for kind in ('methods', 'scenes', 'lights', 'tables', 'profiles'):\n"
            "    main(['list', kind])\n"
            f"print('HEAVY', [m for m in {HEAVY!r} if m in sys.modules])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert "HEAVY []" in out.stdout
    for name in ("vertex", "plants", "sphere-over-plane", "sky", "white", "tessellation", "smoke"):
        assert name in out.stdout


def test_python_dash_m_is_the_same_entry_point():
    ok = subprocess.run([sys.executable, "-m", "prtbench", "list", "lights"], capture_output=True,
                        text=True)
    assert ok.returncode == 0 and "sky" in ok.stdout
    bad = subprocess.run([sys.executable, "-m", "prtbench", "table", "9.9"], capture_output=True,
                         text=True)
    assert bad.returncode == 2 and "unknown table '9.9'" in bad.stderr


@pytest.mark.parametrize("argv, fragment", [
    (["run", "--method", "vertx", "--scene", "plants"], "unknown method 'vertx'; did you mean 'vertex'?"),
    (["run", "--method", "vertex", "--scene", "plnts"], "unknown scene 'plnts'; did you mean 'plants'?"),
    (["run", "--method", "vertex", "--scene", "plants", "--light", "skyy"], "unknown light 'skyy'"),
    (["run", "--method", "vertex", "--scene", "plants", "--set", "sh_band=4"], "sh_bands"),
    (["run", "--method", "vertex", "--scene", "plants", "--set", "sh_bands=four"], "expects int"),
    (["run", "--method", "vertex", "--scene", "plants", "--set", "sh_bands=99"], "accepted"),
    (["run", "--method", "vertex", "--scene", "plants", "--profile", "fast"], "unknown profile 'fast'"),
    (["run", "--method", "vertex", "--scene", "plants", "--res", "big"], "--res 'big'"),
    (["run", "--method", "vertex", "--scene", "plants", "--reference", "mitsuba"], "--reference 'mitsuba'"),
    (["run", "--method", "vertex", "--scene", "plants", "--variant", "glossy"], "diffuse materials only"),
    (["run", "--method", "vertex", "--scene", "plants", "--scene-param", "ground=3"], "no parameter 'ground'"),
    (["run", "--method", "vertex", "--scene", "plants", "--views", "0"], "--views 0"),
])
def test_bad_input_is_one_line_exit_2_and_writes_nothing(tmp_path, monkeypatch, capsys, argv, fragment):
    cache = tmp_path / "cache"
    monkeypatch.setenv("PRTBENCH_CACHE", str(cache))
    out, results = tmp_path / "out", tmp_path / "results.sqlite"
    status = main([*argv, "--out", str(out), "--results", str(results)])
    err = capsys.readouterr().err.strip()
    assert status == 2
    assert err.startswith("prtbench: error: ") and "\n" not in err
    assert fragment in err
    assert not out.exists() and not results.exists()
    assert not cache.exists() or not any(p.is_file() for p in cache.rglob("*"))


def test_unknown_table_and_list_kind(capsys):
    assert main(["table", "9.9"]) == 2
    assert "unknown table '9.9'" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:  # argparse rejects a bad choice with status 2 too
        main(["list", "widgets"])
    assert exc.value.code == 2


def test_smoke_run_end_to_end(tmp_path, capsys):
    out, results, summary = tmp_path / "out", tmp_path / "r.sqlite", tmp_path / "s.json"
    status = main(["run", "--method", "vertex", "--scene", "sphere-over-plane", "--profile", "smoke",
                   "--light", "sky", "--out", str(out), "--results", str(results), "--json",
                   str(summary), "--quiet"])
    assert status == 0
    printed = capsys.readouterr().out
    assert "psnr_masked" in printed and "renderer=" in printed
    data = json.loads(summary.read_text())
    assert data["method"] == "vertex" and data["profile"] == "smoke" and len(data["views"]) == 1
    assert data["mean_metrics"]["psnr_masked"] > 20  # a smooth scene: vertex PRT is close
    view_dir = out / "vertex" / "sphere-over-plane-diffuse" / "sky"
    for name in ("view00.exr", "view00.png", "view00-reference.png", "view00-flip.png"):
        assert (view_dir / name).stat().st_size > 0
    assert main(["results", "--results", str(results), "--method", "vertex"]) == 0
    assert "sphere-over-plane" in capsys.readouterr().out
