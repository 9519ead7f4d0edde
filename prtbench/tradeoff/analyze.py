"""What does this scene require? ``prtbench analyze`` (issue #13 §3, DESIGN.md §15).

Cheap measurements (:mod:`.measures`), each turned into one modelling decision:

=====================  ==========================================  =============================
measurement            number                                      decision
=====================  ==========================================  =============================
lighting frequency     irradiance error of n SH bands (direct      ``required_bands``: fewest
                       integration over 256 normals as truth)      bands within ``target``
glossiness             largest ks and Phong exponent s; lobe       ``needs_glossy`` (ks > 0),
                       error of n bands (exact zonal energy)       ``glossy_bands``
visibility             occluded cosine-weighted hemisphere         ``needs_shadows``
                       fraction at area-uniform points
tessellation           shading error of barycentric per-vertex     ``needs_textures`` (textures
                       transfer vs transfer at interior points     or a finer mesh)
interreflection        one-bounce / direct energy (Mitsuba)        ``needs_bounces``
light variation        the user's ``light_changes``                ``fixed_light_ok``,
                                                                   ``ruled_out``, ``restricted``
=====================  ==========================================  =============================

Methods are ruled out through their own ``light_dependence`` and ``light_baking_knobs``
(:class:`prtbench.api.method.Method`), never by name.
"""

from __future__ import annotations

import sys
import time
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Any

from prtbench.api.errors import InvalidInputError, UnknownNameError
from prtbench.api.method import METHODS
from prtbench.scene.registry import get_scene
from prtbench.tradeoff import measures
from prtbench.transport.lights import get_light
from prtbench.transport.raytrace import Tracer

if TYPE_CHECKING:
    from prtbench.scene.model import Scene
    from prtbench.transport.lights import EnvironmentLight

#: Accepted ``light_changes``, and the light dependences each one rules out.
LIGHT_CHANGES = {"none": (), "rotate": ("fixed-light",), "family": ("fixed-light", "family")}

#: Default target relative error of lighting (and of the glossy lobe).
DEFAULT_TARGET = 0.01

#: Shadowed transfer matters when the mean occluded fraction exceeds this, or when more than
#: this share of the surface is occluded by more than 5 %.
SHADOW_THRESHOLD = 0.01

#: Vertex storage suffices while the per-vertex interpolation error of shading stays below this
#: (and is clearly above the Monte-Carlo noise of the measurement).
TESSELLATION_THRESHOLD = 0.05

#: Bounces are needed when one bounce adds more than this fraction of the direct light.
BOUNCE_THRESHOLD = 0.05

#: Transfer bands of the tessellation measurement: the light's, clipped to what methods store.
TESSELLATION_BANDS = (3, 8)


@dataclass
class SceneAnalysis:
    """What a scene under a light requires, with the measurements behind each decision.

    Attributes
    ----------
    scene, variant, light, light_changes : str
    target : float
        Target relative lighting error the band counts are for.
    required_bands : int
        Fewest SH bands whose irradiance error is within ``target``
        (``measures.MAX_LIGHT_BANDS + 1`` = 17: more than the SH methods here store).
    needs_glossy : bool
        Some material has ks > 0.
    glossy_bands : int
        Bands the sharpest Phong lobe needs for ``target`` (0 when not glossy).
    needs_shadows, needs_textures, needs_bounces, fixed_light_ok : bool
    ruled_out : list of {"method", "why"}
        Methods the light variation excludes.
    restricted : list of {"method", "knob", "value", "why"}
        Methods allowed only with a knob at a light-free value.
    measurements : dict
        Every number measured (see :func:`analyze_scene`).
    decisions : list of {"measurement", "value", "decision"}
        The printed table.
    """

    scene: str
    variant: str
    light: str
    light_changes: str
    target: float
    required_bands: int
    needs_glossy: bool
    glossy_bands: int
    needs_shadows: bool
    needs_textures: bool
    needs_bounces: bool
    fixed_light_ok: bool
    ruled_out: list[dict[str, str]] = field(default_factory=list)
    restricted: list[dict[str, Any]] = field(default_factory=list)
    measurements: dict[str, Any] = field(default_factory=dict)
    decisions: list[dict[str, str]] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        """Plain JSON-able dict of every field (write it with :func:`prtbench.api.strict_json.dumps`)."""
        return asdict(self)


