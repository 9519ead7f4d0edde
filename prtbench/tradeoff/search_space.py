"""The configurations ``prtbench advise`` searches: every registered method, pruned by a scene analysis.

"Model only what the scene requires" (DESIGN.md §15) becomes rules on the analysis
(:func:`prtbench.tradeoff.analyze.analyze_scene`'s ``SceneAnalysis``). Two kinds, kept apart:

**Capability** prunes whole methods, which cannot meet the need at any setting:

* a method that cannot render the scene (its own ``validate`` refuses the materials, the
  surface kind, …) is pruned with that method's message;
* ``needs_glossy`` false: methods whose only addition is glossy transfer (``glossy_only``
  class attribute) are pruned — a diffuse method gives the same image for less;
* ``fixed_light_ok`` false: methods whose precompute bakes one light (``light_dependence``
  other than ``"none"``) are pruned;
* ``needs_bounces`` false prunes methods that cannot turn interreflection off; true prunes
  methods with no ``bounces`` knob.

**Where to start** never excludes a cheaper setting: the analysis' thresholds (1 % irradiance
error, 5 % indirect energy) are not the user's target, so a ladder keeps every step below
the analysed one down to the knob's declared low, and the analysed step is only the first
candidate the search measures (``MethodSpace.start``); what the measurements decide from
there is :func:`prtbench.tradeoff.search._decided`'s business. Steps *above* what the scene
needs may be dropped (they cost more and model nothing the scene has):

* ``required_bands`` (and ``glossy_bands`` when glossy): ``sh_bands`` is searched from the
  knob's low to ``band_margin`` above the required count, clipped to the knob's declared
  range, starting at the required count; a method whose range stops below the requirement
  starts at its top and the gap is recorded (it feeds the "what would be needed" hint);
* ``needs_bounces`` false fixes ``bounces`` at 0; true searches 0–2, starting at 1;
* ``needs_shadows`` false: a ``visibility`` knob, where a method has one, is fixed off;
* ``needs_textures``: ``texture_resolution`` is searched at half, once and twice the profile's
  default; false drops the high resolution.

Every other main knob (a method's ``main_knobs`` class attribute: knobs along which accuracy
and cost both grow) is searched on a short ladder around the profile's default, derived from
the knob's declared bounds (geometric ×2 steps for wide ranges, ±1 for narrow ones), starting
at the default. Nothing here is per-method code: methods are reached through the registry only.
"""

from __future__ import annotations

import dataclasses
import itertools
import typing
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

from prtbench.api import config as config_mod
from prtbench.api.errors import PrtbenchError
from prtbench.api.method import METHODS

#: Knobs whose range the analysis decides (the rest of ``main_knobs`` get generic ladders).
ANALYSIS_KNOBS = ("sh_bands", "bounces", "visibility", "texture_resolution")


@dataclass(frozen=True)
class Candidate:
    """One configuration of one method in the search space.

    Attributes
    ----------
    method : str
    values : tuple of (str, Any)
        The searched and fixed knobs (``--set`` overrides), in the space's knob order.
    ranks : tuple of int
        Position of each searched knob's value on its ascending ladder (for dominance).
    unordered : tuple of (str, Any)
        Searched knobs without an order (choices): candidates compare only when these agree.
    """

    method: str
    values: tuple[tuple[str, Any], ...]
    ranks: tuple[int, ...]
    unordered: tuple[tuple[str, Any], ...] = ()

    @property
    def overrides(self) -> dict[str, Any]:
        return dict(self.values)

    def below(self, other: "Candidate") -> bool:
        """Whether ``other`` models at least as much as this one on every ordered knob
        (same method, same unordered knobs); a candidate is below itself."""
        return (self.method == other.method and self.unordered == other.unordered
                and all(a <= b for a, b in zip(self.ranks, other.ranks)))

    def label(self) -> str:
        """``sh_bands=4 resolution=8`` (searched and fixed knobs)."""
        return " ".join(f"{k}={v}" for k, v in self.values) or "(defaults)"


@dataclass
class MethodSpace:
    """The candidates of one method and how their knob ladders were chosen.

    Attributes
    ----------
    method : str
    ladders : dict of str to list
        Each searched knob's values, ascending.
    fixed : dict of str to Any
        Knobs the analysis fixed (``bounces=0``, ``visibility=False``).
    highs : dict of str to float or None
        Each searched knob's declared upper bound.
    shortfalls : dict of str to str
        Knobs whose declared range stops below what the analysis asks for, and why.
    candidates : list of Candidate
    invalid : int
        Ladder combinations the method's own validation refused (left out of ``candidates``).
    start : Candidate or None
        Where the analysis points (the analysed bands and bounces, every other knob at the
        profile's default): the first candidate the search measures, never a limit on it.
        None when the method refuses that combination.
    """

    method: str
    ladders: dict[str, list]
    fixed: dict[str, Any]
    highs: dict[str, float | None]
    shortfalls: dict[str, str] = field(default_factory=dict)
    candidates: list[Candidate] = field(default_factory=list)
    invalid: int = 0
    start: Candidate | None = None

    def at_top(self, candidate: Candidate) -> list[str]:
        """The searched knobs of ``candidate`` at the top of their ladder."""
        values = candidate.overrides
        return [k for k, ladder in self.ladders.items()
                if len(ladder) and values.get(k) == ladder[-1]]


