"""The protocol (docs/PROTOCOL.md), checked method by method: no method's rendering needs the
path tracer, and every resident GL byte a renderer allocated is in its ``memory_breakdown``."""

from __future__ import annotations

import subprocess
import sys

import pytest

from prtbench.api.method import METHODS, load_or_precompute
from prtbench.api.residency import allocation_log
from prtbench.bench.job import Job
from prtbench.bench.runner import prepare

#: A small scene each method can render at the smoke profile (an SDF method needs an SDF
#: scene; a factored BRDF needs a glossy one: a diffuse BRDF has rank 1).
SCENES = {"learnt-sdf": ("sdf-rabbit", "diffuse"), "factored-brdf": ("sphere-over-plane", "glossy")}
#: The reference each method is scored against: vertex PRT, except for vertex itself (an image
#: against itself is degenerate, infinite PSNR) and on the glossy scene (vertex is diffuse).
REFERENCES = {"vertex": "method:irradiance-volume", "factored-brdf": "method:vertex-tpfl"}

#: `prtbench run` in a fresh interpreter where ``import mitsuba`` (and Dr.Jit) fails.
BLOCKED = """
import sys
sys.modules["mitsuba"] = None
sys.modules["drjit"] = None
from prtbench.cli import main
sys.exit(main(sys.argv[1:]))
"""


def _job(method: str) -> Job:
    scene, variant = SCENES.get(method, ("sphere-over-plane", "diffuse"))
    return Job(method=method, scene=scene, variant=variant, views=1, profile="smoke",
               reference=REFERENCES.get(method, "method:vertex"))


@pytest.fixture(scope="module", params=METHODS.names())
def warm(request):
    """The method's artifact and its reference method's, in the run's cache."""
    job = _job(request.param)
    prepared = prepare(job, store=False, profile="smoke")
    artifact = load_or_precompute(prepared.method_cls, prepared.scene, prepared.config,
                                  progress=False)
    ref_cls, ref_config = prepared.reference_method
    load_or_precompute(ref_cls, prepared.scene, ref_config, progress=False)
    return job, prepared, artifact


def test_every_resident_gl_byte_is_in_the_memory_breakdown(warm):
    _, prepared, artifact = warm
    view, light = prepared.scene.trajectory.views[0], prepared.light
    with allocation_log() as log:
        renderer = prepared.method_cls.renderer(prepared.scene, artifact, prepared.config,
                                                width=prepared.width, height=prepared.height)
        try:
            renderer.render(view, light)
            allocated = log.alive_bytes()  # what the GL driver holds for it now
            breakdown = renderer.memory_breakdown()
        finally:
            renderer.release()
    gpu = sum(v for k, v in breakdown.items() if k.startswith("gpu: "))
    assert gpu == pytest.approx(allocated, rel=0.01, abs=0), (allocated, breakdown)
    assert sum(breakdown.values()) >= gpu and all(v > 0 for v in breakdown.values())


def test_rendering_never_imports_the_path_tracer(warm, tmp_path):
    job, _, _ = warm
    argv = ["run", "--method", job.method, "--scene", job.scene, "--variant", job.variant,
            "--views", "1", "--profile", "smoke", "--reference", job.reference, "--no-store",
            "--quiet", "--out", str(tmp_path / "out")]
    done = subprocess.run([sys.executable, "-c", BLOCKED, *argv], capture_output=True,
                          text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "mitsuba" not in done.stderr.lower(), done.stderr[-2000:]


def test_baked_lights_make_the_fixed_light_class():
    # An engine's lightmap and a probe volume in light_mode=fixed carry one baked light: on a
    # front they are `fixed`, never beside the relightable methods unmarked.
    lightmap, probes = METHODS.get("lightmap"), METHODS.get("probe-volume")
    assert lightmap.light_class_of(lightmap.Config()) == "fixed"
    assert probes.light_class_of(probes.Config(light_mode="fixed")) == "fixed"
    assert probes.light_class_of(probes.Config()) == "relight"
    texture = METHODS.get("texture-tpfl")
    assert texture.light_class_of(texture.Config(bounces=1)) == "fixed"
    assert texture.light_class_of(texture.Config(bounces=0)) == "relight"


@pytest.mark.parametrize("method, overrides", [
    ("lightmap", {"bake_light": "sky"}),
    ("probe-volume", {"light_mode": "fixed", "bake_light": "sky"}),
    ("texture-tpfl", {"bounces": 1, "bounce_light": "sky"}),
])
def test_a_renderer_that_bakes_its_light_runs_and_times_no_light_change(method, overrides):
    # It refuses any other light, so a light change is a new precompute: the run succeeds
    # (before, timing the change with a fresh light failed every such run) and stores no
    # light_change_ms.
    from prtbench.bench.runner import execute

    job = Job(method=method, scene="sphere-over-plane", variant="diffuse", views=1,
              profile="smoke", overrides=overrides, reference="method:vertex")
    summary = execute(prepare(job, store=False, profile="smoke"), progress=False, echo=False)
    assert summary.status == "ok" and summary.light_change_ms is None