def check_light_changes(light_changes: str) -> str:
    """``light_changes`` if accepted, else :class:`UnknownNameError` naming the accepted ones."""
    if light_changes not in LIGHT_CHANGES:
        raise UnknownNameError("light change", str(light_changes), LIGHT_CHANGES)
    return light_changes


def light_variation(light_changes: str) -> tuple[list[dict[str, str]], list[dict[str, Any]]]:
    """Registered methods the light variation rules out, and those it restricts to a knob value.

    Read from each method's ``light_dependence`` / ``light_baking_knobs`` class attributes.

    Returns
    -------
    ruled_out : list of {"method", "why"}
    restricted : list of {"method", "knob", "value", "why"}
    """

    excluded = LIGHT_CHANGES[check_light_changes(light_changes)]
    change = {"rotate": "a rotating light", "family": "lights that change family"}.get(light_changes)
    ruled_out, restricted = [], []
    for name in METHODS.names():
        cls = METHODS.get(name)
        dependence = getattr(cls, "light_dependence", "none")
        if dependence in excluded:
            why = getattr(cls, "light_dependence_why", "") or f"light dependence '{dependence}'"
            cost = ("that is paid again on every change, outside its measured frame time"
                    if dependence == "fixed-light" else "lights outside the family are extrapolated")
            ruled_out.append({"method": name, "why": f"{dependence}: {why}; with {change}, {cost}"})
            continue
        for knob, (knob_dependence, free_value, why) in getattr(cls, "light_baking_knobs",
                                                                  {}).items():
            if knob_dependence in excluded:
                restricted.append({"method": name, "knob": knob, "value": free_value,
                                   "why": f"{why}; with {change} use {knob}={free_value}"})
    return ruled_out, restricted


def _light_name(light: Any) -> str:
    return str(getattr(light, "name", light))


