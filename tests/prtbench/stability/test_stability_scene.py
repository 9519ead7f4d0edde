"""``prtbench stability --scene PATH`` (issues #14 and #15): the cases on a user's file.

The files are written at test time with trimesh: a sphere standing over nothing (no ground
object: the geometry cases that edit a ground run on the built-in base and say so).
"""

from __future__ import annotations

import json

import pytest

from prtbench.api.method import METHODS
from prtbench.cli import main
from prtbench.stability.cases import method_cases


def _same_picture(row) -> bool:
    """The case's image is the moderate one: a masked PSNR against it above 30 dB, or identical
    pixels (PSNR inf, which the store's strict JSON keeps as null, and FLIP 0)."""
    psnr = row["psnr_vs_moderate"]
    return psnr > 30.0 if psnr is not None else row["flip_vs_moderate"] == 0.0


def _sphere_file(folder, suffix: str):
    import trimesh

    mesh = trimesh.creation.icosphere(subdivisions=2, radius=0.6)
    mesh.apply_translation((0.0, 0.8, 0.0))
    path = folder / f"ball{suffix}"
    mesh.export(path)
    return path


def test_file_scene_cases_transform_the_file_and_run_ground_cases_on_the_built_in_base(tmp_path):
    path = _sphere_file(tmp_path, ".ply")
    cases = {c.name: c for c in method_cases(METHODS.get("vertex"), profile="quick",
                                             scene_file=str(path))}
    # Scene transforms apply to the file itself ...
    for name in ("scale=1e+04", "translate=1e+05", "geometry=flipped-normals", "light=black",
                 "sh_bands=1"):
        assert cases[name].scene == "", name
    # ... the ground-editing geometry runs on the built-in base, saying why.
    for name in ("geometry=grazing", "geometry=degenerate", "geometry=coincident"):
        assert cases[name].scene == "sphere-over-plane" and "no object named 'ground'" in \
            cases[name].note
    # With a ground, they transform the file too.
    grounded = {c.name: c for c in method_cases(METHODS.get("vertex"), profile="quick",
                                                scene_file=str(path),
                                                scene_params={"ground": "true"})}
    assert grounded["geometry=degenerate"].scene == ""
    # A method that refuses the file gets its moderate case only (the refusal is the answer).
    assert [c.name for c in method_cases(METHODS.get("learnt-sdf"), profile="quick",
                                         scene_file=str(path))] == ["moderate"]


@pytest.mark.slow  # a stability matrix on a file scene; make test keeps file scenes' runs and the smoke matrix
def test_stability_on_an_obj_file_classifies_its_cases(tmp_path):
    path = _sphere_file(tmp_path, ".obj")
    results, reports, out_json = tmp_path / "r.sqlite", tmp_path / "reports", tmp_path / "s.json"
    cases = ["light=black", "scale=1e+04", "scale=1e-04", "geometry=degenerate"]
    status = main(["stability", "--scene", str(path), "--method", "vertex", "--method",
                   "learnt-sdf", "--profile", "smoke", *[a for c in cases for a in ("--case", c)],
                   "--results", str(results), "--reports", str(reports), "--json",
                   str(out_json), "--quiet"])
    assert status == 0
    data = json.loads(out_json.read_text())
    rows = {(r["method"], r["case"]): r for r in data["rows"]}
    label = rows["vertex", "moderate"]["scene"]
    assert label.startswith("ball-") and len(label) == len("ball-") + 10  # the hashed name
    assert rows["vertex", "moderate"]["outcome"] == "ok"
    assert 10.0 < rows["vertex", "moderate"]["psnr_masked"] < 60.0
    assert rows["vertex", "light=black"]["outcome"] == "ok"
    # Scale invariance: both are rendered in the canonical frame (1e-4 was once refused by
    # the float32 extent check) and show the moderate picture.
    for scaled in ("scale=1e+04", "scale=1e-04"):
        assert rows["vertex", scaled]["outcome"] == "ok"
        assert _same_picture(rows["vertex", scaled]), rows["vertex", scaled]
    degenerate = rows["vertex", "geometry=degenerate"]
    assert degenerate["scene"] == "sphere-over-plane" and degenerate["outcome"] in ("ok",
                                                                                  "degraded")
    refused = rows["learnt-sdf", "moderate"]
    assert refused["outcome"] == "refused" and len([r for r in rows if r[0] == "learnt-sdf"]) == 1
    # Its own report, beside (never over) the committed table-stability.*.
    assert sorted(p.name for p in reports.iterdir()) == [f"table-stability-{label}.csv",
                                                         f"table-stability-{label}.md"]
    assert f"Base scene `{label}`" in (reports / f"table-stability-{label}.md").read_text()
    # The rows are stored apart from the built-in matrix's: --from-store finds them by scene.
    again = tmp_path / "again"
    assert main(["stability", "--scene", str(path), "--profile", "smoke", "--from-store",
                 "--results", str(results), "--reports", str(again)]) == 0
    # (Same rows; --from-store orders the methods by name.)
    assert sorted((again / f"table-stability-{label}.csv").read_text().splitlines()) == \
        sorted((reports / f"table-stability-{label}.csv").read_text().splitlines())
    assert main(["stability", "--profile", "smoke", "--from-store", "--results", str(results),
                 "--reports", str(again)]) == 2  # no built-in matrix in this store


@pytest.mark.parametrize("argv, fragment", [
    (["--scene", "{missing}"], "no such file"),
    (["--scene", "{bad}"], "unsupported extension '.xyz'"),
    (["--scene-param", "ground=true"], "--scene-param without --scene"),
    (["--scene", "{ply}", "--scene-param", "size=3"], "has no parameter 'size'"),
])
def test_scene_errors_are_one_line_exit_2_and_write_nothing(tmp_path, capsys, argv, fragment):
    ply = _sphere_file(tmp_path, ".ply")
    (tmp_path / "ball.xyz").write_text("0 0 0\n")
    names = {"missing": str(tmp_path / "nowhere" / "ball.obj"), "bad": str(tmp_path / "ball.xyz"),
             "ply": str(ply)}
    argv = [a.format(**names) for a in argv]
    results, reports, out_json = tmp_path / "r.sqlite", tmp_path / "reports", tmp_path / "s.json"
    status = main(["stability", *argv, "--method", "vertex", "--profile", "smoke", "--results",
                   str(results), "--reports", str(reports), "--json", str(out_json)])
    err = capsys.readouterr().err.strip()
    assert status == 2 and err.startswith("prtbench: error: ") and "\n" not in err, err
    assert fragment in err
    assert not results.exists() and not reports.exists() and not out_json.exists()
