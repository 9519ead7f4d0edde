"""Declarative sweep grids: a TOML file or CLI options → validated :class:`~prtbench.bench.reproduction.Job` s.

A sweep file (``sweeps/*.toml``, read with :mod:`tomllib`) has defaults at the top level and
one ``[[method]]`` table per method::

    profile = "smoke"            # default profile (``prtbench sweep --profile`` wins)
    scenes = ["plants"]          # or: scene = "plants"
    lights = ["sky"]             # or: light = "sky"; omitted: each scene's default light
    variant = "diffuse"          # material variant (diffuse, glossy)
    views = 1                    # trajectory views (omitted: the profile's count)
    reference = "path"           # path or method:<name>
    reference_bounces = 1        # bounces of the path reference, one for every method (omitted:
                                 # each method's own bounces knob, which splits the panels)
    scene_params = { }           # scene builder parameters

    [[method]]
    name = "vertex"                               # a registered method (prtbench list methods)
    grid = { sh_bands = [3, 4, 5, 6] }            # knob -> list of values: the Cartesian product
    fixed = { rays_per_point = 128 }              # knobs set in every cell of this method
    # optional per-method overrides of scenes, lights, variant, views, reference, scene_params

Each method's cells are the product of its ``grid`` lists, over its scenes and lights; a
cell's ``label`` is its grid values (as the method's config parses them). A method with no
``grid`` contributes one cell (its ``fixed`` knobs, else its profile defaults).

Everything is validated before any work, with the method's own strict config
(``METHODS.get(name).make_config(overrides, profile=...)``) and :func:`prtbench.bench.runner.prepare`:
unknown keys, methods, knobs, scenes and lights, and a value the config rejects on its own are
one-line errors naming the bad value and the accepted ones. A *combination* that only fails
together (a method that cannot handle one of the scenes, knobs that contradict each other) is
dropped and reported in :attr:`Sweep.dropped`; a method left with no valid cell is an error.
"""

from __future__ import annotations

import itertools
import re
import tomllib
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from prtbench.api.config import to_dict
from prtbench.api.errors import InvalidInputError, PrtbenchError, UnknownNameError
from prtbench.api.method import METHODS
from prtbench.api.profiles import get_profile
from prtbench.bench.job import Job
from prtbench.bench.runner import prepare
from prtbench.scene.model import VARIANTS
from prtbench.scene.registry import SCENES
from prtbench.transport.lights import LIGHTS

#: Keys accepted at the top level of a sweep file.
TOP_KEYS = ("profile", "scene", "scenes", "light", "lights", "variant", "views", "reference",
            "reference_bounces", "scene_params", "method")
#: Keys accepted in a ``[[method]]`` table.
METHOD_KEYS = ("name", "grid", "fixed", "scene", "scenes", "light", "lights", "variant", "views",
               "reference", "reference_bounces", "scene_params")
#: Defaults a ``[[method]]`` table may override.
_INHERITED = ("scenes", "lights", "variant", "views", "reference", "reference_bounces",
              "scene_params")


@dataclass(frozen=True)
class Sweep:
    """An expanded, validated sweep.

    Attributes
    ----------
    cells : tuple of Job
        Every valid cell, in file order (method, scene, light, then grid order).
    profile : str
        The profile the cells were validated for.
    source : str
        Where the grid came from (the file path, or ``command line``).
    dropped : tuple of (Job, str)
        Combinations that failed validation together, with the one-line reason.
    """

    cells: tuple[Job, ...]
    profile: str
    source: str
    dropped: tuple[tuple[Job, str], ...] = field(default=())