def analyze_scene(scene: "Scene | str", light: "EnvironmentLight | str", *,
                  light_changes: str = "none", target: float = DEFAULT_TARGET,
                  render_bounces: bool = True, fast: bool = False, progress: bool = False,
                  ) -> SceneAnalysis:
    """Measure what ``scene`` under ``light`` requires and decide what to model.

    Parameters
    ----------
    scene : Scene or str
        A scene or its registry name (built in the diffuse variant with default parameters).
    light : EnvironmentLight or str
        A light or its registry name / HDR path.
    light_changes : {"none", "rotate", "family"}
        How the light will vary at run time.
    target : float
        Target relative lighting error in (0, 1) (band counts for 1/5/10 % are always reported).
    render_bounces : bool
        Measure interreflection with two small Mitsuba renders (False: skipped, decided False
        and reported as not measured).
    fast : bool
        Fewer samples everywhere (for tests and smoke runs).
    progress : bool
        Print one line per measurement (with its time) on stderr.

    Returns
    -------
    SceneAnalysis
    """

    check_light_changes(light_changes)
    if not (isinstance(target, (int, float)) and 0.0 < float(target) < 1.0):
        raise InvalidInputError(f"target lighting error {target!r}; accepted: a number in (0, 1)")
    target = float(target)
    if isinstance(scene, str):

        scene = get_scene(scene)
    light = get_light(light) if isinstance(light, str) else light
    timings: dict[str, float] = {}
    m: dict[str, Any] = {}

    def timed(key: str, fn, *args, **kwargs):
        start = time.perf_counter()
        value = fn(*args, **kwargs)
        timings[key] = time.perf_counter() - start
        if progress:
            print(f"analyze: {key} {timings[key]:.1f} s", file=sys.stderr)
        return value

    # Lighting frequency.
    m["lighting"] = timed("lighting", measures.light_frequency, light)
    required_bands = measures.bands_for(m["lighting"]["irradiance_error"], target)

    # Glossiness: the lobe alone, and the light filtered by it.
    gloss = measures.glossiness(scene)
    needs_glossy = gloss["max_ks"] > 0
    if needs_glossy:
        lobe = measures.lobe_errors(gloss["max_shininess"])
        gloss["lobe_error"] = lobe
        gloss["lobe_bands"] = measures.bands_table(lobe)
        filtered = timed("glossy", measures.phong_filtered_errors, light, gloss["max_shininess"])
        gloss["filtered_light_error"] = filtered
        gloss["filtered_light_bands"] = measures.bands_table(filtered)
        glossy_bands = measures.bands_for(lobe, target)
    else:
        glossy_bands = 0
    m["glossiness"] = gloss

    # Visibility and tessellation share one BVH.
    tracer = Tracer.from_scene(scene)
    m["visibility"] = timed("visibility", measures.occlusion, scene, tracer=tracer,
                            n_points=1024 if fast else 4096, rays_per_point=128 if fast else 256)
    vis = m["visibility"]
    needs_shadows = (vis["mean"] > SHADOW_THRESHOLD
                     or vis["shadowed_area_fraction"] > SHADOW_THRESHOLD)
    bands = min(max(required_bands, TESSELLATION_BANDS[0]), TESSELLATION_BANDS[1])
    m["tessellation"] = timed("tessellation", measures.tessellation_error, scene, light,
                              bands=bands, tracer=tracer, n_points=512 if fast else 1024,
                              rays_per_point=512 if fast else 1024)
    tess = m["tessellation"]
    needs_textures = (tess["shading_error"] > TESSELLATION_THRESHOLD
                      and tess["shading_error"] > 3.0 * tess["shading_noise"])

    # Interreflection.
    if render_bounces:
        size = dict(width=64, height=48, spp=8) if fast else {}
        m["interreflection"] = timed("interreflection", measures.interreflection, scene, light,
                                     **size)
        indirect = m["interreflection"]["indirect_fraction"]
        needs_bounces = indirect is not None and indirect > BOUNCE_THRESHOLD
    else:
        m["interreflection"] = {"indirect_fraction": None, "why": "skipped on request"}
        needs_bounces = False

    ruled_out, restricted = light_variation(light_changes)
    m["timings_s"] = timings
    m["thresholds"] = {"target": target, "shadow": SHADOW_THRESHOLD,
                       "tessellation": TESSELLATION_THRESHOLD, "bounce": BOUNCE_THRESHOLD}
    analysis = SceneAnalysis(
        scene=scene.name, variant=scene.variant, light=_light_name(light),
        light_changes=light_changes, target=target, required_bands=required_bands,
        needs_glossy=needs_glossy, glossy_bands=glossy_bands, needs_shadows=needs_shadows,
        needs_textures=needs_textures, needs_bounces=needs_bounces,
        fixed_light_ok=light_changes == "none", ruled_out=ruled_out, restricted=restricted,
        measurements=m)
    analysis.decisions = _decisions(analysis)
    return analysis


def _bands_text(n: int, most: int) -> str:
    return f"> {most}" if n > most else str(n)


