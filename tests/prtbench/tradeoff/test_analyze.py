"""``prtbench analyze``: each measurement against a case whose answer is known."""

from __future__ import annotations

import json

import numpy as np
import pytest

from prtbench.api.method import LIGHT_DEPENDENCES, METHODS
from prtbench.cli import main
from prtbench.scene.model import Material, Scene, SceneObject
from prtbench.scene.registry import get_scene
from prtbench.tradeoff import analyze, measures
from prtbench.transport.lights import EnvironmentLight
from prtbench.transport.raytrace import Tracer
from scenes.primitives import uv_sphere

SUN = np.array([0.4, 0.8, 0.3]) / np.linalg.norm([0.4, 0.8, 0.3])


def _light(name: str, image: np.ndarray) -> EnvironmentLight:
    return EnvironmentLight(name, np.ascontiguousarray(image, dtype=np.float32))


def _grid(height: int = 64) -> np.ndarray:
    return _light("grid", np.ones((height, 2 * height, 3))).texel_directions()


@pytest.fixture(scope="module")
def sun_light() -> EnvironmentLight:
    """A 5° sun of radiance 50 on a dim sky (64 × 128: its SH projection is fast)."""
    d = _grid()
    image = np.full(d.shape, 0.05)
    image[d @ SUN > np.cos(np.radians(5.0))] = 50.0
    return _light("test-sun", image)


def test_constant_light_needs_one_band():
    freq = measures.light_frequency(_light("constant", np.full((32, 64, 3), 0.7)))
    assert freq["radiance_energy_fraction"][0] == pytest.approx(1.0, abs=1e-6)
    assert freq["radiance_bands"] == {"1%": 1, "5%": 1, "10%": 1}
    assert freq["irradiance_bands"] == {"1%": 1, "5%": 1, "10%": 1}
    assert freq["irradiance_error"][0] < 2e-3


def test_irradiance_reconstruction_is_exact_for_a_band_limited_light():
    # 2 + z has bands 0 and 1 only: two bands reconstruct its irradiance exactly (this checks the
    # clamped-cosine convolution against the direct integration), one band misses it clearly.
    d = _grid()
    freq = measures.light_frequency(_light("linear", 2.0 + d[..., 2:3] * np.ones(3)))
    assert freq["irradiance_error"][0] > 0.1
    assert max(freq["irradiance_error"][1:]) < 5e-3
    assert freq["radiance_energy_fraction"][1] == pytest.approx(1.0, abs=1e-4)


def test_sun_needs_many_bands_and_irradiance_fewer_than_radiance(sun_light):
    freq = measures.light_frequency(sun_light)
    fraction = np.array(freq["radiance_energy_fraction"])
    assert np.all(np.diff(fraction) >= -1e-12) and fraction[-1] < 0.5  # 16 bands miss most
    assert freq["radiance_bands"]["10%"] == measures.MAX_LIGHT_BANDS + 1
    irr = freq["irradiance_bands"]
    assert 5 <= irr["1%"] <= measures.MAX_LIGHT_BANDS  # many bands, but within what SH stores
    assert irr["1%"] >= irr["5%"] >= irr["10%"]
    assert all(irr[k] < freq["radiance_bands"][k] for k in irr)
    assert freq["irradiance_error"][0] > 0.3 and freq["irradiance_error"][-1] < 0.01
    # The cosine damps high bands: irradiance holds more of its energy in few bands than radiance.
    assert freq["irradiance_energy_fraction"][2] > 0.99 > 0.1 > fraction[2]


def test_phong_lobe_bands_grow_with_the_exponent():
    bands = [measures.bands_for(measures.lobe_errors(s), 0.05) for s in (4.0, 16.0, 64.0, 256.0)]
    assert bands == sorted(bands) and len(set(bands)) == 4, bands
    # The closed-form total energy is right: enough bands capture all of a smooth lobe.
    assert measures.lobe_errors(8.0)[-1] < 1e-6
    assert measures.lobe_errors(8.0)[0] > 0.5