def load_sweep(path: str | Path, *, profile: str | None = None) -> Sweep:
    """Read and expand the sweep file at ``path``.

    Parameters
    ----------
    path : str or Path
        A TOML file in the schema of this module's docstring.
    profile : str, optional
        Overrides the file's ``profile`` (default: the file's, else ``quick``).

    Raises
    ------
    PrtbenchError
        A missing or malformed file (one line with the file and TOML's line/column), or any
        validation error of :func:`expand`.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InvalidInputError(f"sweep file '{path}' not found; accepted: a TOML sweep file "
                                f"(e.g. sweeps/plants-all.toml)") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InvalidInputError(f"sweep file '{path}' cannot be read: {exc}") from None
    try:
        spec = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:  # its message ends "(at line L, column C)"
        raise InvalidInputError(f"sweep file '{path}': malformed TOML: {exc}") from None
    return expand(spec, source=str(path), profile=profile)


def split_values(text: str, *, option: str = "value list", given: str | None = None) -> list[str]:
    """``"3,4,[2,1,2]"`` → ``["3", "4", "[2,1,2]"]``: commas inside brackets do not split.

    Parameters
    ----------
    text : str
        Comma-separated values.
    option, given : str
        The option and the text as the user gave it (default ``text``), for the message.

    Raises
    ------
    InvalidInputError
        An empty value (``3,,4``, ``3,4,``, ``''``) or unbalanced brackets: a value dropped
        in silence would shrink the grid without a word.
    """
    shown = text if given is None else given
    parts, depth, current = [], 0, []
    for char in text:
        depth += {"[": 1, "]": -1}.get(char, 0)
        if depth < 0:
            break
        if char == "," and depth == 0:
            parts.append("".join(current).strip())
            current = []
        else:
            current.append(char)
    if depth != 0:
        raise InvalidInputError(f"{option} '{shown}' has unbalanced brackets; accepted: "
                                f"comma-separated values, a list value in [ ] (e.g. 3,[2,1,2])")
    parts.append("".join(current).strip())
    if not all(parts):
        raise InvalidInputError(f"{option} '{shown}' has an empty value; accepted: "
                                f"comma-separated values, none empty (e.g. 3,4,5)")
    return parts


def from_options(*, scenes: Sequence[str], methods: Sequence[str], grid: Iterable[str] = (),
                 fixed: Mapping[str, Any] | None = None, lights: Sequence[str] = (),
                 variant: str = "diffuse", views: int | None = None,
                 scene_params: Mapping[str, Any] | None = None, reference: str = "path",
                 reference_bounces: int | None = None, profile: str = "quick") -> Sweep:
    """The sweep of ``prtbench sweep --scene … --method … --grid knob=v1,v2 …``.

    Parameters
    ----------
    scenes, methods, lights : sequence of str
        Names (the CLI splits comma lists); no lights: each scene's default light.
    grid : iterable of str
        ``knob=v1,v2,...`` items; every method gets the same grid (each must have the knob).
    fixed : mapping, optional
        Knobs set in every cell (the CLI's ``--set``).
    """
    table_grid: dict[str, list[str]] = {}
    for item in grid:
        key, sep, values = item.partition("=")
        key = key.strip()
        if not sep or not key or not values.strip():
            raise InvalidInputError(f"--grid '{item}'; accepted: KNOB=V1,V2,... "
                                    f"(e.g. sh_bands=3,4,5,6)")
        if key in table_grid:
            raise InvalidInputError(f"--grid '{key}' given twice; accepted: one --grid per knob")
        table_grid[key] = split_values(values, option="--grid", given=item)
    spec: dict[str, Any] = {
        "profile": profile, "scenes": list(scenes), "variant": variant, "reference": reference,
        "scene_params": dict(scene_params or {}),
        "method": [{"name": m, "grid": table_grid, "fixed": dict(fixed or {})} for m in methods]}
    if lights:
        spec["lights"] = list(lights)
    if views is not None:
        spec["views"] = views
    if reference_bounces is not None:
        spec["reference_bounces"] = reference_bounces
    return expand(spec, source="command line", profile=profile)


def expand(spec: Mapping[str, Any], *, source: str, profile: str | None = None) -> Sweep:
    """Validate a parsed sweep ``spec`` and expand it into cells (see the module docstring).

    Writes nothing; raises a one-line :class:`PrtbenchError` (prefixed with ``source``) for
    any mistake, and when a method has no valid cell.
    """

    where = f"sweep {source}" if source == "command line" else f"sweep file '{source}'"
    _check_keys(spec, TOP_KEYS, where, "top-level key")
    profile = profile or _typed(spec, "profile", str, where) or "quick"
    get_profile(profile)
    defaults = _defaults(spec, where)
    tables = spec.get("method")
    if not isinstance(tables, list) or not tables or not all(isinstance(t, Mapping) for t in tables):
        raise InvalidInputError(f"{where}: no [[method]] tables; accepted: one or more "
                                f"[[method]] tables with name = \"<method>\" and a grid")
    cells: list[Job] = []
    dropped: list[tuple[Job, str]] = []
    for number, table in enumerate(tables, 1):
        made, lost = _expand_method(table, defaults, profile, f"{where}, [[method]] #{number}")
        cells += made
        dropped += lost
    return Sweep(tuple(cells), profile, source, tuple(dropped))


def _check_keys(table: Mapping[str, Any], accepted: Sequence[str], where: str, kind: str) -> None:
    for key in table:
        if key not in accepted:
            raise InvalidInputError(f"{where}: {UnknownNameError(kind, str(key), accepted)}")


def _typed(table: Mapping[str, Any], key: str, kind: type | tuple[type, ...], where: str):
    value = table.get(key)
    if value is not None and (not isinstance(value, kind) or isinstance(value, bool) and kind is int):
        names = "/".join(k.__name__ for k in (kind if isinstance(kind, tuple) else (kind,)))
        raise InvalidInputError(f"{where}: '{key}' = {value!r}; accepted: a {names}")
    return value


def _names(table: Mapping[str, Any], one: str, many: str, where: str) -> list[str] | None:
    """``scene = "x"`` or ``scenes = ["x", ...]`` → a list (None when neither is given)."""
    if one in table and many in table:
        raise InvalidInputError(f"{where}: both '{one}' and '{many}'; accepted: one of them")
    if one in table:
        return [_typed(table, one, str, where)]
    if many in table:
        values = table[many]
        if (not isinstance(values, list) or not values
                or not all(isinstance(v, str) and v for v in values)):
            raise InvalidInputError(f"{where}: '{many}' = {values!r}; accepted: a non-empty list "
                                    f"of names")
        return list(values)
    return None


def _defaults(table: Mapping[str, Any], where: str) -> dict[str, Any]:
    out: dict[str, Any] = {}
    scenes = _names(table, "scene", "scenes", where)
    lights = _names(table, "light", "lights", where)
    if scenes is not None:
        out["scenes"] = scenes
    if lights is not None:
        out["lights"] = lights
    for key, kind in (("variant", str), ("views", int), ("reference", str),
                      ("reference_bounces", int)):
        if key in table:
            out[key] = _typed(table, key, kind, where)
    if "scene_params" in table:
        if not isinstance(table["scene_params"], Mapping):
            raise InvalidInputError(f"{where}: 'scene_params' = {table['scene_params']!r}; "
                                    f"accepted: a table of scene builder parameters")
        out["scene_params"] = dict(table["scene_params"])
    return out


def _knob_values(table: Mapping[str, Any], key: str, where: str) -> dict[str, Any]:
    value = table.get(key, {})
    if not isinstance(value, Mapping):
        raise InvalidInputError(f"{where}: '{key}' = {value!r}; accepted: a table of knob = "
                                f"{'[values]' if key == 'grid' else 'value'}")
    return dict(value)


def _expand_method(table: Mapping[str, Any], defaults: Mapping[str, Any], profile: str,
                   where: str) -> tuple[list[Job], list[tuple[Job, str]]]:

    _check_keys(table, METHOD_KEYS, where, "[[method]] key")
    name = _typed(table, "name", str, where)
    if not name:
        raise InvalidInputError(f"{where}: no 'name'; accepted: name = \"<method>\" (one of "
                                f"{', '.join(METHODS.names())})")
    try:
        method_cls = METHODS.get(name)
    except PrtbenchError as exc:
        raise InvalidInputError(f"{where}: {exc}") from None
    where = f"{where.rsplit(', ', 1)[0]}, method '{name}'"
    settings = {**defaults, **_defaults(table, where)}
    grid, fixed = _knob_values(table, "grid", where), _knob_values(table, "fixed", where)
    knobs = [f.name for f in fields(method_cls.Config)]
    for key in [*grid, *fixed]:
        if key not in knobs:
            raise InvalidInputError(f"{where}: {UnknownNameError('knob', key, knobs)}")
    for key in grid:
        if key in fixed:
            raise InvalidInputError(f"{where}: knob '{key}' is both in grid and fixed; accepted: "
                                    f"one of them")
        values = grid[key]
        if not isinstance(values, list) or not values:
            raise InvalidInputError(f"{where}: grid {key} = {values!r}; accepted: a non-empty "
                                    f"list of values, e.g. {key} = [a, b, c]")
    try:  # every value the config rejects on its own is a mistake, not a dropped combination
        method_cls.make_config(fixed, profile=profile)
        for key, values in grid.items():
            for value in values:
                method_cls.make_config({**fixed, key: value}, profile=profile)
    except PrtbenchError as exc:
        raise InvalidInputError(f"{where}: {exc}") from None
    scenes = settings.get("scenes") or []
    if not scenes:
        raise InvalidInputError(f"{where}: no scene; accepted: scene = \"<name>\" or scenes = "
                                f"[...] at the top level or in the [[method]] table")
    for scene in scenes:
        try:
            SCENES.check(scene)
        except PrtbenchError as exc:
            raise InvalidInputError(f"{where}: {exc}") from None
    variant = settings.get("variant", "diffuse")
    if variant not in VARIANTS:
        raise InvalidInputError(f"{where}: {UnknownNameError('variant', variant, VARIANTS)}")
    lights = settings.get("lights") or [None]
    for light in lights:
        if light is not None:
            _check_light(light, where)
    cells, dropped = [], []
    combos = list(itertools.product(*grid.values())) if grid else [()]
    for scene, light, combo in itertools.product(scenes, lights, combos):
        overrides = {**fixed, **dict(zip(grid, combo))}
        cell = Job(method=name, scene=scene, label=dict(zip(grid, combo)), variant=variant,
                    light=light, overrides=overrides,
                    scene_params=dict(settings.get("scene_params", {})),
                    reference=settings.get("reference", "path"),
                    reference_bounces=settings.get("reference_bounces"),
                    views=settings.get("views"))
        try:
            prepared = prepare_cell(cell, profile=profile, reuse=True)
        except PrtbenchError as exc:
            dropped.append((cell, str(exc)))
            continue
        # Label and overrides as the config parsed them ("3" on the command line is 3).

        typed = to_dict(prepared.config)
        typed_cell = Job(method=name, scene=scene, label={k: typed[k] for k in grid},
                          variant=variant, light=light,
                          overrides={k: typed[k] for k in overrides},
                          scene_params=cell.scene_params, reference=cell.reference,
                          reference_bounces=cell.reference_bounces, views=cell.views)
        _VALIDATED[repr((typed_cell, profile, None, False))] = prepared  # run_cells reuses it
        cells.append(typed_cell)
    if not cells:
        first = dropped[0][1] if dropped else "no combination"
        raise InvalidInputError(f"{where}: no valid cell in its grid ({len(dropped)} "
                                f"combination(s) rejected; first: {first})")
    return cells, dropped


def _check_light(light: str, where: str) -> None:
    if light in LIGHTS.names() or re.search(r"\.(exr|hdr)$", light, re.IGNORECASE):
        return  # a path is checked (read) by prepare
    raise InvalidInputError(f"{where}: {UnknownNameError('light', light, LIGHTS.names())} "
                            f"(or an .exr/.hdr path)")


#: Validated cells (see :func:`prepare_cell`): building a scene dominates ``prepare``
#: (0.2-0.6 s for plants) and a sweep validates each cell twice (expansion, run_cells).
_VALIDATED: dict[str, Any] = {}
_VALIDATED_MAX = 1024


def prepare_cell(cell: Job, *, profile: str, results_path: Path | None = None,
                 store_results: bool = False, reuse: bool = False):
    """:func:`prtbench.bench.runner.prepare` of ``cell`` in ``profile`` (no images; rows only if
    ``store_results``, which also checks the store at ``results_path``). Writes nothing.

    ``reuse``: return the run prepared by an earlier ``reuse`` call for the same arguments
    (for validation only; a cell is always measured from a fresh ``prepare``).
    """

    memo = repr((cell, profile, results_path, store_results)) if reuse else None
    if memo is not None and memo in _VALIDATED:
        return _VALIDATED[memo]
    prepared = prepare(cell, profile=profile, results_path=results_path, store=store_results)
    if memo is not None:
        if len(_VALIDATED) >= _VALIDATED_MAX:
            _VALIDATED.clear()
        _VALIDATED[memo] = prepared
    return prepared
