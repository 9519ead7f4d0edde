"""No configuration the project evaluates scores a learnt or fitted method on a light or a view
it was trained or fitted on (docs/PROTOCOL.md, "Split").

Walks what is evaluated: every shipped sweep (the demo's, whose rows the site and the Pareto
reports are built from, and the fuller grids), every regression case, the lights the Makefile's
demo runs ``analyze``/``advise`` under and the candidates ``advise`` would try there.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from prtbench.api.method import METHODS
from prtbench.bench import regress
from prtbench.bench.protocol import split_of
from prtbench.bench.runner import prepare
from prtbench.scene.registry import get_scene
from prtbench.tradeoff import grid
from prtbench.tradeoff.search_space import build_space
from prtbench.transport.lights import get_light

ROOT = Path(__file__).resolve().parents[3]
SWEEPS = sorted((ROOT / "sweeps").glob("*.toml"))


def _trained_on(prepared) -> bool:
    return split_of(prepared.method_cls, prepared.config, prepared.light,
                    scene=prepared.scene) == "trained"


@pytest.mark.parametrize("path", SWEEPS, ids=lambda p: p.name)
def test_no_sweep_cell_evaluates_a_method_on_what_it_trained_on(path):
    sweep = grid.load_sweep(path)
    bad = [cell.describe() for cell in sweep.cells
           if _trained_on(grid.prepare_cell(cell, profile=sweep.profile, reuse=True))]
    assert not bad, f"{path.name}: {bad}"


def test_no_regression_case_evaluates_a_method_on_what_it_trained_on():
    bad = []
    for name in regress.case_names():
        job = regress.case_job(name)
        if _trained_on(prepare(job, store=False, profile=job.profile or "smoke")):
            bad.append(name)
    assert not bad


def _demo_lights() -> set[str]:
    """The lights the Makefile's demo analyses and advises under."""
    text = (ROOT / "Makefile").read_text()
    return set(re.findall(r"prtbench\)? (?:analyze|advise) [^\n]*--light (\S+)", text)) | set(
        re.findall(r"(?:analyze|advise) --scene \S+ --light (\S+)", text))


def test_advise_in_the_demo_never_tries_a_trained_on_light():
    lights = _demo_lights()
    assert lights, "the demo's analyze/advise lines name no light"
    scene = get_scene("plants")

    class Everything:  # an analysis that prunes nothing: every method's candidates
        required_bands, needs_glossy, glossy_bands, needs_shadows = 2, False, 0, True
        needs_textures, needs_bounces, fixed_light_ok = False, False, True
        measurements = {"light_energy_bands": [0.9, 0.99]}

    for profile in ("smoke", "quick"):
        space = build_space(scene, Everything(), profile=profile)
        for method in space.methods:
            cls = METHODS.get(method.method)
            for candidate in method.candidates:
                config = cls.make_config(dict(candidate.values), profile=profile)
                for light in lights:
                    assert split_of(cls, config, get_light(light), scene=scene) != "trained", (
                        method.method, candidate.values, light)


def test_a_view_on_a_training_camera_is_trained_not_held_out(monkeypatch):
    # The check above can fail: a learnt method scored on one of its own training cameras (or
    # under one of its training lights) is reported as trained.
    import dataclasses

    cls = METHODS.get("neural-wavelet")
    config = cls.make_config({}, profile="smoke")
    scene = get_scene("sphere-over-plane", variant="glossy").with_views(1)
    assert split_of(cls, config, get_light("sky"), scene=scene) == "held-out"
    assert split_of(cls, config, get_light(config.train_lights[0]), scene=scene) == "trained"
    cameras = cls.training_cameras(scene, config)
    # Its cameras follow the trajectory: keep the original scene's while the views change.
    monkeypatch.setattr(cls, "training_cameras", classmethod(lambda c, s, cfg: cameras))
    seen = dataclasses.replace(scene, trajectory=dataclasses.replace(scene.trajectory,
                                                                     views=(cameras[0],)))
    assert split_of(cls, config, get_light("sky"), scene=seen) == "trained"