def test_glossiness_decides_glossy_transfer():
    diffuse = measures.glossiness(get_scene("plants"))
    assert diffuse["max_ks"] == 0.0 and diffuse["glossy_objects"] == []
    glossy = measures.glossiness(get_scene("plants", variant="glossy"))
    assert glossy["max_ks"] == pytest.approx(0.35) and glossy["max_shininess"] == 128.0


def _sphere_scene(shininess: float | None = None) -> Scene:
    material = (Material(kd=(0.5, 0.5, 0.5), name="ball") if shininess is None else
                Material(kd=(0.4, 0.4, 0.4), ks=(0.3, 0.3, 0.3), shininess=shininess, name="ball"))
    ball = uv_sphere(radius=0.5, segments=48, center=(0.0, 1.0, 0.0))
    return Scene("sphere", [SceneObject("ball", ball, material)])


def test_glossy_bands_of_the_analysis_grow_with_the_exponent(sun_light):
    results = {}
    for s in (None, 8.0, 64.0):
        a = analyze.analyze_scene(_sphere_scene(s), sun_light, render_bounces=False, fast=True)
        results[s] = a
    assert not results[None].needs_glossy and results[None].glossy_bands == 0
    assert results[8.0].needs_glossy and results[64.0].needs_glossy
    assert 0 < results[8.0].glossy_bands < results[64.0].glossy_bands
    # A convex object alone: nothing occludes it, and nothing to interpolate across shadows.
    assert not results[None].needs_shadows
    assert results[None].measurements["visibility"]["max"] == 0.0
    # A scene without views: interreflection is reported as not measured, never guessed.
    bare = analyze.analyze_scene(_sphere_scene(), sun_light, fast=True)
    assert bare.measurements["interreflection"]["indirect_fraction"] is None
    assert not bare.needs_bounces and "not measured" in analyze.format_analysis(bare)


def test_convex_sphere_is_unoccluded_and_sphere_over_plane_is_not():
    alone = measures.occlusion(_sphere_scene(), n_points=2048, rays_per_point=128)
    assert alone["mean"] == 0.0 and alone["max"] == 0.0
    over = measures.occlusion(get_scene("sphere-over-plane"), n_points=2048, rays_per_point=128)
    assert over["mean"] > analyze.SHADOW_THRESHOLD
    # The sphere's lower half faces the ground (occluded); the ground is shadowed near the sphere.
    assert over["per_object"]["sphere"] > 0.2 and over["per_object"]["ground"] > 0.005


def test_occluded_fraction_below_a_sphere_is_analytic():
    # Sphere of radius r centred at height h: the cosine-weighted occluded fraction of the
    # ground point below it is (r/h)² = 0.25 (DESIGN.md §13).
    scene = get_scene("sphere-over-plane", radius=0.5, height=1.0)
    frac = measures.occluded_fraction(Tracer.from_scene(scene), np.zeros((64, 3)),
                                      np.tile([0.0, 1.0, 0.0], (64, 1)), rays_per_point=1024)
    assert frac.mean() == pytest.approx(0.25, abs=0.005)


def test_tessellation_error_large_on_two_ground_triangles_small_on_a_fine_ground(sun_light):
    errors = {}
    for k in (1, 64):
        errors[k] = measures.tessellation_error(get_scene("plants", ground_subdivisions=k),
                                                sun_light, bands=6, n_points=1024,
                                                rays_per_point=512)
    coarse, fine = errors[1], errors[64]
    # PRTT's claim, measured: the leaves' shadows on a two-triangle ground are lost between its
    # vertices; a 64 × 64 ground resolves them.
    assert coarse["per_object_shading_error"]["ground"] > 0.15
    assert fine["per_object_shading_error"]["ground"] < 0.05
    assert fine["shading_error"] < 0.75 * coarse["shading_error"]
    assert coarse["shading_error"] > analyze.TESSELLATION_THRESHOLD
    assert coarse["shading_noise"] < 0.05 and fine["shading_noise"] < 0.05
    flat = measures.tessellation_error(get_scene("plane"), sun_light, bands=6, n_points=512,
                                       rays_per_point=256)
    # Nothing varies inside the plane's triangles: what it measures is Monte-Carlo noise (the
    # interpolated estimate carries the vertices' noise too, hence the factor above 1).
    assert flat["shading_error"] < min(2.0 * flat["shading_noise"], 0.03), flat