@dataclass
class SearchSpace:
    """All candidates, per method, and the methods pruned with their reason."""

    methods: list[MethodSpace]
    pruned: list[dict[str, str]]

    @property
    def size(self) -> int:
        return sum(len(m.candidates) for m in self.methods)

    def space_of(self, method: str) -> MethodSpace:
        return next(m for m in self.methods if m.method == method)


def _field_type(config_cls: type, name: str) -> Any:
    tp = typing.get_type_hints(config_cls).get(name, Any)
    args = [a for a in typing.get_args(tp) if a is not type(None)]
    return args[0] if typing.get_origin(tp) in (typing.Union, getattr(__import__("types"), "UnionType", None)) and args else tp


def _clip(values: Iterable[float], low, high, tp) -> list:
    out = []
    for v in values:
        v = tp(round(v)) if tp is int else tp(v)
        if (low is None or v >= low) and (high is None or v <= high) and v not in out:
            out.append(v)
    return sorted(out)


def generic_ladder(f: dataclasses.Field, default: Any, tp: Any) -> tuple[list, bool]:
    """A short ascending ladder of a main knob around ``default``, from its declared bounds.

    Returns (values, ordered). Wide numeric ranges (high/low ≥ 16) step ×2 around the
    default, narrow ones ±1; choices are all searched but have no order; a bool is both.
    """
    meta = f.metadata
    if tp is bool:
        return [False, True], True
    if meta.get("choices"):
        return list(meta["choices"]), False
    if tp not in (int, float) or default is None:
        return [default], True
    low, high = meta.get("low"), meta.get("high")
    wide = default > 0 and (high is None or high / max(low or 1, 1e-12) >= 16)
    values = [default / 2, default, default * 2] if wide else [default - 1, default, default + 1]
    return _clip(values, low, high, tp) or [default], True


def _prune_reason(cls, name: str, scene, base, analysis) -> str | None:
    try:
        cls.validate(scene, base)
    except PrtbenchError as exc:
        return f"cannot render this scene: {exc}"
    if cls.glossy_only and not analysis.needs_glossy:
        return ("models glossy transfer, which this scene does not need (needs_glossy false): "
                "a diffuse method renders the same image for less")
    dependence = getattr(cls, "light_dependence", "none")
    if dependence != "none" and not analysis.fixed_light_ok:
        return (f"its precompute depends on the light ({dependence}), but the lights will "
                "change (fixed_light_ok false)")
    fields = {f.name: f for f in dataclasses.fields(cls.Config)}
    if "bounces" in fields:
        low = fields["bounces"].metadata.get("low") or 0
        if not analysis.needs_bounces and low > 0:
            return (f"always models interreflection (bounces >= {low}), which this scene does "
                    "not need (needs_bounces false)")
    elif analysis.needs_bounces:
        return ("has no bounces knob, so cannot model the interreflection this scene needs "
                "(needs_bounces true)")
    return None


def _analysis_ladder(knob: str, f, default, tp, analysis, *, band_margin: int,
                     space: MethodSpace) -> tuple[list, Any] | None:
    """The ladder the analysis decides for ``knob`` and the step it points at (where the
    search starts), or None if it does not decide the knob.

    The analysis' thresholds are not the user's target, so no ladder stops above the knob's
    declared low: a cheaper step may meet a looser target, and only a measurement may rule
    it out.
    """
    low, high = f.metadata.get("low"), f.metadata.get("high")
    if knob == "sh_bands":
        required = int(analysis.required_bands)
        if analysis.needs_glossy:
            required = max(required, int(analysis.glossy_bands))
        low_bands = int(low or 1)
        if high is not None and required > high:
            space.shortfalls[knob] = (f"the analysis asks for {required} bands; "
                                      f"{space.method} stops at {int(high)}")
        start = max(low_bands, min(required, int(high)) if high is not None else required)
        return _clip(range(low_bands, start + band_margin + 1), low, high, int), start
    if knob == "bounces":
        if not analysis.needs_bounces:
            return (_clip([0], low, high, int) or [int(low)]), None
        ladder = _clip([0, 1, 2], low, high, int) or [int(high or 0)]
        return ladder, min(ladder, key=lambda v: abs(v - 1))
    if knob == "visibility":
        return ([False], False) if not analysis.needs_shadows else None
    if knob == "texture_resolution" and default:
        # Vertices already resolve the shadows: no texels beyond the profile's default. (Not
        # below half of it either: small atlases stop packing big scenes.)
        ladder = _clip([default / 2, default, default * 2], low, high, int)
        return [v for v in ladder if analysis.needs_textures or v <= default] or ladder[:1], default
    return None


