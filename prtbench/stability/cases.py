"""The stability case catalogue (issue #15): extreme settings, as data, per registered method.

A method's cases are generated from its own ``Config`` fields, so a method added later gets
them without being named here: every knob whose *name* has a rule in :data:`KNOB_RULES`
contributes a case at each of the rule's extremes (``"low"`` / ``"high"`` are the knob's
declared bounds, read from its metadata; numbers are used as they are), minus the value the
method's moderate setting already has. Then come the cases that apply to every method: the
extreme lights of :mod:`prtbench.stability.lights`, the scene transforms (scales 10⁻⁶ to 10⁶,
translations by 10⁵ and 10⁷, a grazing view, flipped normals, degenerate triangles, coincident
surfaces) and, for methods that accept glossy materials, the Phong exponents.

Every case is measured against the method's *moderate* case: the profile's defaults plus the
method's regression-case overrides (:func:`prtbench.bench.regress.regression_case`), on the base
scene (``sphere-over-plane`` unless the method refuses it, then its regression scene) under
``sky``, one view.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from prtbench.api.errors import UnknownNameError
from prtbench.bench.regress import regression_case
from prtbench.stability import edges
from prtbench.stability.case import BASE_SCENE, PROFILES, Case, accepts, case_base_scene
from prtbench.stability.lights import LIGHTS

#: Phong exponents of the material cases (quick; smoke keeps the ends). 10⁵ is past the
#: material's accepted range [0, 10⁴]: its correct answer is a refusal naming that range.
SHININESS = {"smoke": (0.0, 1.0e4, 1.0e5), "quick": (0.0, 1.0, 1.0e3, 1.0e4, 1.0e5)}


@dataclass(frozen=True)
class KnobRule:
    """Extremes of one knob name.

    Attributes
    ----------
    values : dict of str to tuple
        Per profile: ``"low"``, ``"high"`` (the knob's declared bounds) or literal values.
    note : str
        What the extreme probes.
    advice : str
        What a user should do instead when the case is degraded.
    group : str
        Report group (``knob``, ``storage``, ``learning``, ``sampling``).
    """

    values: Mapping[str, tuple[Any, ...]]
    note: str
    advice: str
    group: str = "knob"
    #: Extreme lights each value is also measured under (a knob whose arithmetic scales with
    #: the light: half-float storage, gamma-space transfer).
    lights: tuple[str, ...] = ()
    #: Knobs a value of this knob needs to take effect, where the method has them and they
    #: accept the value (wavelet-image reads ``sh_bands`` only with ``lighting="sh"``): without
    #: them the case would render the moderate picture again and call it ``ok``.
    requires: Mapping[str, Any] = field(default_factory=dict)


def _both(*values: Any) -> dict[str, tuple[Any, ...]]:
    return {"smoke": tuple(values), "quick": tuple(values)}


#: Values of the token ``"all"`` of a rule: the knob's largest meaningful value for the moderate
#: config (a declared ``high`` is often a bound over every config, not this one's maximum).
ALL_VALUES = {"light_terms": lambda config: 6 * int(config.cubemap) ** 2}

#: Knob name -> its extremes. A knob a method lacks contributes nothing.
KNOB_RULES: dict[str, KnobRule] = {
    "sh_bands": KnobRule({"smoke": ("low", "high"), "quick": ("low", 2, "high")},
                         "SH band count at the ends of the method's range",
                         "use 3-5 bands (the moderate setting): 1-2 bands lose the shadow",
                         requires={"lighting": "sh"}),
    "storage": KnobRule(_both("float16", "int8"),
                        "half-float (or 8-bit scaled) stored transfer (overflow/underflow)",
                        "store float32 where coefficients exceed 65504 or matter below 6e-5",
                        "storage", lights=("huge-constant",)),
    "precision": KnobRule(_both("float16"), "half-float probe radiance (overflow/underflow)",
                          "store float32 where radiance exceeds 65504 or matters below 6e-5",
                          "storage", lights=("huge-constant",)),
    "texture_resolution": KnobRule({"smoke": ("low", "high"), "quick": ("low", 2048, "high")},
                                   "transfer texture at the smallest, a large and the largest "
                                   "resolution (refused past this machine's memory)",
                                   "use >= 128 texels per side for the scene's shadow detail",
                                   "storage"),
    "dilation": KnobRule(_both(0), "no dilation: bilinear lookups read empty texels at seams",
                         "keep dilation >= 1 with bilinear filtering", "storage"),
    "resolution": KnobRule({"smoke": ("low",), "quick": ("low", "high")},
                           "probe grid at its coarsest (and finest) resolution",
                           "use >= 8 probes per axis", "storage"),
    "normal_bias": KnobRule(_both("low", "high"), "probe lookup bias at 0 and 4 cells",
                            "keep normal_bias near 0.5 cells"),
    "invalid_backface_fraction": KnobRule(_both("low", "high"),
                                          "every probe that sees a back face is invalid (0), "
                                          "or none is, even inside geometry (1)",
                                          "keep invalid_backface_fraction near 0.25"),
    "light_terms": KnobRule(_both("low", "all"),
                            "wavelet lighting terms k = 1, and k = all (every coefficient of "
                            "the cubemap: no lighting approximation)",
                            "use k of 50-200 terms: k = 1 keeps only the light's mean"),
    "keep": KnobRule(_both(1.0), "every transport wavelet coefficient kept (no truncation)",
                     "keep 0.1-0.25 of the coefficients: all of them costs 4-10x the memory",
                     "storage"),
    "bounces": KnobRule(_both("high"), "the most interreflection bounces the knob accepts",
                        "use 1-2 bounces: later ones add little light for much more precompute"),
    "ridge": KnobRule(_both("low", "high"), "transfer-matrix ridge of 0 and 1e6",
                      "use a ridge of 1e-3..1: 1e6 shrinks the transfer towards 0", "learning"),
    "basis": KnobRule({"smoke": ("low", "high"), "quick": ("low", "high")},
                      "1 basis element, and more elements than lighting configurations",
                      "use basis <= configurations", "learning"),
    "configurations": KnobRule(_both("low"), "one lighting configuration: a rank-1 dataset",
                               "use >= 16 configurations", "learning"),
    "gamma": KnobRule(_both("low", "high"),
                      "transfer stored at gamma 0.1 and 10", "keep gamma in 1..2.2", "learning",
                      lights=("huge-constant",)),
    "samples": KnobRule(_both(1, "low"), "training on 1 point (below the range) and the fewest",
                        "train on >= 10⁴ points", "learning"),
    "epochs": KnobRule(_both("low"), "a single training epoch", "train >= 20 epochs", "learning"),
    "learning_rate": KnobRule(_both("high"), "Adam learning rate 1.0 (divergence)",
                              "keep the learning rate at 1e-3..1e-2", "learning"),
    "pe_frequencies": KnobRule(_both("high"), "positional encoding up to sin(2^15 pi x) in float32",
                               "use <= 8 frequencies", "learning"),
    "target_margin": KnobRule(_both("high"), "targets mapped to [-0.999, 0.999] under tanh",
                              "keep target_margin near 0.9", "learning"),
    "max_steps": KnobRule(_both("low"), "one sphere-tracing step per primary ray",
                          "use >= 64 steps", "sampling"),
    "rays_per_point": KnobRule(_both("low"), "one visibility ray per point",
                               "use >= 64 rays per point", "sampling"),
    "rays_per_probe": KnobRule(_both("low"), "one ray per probe",
                               "use >= 64 rays per probe", "sampling"),
    "paths_per_texel": KnobRule(_both("low"), "one path per lightmap texel",
                                "use >= 16 paths per texel", "sampling"),
    "env_lights": KnobRule(_both("low"), "the environment drawn by one median-cut light",
                           "use >= 16 median-cut lights", "sampling"),
    "measurement_points": KnobRule(_both("low"), "one measurement point",
                                   "use >= 64 measurement points", "sampling"),
}


def _format_value(value: Any) -> str:
    if isinstance(value, float) and (value != 0 and (abs(value) >= 1e4 or abs(value) < 1e-3)):
        return f"{value:.0e}"
    if isinstance(value, float) and value.is_integer():
        return str(int(value))
    return str(value)


def base_case(method_cls, *, scene_file: str | None = None,
              scene_params: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Scene, variant, scene params, light and config overrides of ``method_cls``'s moderate case.

    ``sphere-over-plane`` (:data:`BASE_SCENE`) unless the method refuses it, then its glossy
    variant (a method that needs a glossy material), then the method's regression scene (e.g.
    it needs an SDF scene); with ``scene_file``, that file (with
    ``scene_params``), whether the method accepts it or not (a refusal is the answer). The
    regression case's config overrides always apply (they make the smoke profile's training
    or lighting meaningful). ``label`` names the base scene in rows and reports.
    """

    regression = regression_case(method_cls)
    overrides = dict(regression.get("overrides", {}))
    if scene_file is not None:
        scene = case_base_scene(scene_file, "diffuse", scene_params or {})
        return {"scene": str(scene_file), "variant": "diffuse", "light": "sky",
                "scene_params": dict(scene_params or {}), "overrides": overrides,
                "label": scene.name, "file": True}
    base = {**BASE_SCENE, "overrides": overrides}
    if not accepts(method_cls, base["scene"], "diffuse", base["scene_params"]):
        if accepts(method_cls, base["scene"], "glossy", base["scene_params"]):
            # e.g. factored-brdf: more than one BRDF term needs a glossy material to factor.
            base.update(variant="glossy")
        else:
            base.update(scene=regression["scene"], variant="diffuse",
                        scene_params=dict(regression.get("scene_params", {})))
    base["label"] = base["scene"]
    return base


def knob_cases(method_cls, *, profile: str) -> list[Case]:
    """One case per extreme of every knob of ``method_cls.Config`` that has a rule."""
    moderate = method_cls.make_config(profile=profile)
    fields = {f.name: f for f in dataclasses.fields(method_cls.Config)}
    cases = []
    for f in fields.values():
        rule = KNOB_RULES.get(f.name)
        if rule is None:
            continue
        needs = {k: v for k, v in rule.requires.items() if k in fields
                 and getattr(moderate, k) != v
                 and v in (fields[k].metadata.get("choices") or (v,))}
        prefix = "".join(f"{k}={_format_value(v)} " for k, v in needs.items())
        seen = {getattr(moderate, f.name)}
        for token in rule.values[profile]:
            if token == "all":
                value = ALL_VALUES[f.name](moderate)
            else:
                value = f.metadata.get(token) if token in ("low", "high") else token
            if value is None or value in seen:
                continue
            choices = f.metadata.get("choices")
            if choices is not None and value not in choices:
                continue
            seen.add(value)
            name = prefix + f"{f.name}={'all' if token == 'all' else _format_value(value)}"
            overrides = {**needs, f.name: value}
            note = rule.note + (f" (with {prefix.strip()}, which the knob needs)" if needs else "")
            cases.append(Case(name, rule.group, overrides=overrides, note=note,
                              advice=rule.advice, compare_image=True))
            cases += [Case(f"{name} light={light}", rule.group, overrides=overrides,
                           light=light, note=f"{note}, under the {light} light",
                           advice=rule.advice) for light in rule.lights]
    return cases


def light_cases(method_cls, *, profile: str) -> list[Case]:
    """Every extreme light (:data:`prtbench.stability.lights.LIGHTS`); smoke keeps four."""

    names = list(LIGHTS) if profile == "quick" else ["black", "huge-constant", "below-horizon",
                                                     "sun-0.1deg"]
    return [Case(f"light={name}", "light", light=name, note=LIGHTS[name].note,
                 advice=light_advice(method_cls, name)) for name in names]


#: Extreme lights whose source is far smaller than a cubemap texel at the wavelet methods' default
#: face resolutions (N = 16-32: texels of 3-6 degrees).
SMALL_SOURCES = frozenset({"single-texel", "sun-0.1deg"})
def light_advice(method_cls, light: str) -> str:
    """What to do instead of the extreme ``light``, in the terms of the method's basis."""

    knobs, per_vertex = _knob_names(method_cls), method_cls.storage == "per-vertex"
    if not _wavelet_lit(method_cls):
        if light in SMALL_SOURCES and per_vertex:
            # Measured (vertex, 0.1-degree sun): 19.1 dB; 19.3 at 8 bands; 22.7 with the ground
            # at 64 subdivisions, 25.3 with both. Per texel (texture-tp) 8 bands alone give +2.7.
            return ("subdivide the receiving surfaces, then raise sh_bands (<= 8): per-vertex "
                    "transfer interpolates a point-like source's sharp shadow between vertices, "
                    "which more bands alone do not restore; or store transfer per texel")
        return ("more SH bands (or windowing) for all-frequency light, or a method that stores "
                "visibility per pixel")
    if light in SMALL_SOURCES and per_vertex:
        # Measured on the base scene's 0.1-degree sun: wavelet-vertex 19.2 dB, 26.3 and 32.9 dB
        # with the ground at 16 and 64 subdivisions; wavelet-tp 19.4 dB at cubemap 16, 32 and
        # 64 and at 256 light terms alike (the shadow is interpolated between vertices).
        advice = ("subdivide the receiving surfaces, or store transport per texel "
                  "(wavelet-texture): per-vertex transport interpolates a point-like source's "
                  "sharp shadow between vertices")
    elif light in SMALL_SOURCES:
        advice = ("raise cubemap (texels per face, within the memory limit): a source smaller "
                  "than one cubemap texel is spread over the whole texel, which softens its "
                  "shadows and highlights")
    elif "train_lights" in knobs:
        # Measured (neural-wavelet, below-horizon): 31.06 dB at 64 and at 256 light terms. Not
        # light_tilt: tilted training maps lowered the held-out sunrise/sunset PSNR of the
        # must-hold's reduced case (27.37 against 28.45 dB untilted).
        return ("train under lights like this one (train_lights): a learnt transport is fitted "
                "only under its training lights and extrapolates to others, which more light "
                "terms do not change")
    else:
        kept = " and ".join(k for k in ("light_terms", "keep") if k in knobs)
        advice = f"raise {kept}: a light spread over many wavelets loses what the kept terms drop"
    if "train_lights" in knobs:
        advice += "; a learnt transport is fitted only under its training lights (train_lights)"
    return advice


#: The scale and translation cases move the whole scene in the user's world; the harness renders
#: it in its canonical frame (prtbench.scene.frame), so each must render the moderate case's
#: image (``psnr_vs_moderate``) and is ``ok`` when it does. Nothing about the scene's units is
#: for the user to change: a degraded or refused row here is a bug of the canonical frame.
SCALE_ADVICE = ("nothing to change in the scene (any units and position are rendered in the "
                "canonical frame); this case must render the moderate image, so report it as a "
                "prtbench bug")
#: (scale, translation) of the scene-transform cases: millimetres to kilometres and beyond, and
#: far from the origin (10⁷ is where float32 positions are spaced 1 apart).
SCENE_TRANSFORMS = ((1e-6, 0.0), (1e-4, 0.0), (1e4, 0.0), (1e6, 0.0), (1.0, 1e5), (1.0, 1e7))


#: Geometry cases that edit or look along the base scene's ``ground`` object.
NEEDS_GROUND = ("grazing", "edge-on", "degenerate", "t-junction", "coincident")


def scene_cases(*, profile: str, sdf: bool, ground: bool = True) -> list[Case]:
    """Scale, translation and geometry cases (SDF scenes: scale and translation only).

    Without a ``ground`` object in the base scene (a file imported without ``ground=true``),
    the cases of :data:`NEEDS_GROUND` run on the built-in :data:`BASE_SCENE` instead, and say so.
    """
    cases = [Case(f"scale={_format_value(scale)}", "scene", scale=scale,
                  note=f"scene and views scaled by {scale:.0e} about the origin (rendered in "
                       "the canonical frame: must match the moderate image)",
                  advice=SCALE_ADVICE, compare_image=True)
             for scale, move in SCENE_TRANSFORMS if not move]
    cases += [Case(f"translate={_format_value(move)}", "scene", translate=move,
                   note=f"scene and views moved {move:.0e} from the origin along (1, 1, 1) "
                        "(float64 until the canonical frame: must match the moderate image)",
                   advice=SCALE_ADVICE, compare_image=True)
              for scale, move in SCENE_TRANSFORMS if move]
    if sdf:
        return cases
    geometry = [("grazing", "camera 1e-3 of the diagonal above the ground, looking along it",
                 "avoid views in the plane of large flat surfaces (or raise the ground's "
                 "tessellation)"),
                ("edge-on", "a single-triangle ground seen edge-on (camera in its plane)",
                 "avoid views in the plane of large flat surfaces"),
                ("flipped-normals", "object normals negated (winding kept)",
                 "fix the mesh's normals: surfaces are one-sided"),
                ("degenerate", "zero-area and sliver triangles added to the ground",
                 "remove degenerate triangles before the precompute"),
                ("t-junction", "a T-junction on the ground's diagonal",
                 "weld the mesh: remove T-junctions before a per-vertex precompute"),
                ("coincident", "the ground duplicated in place (z-fighting)",
                 "remove coincident surfaces")]
    if profile == "smoke":
        geometry = [g for g in geometry if g[0] in ("grazing", "edge-on", "degenerate")]
    built_in = {"scene": BASE_SCENE["scene"], "scene_params": dict(BASE_SCENE["scene_params"])}
    elsewhere = (f" (on the built-in {BASE_SCENE['scene']}: the base scene has no object named "
                 "'ground'; a file scene gets one with --scene-param ground=true)")
    return cases + [Case(f"geometry={name}", "scene", geometry=name,
                         note=note + ("" if ground or name not in NEEDS_GROUND else elsewhere),
                         advice=advice,
                         **({} if ground or name not in NEEDS_GROUND else built_in))
                    for name, note, advice in geometry]


def _knob_names(method_cls) -> set[str]:
    return {f.name for f in dataclasses.fields(method_cls.Config)}


def _wavelet_lit(method_cls) -> bool:
    """Whether the method lights with Haar wavelets of a cubemap by default (not SH bands)."""
    fields = {f.name: f for f in dataclasses.fields(method_cls.Config)}
    if "cubemap" not in fields:
        return False
    lighting = fields.get("lighting")
    return "sh_bands" not in fields or (lighting is not None and lighting.default == "wavelet")


def material_advice(method_cls) -> str:
    """What to do instead of an extreme Phong exponent, in the terms of the method's basis."""
    knobs = _knob_names(method_cls)
    if not _wavelet_lit(method_cls):
        return ("use exponents <= 1e3 with <= 8 SH bands: a sharper lobe is truncated to the "
                "bands' blur")
    # Measured (wavelet-tp, s = 1e4): masked FLIP 0.232 at cubemap 16, 0.148 at 32, 0.094 at 64;
    # 0.229 at brdf_keep 512 and 0.232 at 256 light terms: the cubemap, not the kept terms.
    extra = " and reflect_degree (the network's encoding of the mirror direction)" if (
        "reflect_degree" in knobs) else ""
    return (f"use exponents <= 1e3, or raise cubemap{extra}: a near-mirror lobe is narrower than "
            "the cubemap's texels")


def material_cases(method_cls, *, profile: str) -> list[Case]:
    """The Phong exponents of :data:`SHININESS` (for methods that render glossy materials)."""
    advice = material_advice(method_cls)
    return [Case(f"shininess={_format_value(s)}", "material", shininess=s,
                 note="Phong exponent of every glossy material (zonal recurrence, reference "
                      "BRDF sampling)", advice=advice)
            for s in SHININESS[profile]]


def learning_cases(method_cls) -> list[Case]:
    """Training on all-constant targets: the ``plane`` scene (every point's transfer is the
    same), for methods that learn from sampled points (a ``samples`` knob)."""
    if "samples" not in {f.name for f in dataclasses.fields(method_cls.Config)}:
        return []
    return [Case("targets=constant", "learning", scene="plane",
                 note="training on all-constant targets (the unoccluded plane)",
                 advice="a constant transfer needs no network: use vertex PRT")]


MODERATE = Case("moderate", "moderate", note="the method's moderate setting (the comparison)",
                compare_image=False)


def method_cases(method_cls, *, profile: str, scene_file: str | None = None,
                 scene_params: Mapping[str, Any] | None = None) -> list[Case]:
    """The moderate case first, then every case that applies to ``method_cls``.

    With ``scene_file`` the base scene is that file (:func:`base_case`); a method that refuses
    it gets the moderate case only (its refusal is the answer, and every other case would
    repeat it).
    """

    if profile not in PROFILES:

        raise UnknownNameError("stability profile", profile, PROFILES)
    base = base_case(method_cls, scene_file=scene_file, scene_params=scene_params)
    if base.get("file") and not accepts(method_cls, base["scene"], base["variant"],
                                         base["scene_params"]):
        return [MODERATE]
    scene = case_base_scene(base["scene"], base["variant"], base["scene_params"])
    has_ground = any(o.name == "ground" for o in scene.objects)
    cases = [MODERATE, *knob_cases(method_cls, profile=profile),
             *light_cases(method_cls, profile=profile),
             *scene_cases(profile=profile, sdf=scene.sdf is not None, ground=has_ground)]
    cases += edges.method_edge_cases(method_cls, base=base, scene=scene, profile=profile)
    if scene.sdf is None:
        cases += learning_cases(method_cls)
    if scene.sdf is None and accepts(method_cls, base["scene"], "glossy", base["scene_params"]):
        cases += material_cases(method_cls, profile=profile)
    return cases


def select(cases: Sequence[Case], names: Sequence[str] | None) -> list[Case]:
    """``cases`` whose name is in ``names`` (None: all), the moderate case always kept first."""
    if not names:
        return list(cases)
    known = {c.name for c in cases}

    for name in names:
        if name not in known:
            raise UnknownNameError("stability case", name, known)
    return [c for c in cases if c.name == "moderate" or c.name in names]


def is_finite_number(value: Any) -> bool:
    """A real finite number (not None, NaN or ±inf)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