def test_interreflection_energy(sun_light):
    plane = measures.interreflection(get_scene("plane"), sun_light, width=48, height=36, spp=8)
    assert abs(plane["indirect_fraction"]) < 0.01  # nothing to bounce off
    room = measures.interreflection(get_scene("room"), sun_light, width=48, height=36, spp=8)
    assert room["indirect_fraction"] > analyze.BOUNCE_THRESHOLD


def test_every_method_declares_a_known_light_dependence():
    for name in METHODS.names():
        cls = METHODS.get(name)
        assert cls.light_dependence in LIGHT_DEPENDENCES, name
        for knob, (dependence, _, why) in cls.light_baking_knobs.items():
            assert dependence in LIGHT_DEPENDENCES and why, (name, knob)
            assert knob in {f for f in cls.Config.__dataclass_fields__}, (name, knob)


def test_light_changes_rule_methods_out():
    assert analyze.light_variation("none") == ([], [])
    rotate, restricted = analyze.light_variation("rotate")
    out = {r["method"] for r in rotate}
    assert {"vertex-tpfl", "texture-tpfl"} <= out
    assert not out & {"vertex", "vertex-tp", "texture-tp", "data-driven"}
    assert {"method": "texture-tp", "knob": "bounces", "value": 0} .items() <= \
        next(r for r in restricted if r["method"] == "texture-tp").items()
    family = {r["method"] for r in analyze.light_variation("family")[0]}
    assert out | {"data-driven"} <= family
    with pytest.raises(Exception, match="known: family, none, rotate"):
        analyze.light_variation("sometimes")


def _strict(text: str):
    def no_constant(token):
        raise ValueError(f"non-strict JSON token {token}")
    return json.loads(text, parse_constant=no_constant)


def test_cli_writes_strict_json_with_every_field(tmp_path, capsys):
    path = tmp_path / "analysis.json"
    assert main(["analyze", "--scene", "sphere-over-plane", "--light", "white",
                 "--light-changes", "rotate", "--json", str(path), "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "measurement" in out and "required_bands = 1" in out
    data = _strict(path.read_text())
    for key in ("required_bands", "needs_glossy", "glossy_bands", "needs_shadows",
                "needs_textures", "needs_bounces", "fixed_light_ok", "measurements", "ruled_out",
                "restricted", "decisions"):
        assert key in data, key
    assert data["required_bands"] == 1 and data["needs_shadows"] is True
    assert data["fixed_light_ok"] is False and data["needs_glossy"] is False
    assert {"vertex-tpfl", "texture-tpfl"} <= {r["method"] for r in data["ruled_out"]}
    for key in ("lighting", "glossiness", "visibility", "tessellation", "interreflection"):
        assert key in data["measurements"], key


@pytest.mark.parametrize("argv, fragment", [
    (["--scene", "plnts"], "unknown scene 'plnts'"),
    (["--scene", "plants", "--light", "skyy"], "unknown light 'skyy'"),
    (["--scene", "plants", "--variant", "shiny"], "unknown variant 'shiny'"),
    (["--scene", "plants", "--light-changes", "often"], "unknown light change 'often'"),
    (["--scene", "plants", "--target", "2"], "--target 2"),
    (["--scene", "plants", "--target", "often"], "--target often"),
    (["--scene", "plants", "--scene-param", "foo=1"], "no parameter 'foo'"),
])
def test_cli_bad_input_is_one_line_exit_2(tmp_path, capsys, argv, fragment):
    path = tmp_path / "a.json"
    assert main(["analyze", *argv, "--json", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("prtbench: error:") and fragment in err and "\n" not in err
    assert not path.exists()


def test_cli_json_to_a_folder_is_refused(tmp_path, capsys):
    assert main(["analyze", "--scene", "plane", "--json", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert "--json" in err and "\n" not in err