def method_space(cls, name: str, scene, analysis, *, profile: str,
                 band_margin: int = 2) -> MethodSpace:
    """The searched ladders and candidates of one (unpruned) method."""

    base = cls.make_config(profile=profile)
    fields = {f.name: f for f in dataclasses.fields(cls.Config)}
    knobs = [k for k in cls.main_knobs if k in fields]
    knobs += [k for k in ANALYSIS_KNOBS if k in fields and k not in knobs]
    space = MethodSpace(name, {}, {}, {})
    ordered: dict[str, bool] = {}
    pointed: dict[str, Any] = {}  # the step the analysis points at, per searched knob
    for knob in knobs:
        f, default, tp = fields[knob], getattr(base, knob), _field_type(cls.Config, knob)
        decided = _analysis_ladder(knob, f, default, tp, analysis, band_margin=band_margin,
                                   space=space)
        if decided is None:
            if knob not in cls.main_knobs:
                continue  # an analysis knob the analysis leaves alone keeps the profile's value
            (ladder, ordered[knob]), pointed[knob] = generic_ladder(f, default, tp), default
        else:
            (ladder, pointed[knob]), ordered[knob] = decided, True
        if len(ladder) == 1:
            space.fixed[knob] = ladder[0]
        else:
            space.ladders[knob] = ladder
            space.highs[knob] = f.metadata.get("high")
    names = list(space.ladders)
    for combo in itertools.product(*(range(len(space.ladders[k])) for k in names)):
        values = {**{k: space.ladders[k][i] for k, i in zip(names, combo)}, **space.fixed}
        try:
            config = config_mod.with_overrides(base, values)
            cls.validate(scene, config)
        except PrtbenchError:
            space.invalid += 1
            continue
        space.candidates.append(Candidate(
            name, tuple((k, values[k]) for k in [*names, *space.fixed]),
            tuple(i for k, i in zip(names, combo) if ordered[k]),
            tuple((k, values[k]) for k in names if not ordered[k])))
    # The start: on each ladder, the step nearest the one the analysis points at.
    start = {k: min(ladder, key=lambda v: (_distance(v, pointed.get(k)), ladder.index(v)))
             for k, ladder in space.ladders.items()}
    space.start = next((c for c in space.candidates
                        if all(c.overrides[k] == v for k, v in start.items())), None)
    return space


def _distance(value: Any, pointed: Any) -> float:
    """How far a ladder step is from the step the analysis points at (0: the same)."""
    if value == pointed:
        return 0.0
    try:
        return abs(float(value) - float(pointed))
    except (TypeError, ValueError):  # unordered choices: any other step is as far
        return float("inf")


def build_space(scene, analysis, *, profile: str, methods: Sequence[str] | None = None,
                band_margin: int = 2) -> SearchSpace:
    """Prune the registered methods with ``analysis`` and build the remaining candidates.

    Parameters
    ----------
    scene : prtbench.scene.model.Scene
        The scene (its variant decides which methods can render it).
    analysis : SceneAnalysis-like
        Has ``required_bands``, ``needs_glossy``, ``glossy_bands``, ``needs_shadows``,
        ``needs_textures``, ``needs_bounces``, ``fixed_light_ok``.
    profile : str
        The profile whose per-method defaults centre the generic ladders.
    methods : sequence of str, optional
        Only these registered methods (default: all).
    band_margin : int
        Bands searched above the required count.

    Returns
    -------
    SearchSpace
    """

    names = list(methods) if methods is not None else METHODS.names()
    spaces, pruned = [], []
    for name in names:
        try:
            cls = METHODS.get(name)
        except ImportError as exc:
            pruned.append({"method": name, "why": f"cannot import: {str(exc).splitlines()[0]}"})
            continue
        why = _prune_reason(cls, name, scene, cls.make_config(profile=profile), analysis)
        if why is None:
            space = method_space(cls, name, scene, analysis, profile=profile,
                                 band_margin=band_margin)
            if space.candidates:
                spaces.append(space)
                continue
            why = f"no valid configuration in the searched ranges ({space.invalid} refused)"
        pruned.append({"method": name, "why": why})
    return SearchSpace(spaces, pruned)


def analysis_json(analysis: Any) -> dict[str, Any]:
    """The analysis as a JSON-able dict (its ``to_json()`` when it has one)."""
    if hasattr(analysis, "to_json"):
        return dict(analysis.to_json())
    if dataclasses.is_dataclass(analysis):
        return dataclasses.asdict(analysis)
    return dict(vars(analysis))