def _decisions(a: SceneAnalysis) -> list[dict[str, str]]:
    """The (measurement, value, decision) rows of the printed table."""
    m, pct = a.measurements, f"{a.target:.0%}"
    light = m["lighting"]
    most = measures.MAX_LIGHT_BANDS

    def bands(table: dict[str, int], most: int = measures.MAX_LIGHT_BANDS) -> str:
        return ", ".join(f"{k}: {_bands_text(v, most)}" for k, v in table.items())

    def lobe_bands(table: dict[str, int]) -> str:
        return bands(table, measures.MAX_LOBE_BANDS)

    rows = [
        {"measurement": "radiance energy in 3 / 6 / 16 bands",
         "value": " / ".join(f"{light['radiance_energy_fraction'][n - 1]:.1%}" for n in (3, 6, 16)),
         "decision": f"bands for radiance error {bands(light['radiance_bands'])}"},
        {"measurement": "irradiance error of 3 / 6 / 16 bands",
         "value": " / ".join(f"{light['irradiance_error'][n - 1]:.2%}" for n in (3, 6, 16)),
         "decision": f"required_bands = {_bands_text(a.required_bands, most)} for {pct} "
                     f"({bands(light['irradiance_bands'])})"},
    ]
    g = m["glossiness"]
    if a.needs_glossy:
        rows.append({"measurement": "largest ks / Phong exponent",
                     "value": f"{g['max_ks']:.2f} / {g['max_shininess']:g}",
                     "decision": f"glossy transfer needed; lobe needs "
                                 f"{_bands_text(a.glossy_bands, measures.MAX_LOBE_BANDS)} bands "
                                 f"for {pct} ({lobe_bands(g['lobe_bands'])}); light filtered by it: "
                                 f"{bands(g['filtered_light_bands'])}"})
    else:
        rows.append({"measurement": "largest ks", "value": "0",
                     "decision": "diffuse only: no glossy transfer"})
    v = m["visibility"]
    rows.append({"measurement": "occluded hemisphere (cosine) mean ± std",
                 "value": f"{v['mean']:.1%} ± {v['std']:.1%} ({v['shadowed_area_fraction']:.0%} "
                          "of area > 5 %)",
                 "decision": "shadowed transfer needed" if a.needs_shadows
                 else "unshadowed transfer suffices (nothing occludes)"})
    t = m["tessellation"]
    worst = sorted(t["per_object_shading_error"].items(), key=lambda kv: -kv[1])[:3]
    rows.append({"measurement": f"per-vertex interpolation error of shading ({t['bands']} bands)",
                 "value": f"{t['shading_error']:.1%} (noise {t['shading_noise']:.1%}; worst: "
                          + ", ".join(f"{k} {e:.0%}" for k, e in worst) + ")",
                 "decision": "textures or a finer mesh needed" if a.needs_textures
                 else "vertex storage suffices"})
    r = m["interreflection"]
    if r.get("indirect_fraction") is None:
        rows.append({"measurement": "one-bounce / direct energy",
                     "value": f"not measured ({r.get('why', '')})",
                     "decision": "bounces not assessed"})
    else:
        rows.append({"measurement": "one-bounce / direct energy",
                     "value": f"+{r['indirect_fraction']:.1%} (± {r['indirect_stderr']:.1%})",
                     "decision": "bounces needed" if a.needs_bounces
                     else f"direct only (indirect <= {BOUNCE_THRESHOLD:.0%})"})
    names = ", ".join(x["method"] for x in a.ruled_out) or "none"
    limited = ", ".join(f"{x['method']} ({x['knob']}={x['value']})" for x in a.restricted)
    rows.append({"measurement": "light changes", "value": a.light_changes,
                 "decision": f"ruled out: {names}" + (f"; only with {limited}" if limited else "")})
    return rows


def format_analysis(a: SceneAnalysis) -> str:
    """The decisions as an aligned text table (measurement | value | decision)."""
    header = {"measurement": "measurement", "value": "value", "decision": "decision"}
    rows = [header] + a.decisions
    w = [max(len(r[k]) for r in rows) for k in ("measurement", "value")]
    lines = [f"scene {a.scene} ({a.variant}), light {a.light}, light changes {a.light_changes}"]
    for i, r in enumerate(rows):
        lines.append(f"{r['measurement']:<{w[0]}}  {r['value']:<{w[1]}}  {r['decision']}")
        if i == 0:
            lines.append("-" * (w[0] + w[1] + 4 + len("decision")))
    for x in a.ruled_out:
        lines.append(f"  ruled out {x['method']}: {x['why']}")
    return "\n".join(lines)
