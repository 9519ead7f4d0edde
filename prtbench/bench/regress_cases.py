"""Regression cases of a team's own: a TOML cases file (``prtbench regress --cases FILE``).

By default ``prtbench regress`` measures each registered method's own regression case
(:func:`prtbench.bench.regress.regression_case`). A cases file replaces those with cases of its
own, e.g. a team's scene (an asset file) under its own method (a plug-in registered through the
``prtbench.methods`` entry points, ``docs/ADDING_A_METHOD.md``), with a baseline file of its own
(``--baselines``)::

    [[case]]
    name = "crate-vertex"             # the baseline key and the JUnit class: letters, digits, _ - :
    method = "vertex"                 # a registered method (prtbench list methods), plug-ins too
    scene = "scenes/crate.glb"        # a built-in scene name, or a file (glTF/GLB, OBJ, PLY, OFF,
                                      #   STL; "a.glb+b.obj" joins files) relative to this file
    variant = "diffuse"               # optional: diffuse (default) or glossy
    light = "sky"                     # optional: a light name (default sky) or an .exr/.hdr file,
                                      #   relative to this file
    scene_params = { ground = true }  # optional: scene builder or file import parameters
    overrides = { sh_bands = 4 }      # optional: config knobs, strict (prtbench describe METHOD)

Every case runs in the ``smoke`` profile, like the built-in ones. Everything is checked before any
work, and a mistake is one line naming the file, the case and the bad key or value: unknown keys,
methods, knobs, scenes, lights and variants, values a method's config or a scene rejects, and a
case that fails only as a whole (:func:`prtbench.bench.runner.prepare`: a method that cannot
handle the scene, an unreadable scene file).

The baseline entry of a case records the case as written (``method``, ``scene``, ``variant``,
``light``, ``scene_params``, ``overrides``) and, for files, their SHA-256 (``scene_sha256``: the
file and its sidecar files, ``light_sha256``), so an edited scene file makes its baseline stale
(a FAIL asking for ``--update``) instead of comparing new pixels with old numbers.
"""

from __future__ import annotations

import hashlib
import json
import re
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

from prtbench.api.errors import InvalidInputError, PrtbenchError, UnknownNameError
from prtbench.api.method import METHODS
from prtbench.bench.job import Job
from prtbench.bench.runner import prepare
from prtbench.scene.files import SUFFIXES
from prtbench.scene.model import VARIANTS
from prtbench.scene.registry import SCENES
from prtbench.transport.lights import HDR_SUFFIXES, LIGHTS

#: The case every method is regressed on unless its ``regression_case`` says otherwise, and
#: the defaults of a cases file's ``variant`` and ``light``.
DEFAULT_CASE = {"scene": "plants", "variant": "diffuse", "light": "sky"}
#: Keys accepted at the top level of a cases file.
TOP_KEYS = ("case",)
#: Keys accepted in a ``[[case]]`` table.
CASE_KEYS = ("name", "method", "scene", "variant", "light", "scene_params", "overrides")
#: A case name: it prefixes printed lines, keys the baseline file and names a JUnit class.
NAME_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9_:-]*")
#: Regression cases run in this profile.
PROFILE = "smoke"


@dataclass(frozen=True)
class RegressionCase:
    """One case of a cases file, validated.

    Attributes
    ----------
    name : str
        Its baseline key and printed name.
    job : Job
        What is measured (smoke profile; file paths made absolute).
    record : dict
        The case as the baseline entry stores it (see the module docstring).
    """

    name: str
    job: Job
    record: Mapping[str, Any]


def load_cases(path: str | Path) -> tuple[RegressionCase, ...]:
    """Read and validate the cases file at ``path`` (schema: the module docstring).

    Raises
    ------
    InvalidInputError
        One line naming the file (and the case, key and value) for any mistake; TOML syntax
        errors carry TOML's line and column.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InvalidInputError(f"cases file '{path}' not found; accepted: a TOML file of "
                                "[[case]] tables (docs/ci.md)") from None
    except IsADirectoryError:
        raise InvalidInputError(f"cases file '{path}' is a folder; accepted: a TOML file of "
                                "[[case]] tables (docs/ci.md)") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InvalidInputError(f"cases file '{path}' cannot be read: {exc}") from None
    try:
        spec = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:  # its message ends "(at line L, column C)"
        raise InvalidInputError(f"cases file '{path}': malformed TOML: {exc}") from None
    return parse_cases(spec, source=str(path), base=path.resolve().parent)


def parse_cases(spec: Mapping[str, Any], *, source: str,
                base: Path) -> tuple[RegressionCase, ...]:
    """Validate a parsed cases file; ``base`` is the folder relative file paths start from."""
    where = f"cases file '{source}'"
    for key in spec:
        if key not in TOP_KEYS:
            unknown = UnknownNameError("top-level key", str(key), TOP_KEYS)
            raise InvalidInputError(f"{where}: {unknown} (one [[case]] table per case)")
    tables = spec.get("case")
    if not isinstance(tables, list) or not tables or not all(isinstance(t, Mapping)
                                                             for t in tables):
        raise InvalidInputError(f"{where}: no [[case]] tables; accepted: one or more [[case]] "
                                "tables with name, method and scene")
    cases: list[RegressionCase] = []
    for number, table in enumerate(tables, 1):
        case = _parse_case(table, f"{where}, [[case]] #{number}", base)
        if any(c.name == case.name for c in cases):
            raise InvalidInputError(f"{where}: case name '{case.name}' appears twice; accepted: "
                                    "one [[case]] per name (it keys the baseline file)")
        cases.append(case)
    return tuple(cases)


def _text(table: Mapping[str, Any], key: str, where: str, *, default: str | None = None) -> str:
    value = table.get(key, default)
    if value is None:
        raise InvalidInputError(f"{where}: no '{key}'; accepted: {key} = \"...\" "
                                f"(keys: {', '.join(CASE_KEYS)})")
    if not isinstance(value, str) or not value:
        raise InvalidInputError(f"{where}: '{key}' = {value!r}; accepted: a non-empty string")
    return value


def _table(table: Mapping[str, Any], key: str, where: str, accepted: str) -> dict[str, Any]:
    value = table.get(key, {})
    if not isinstance(value, Mapping):
        raise InvalidInputError(f"{where}: '{key}' = {value!r}; accepted: {accepted}")
    try:  # the baseline file stores it as JSON and compares it after a round trip
        if json.loads(json.dumps(dict(value))) != dict(value):
            raise TypeError
    except (TypeError, ValueError):
        raise InvalidInputError(f"{where}: '{key}' = {value!r}; accepted: strings, numbers, "
                                "booleans, arrays and tables (no dates or times)") from None
    return dict(value)


def _resolve(text: str, base: Path) -> str:
    """A scene or light path relative to the cases file made absolute (``+`` joins files)."""
    parts = [text] if "+" not in text or (base / text).is_file() else text.split("+")
    return "+".join(p if Path(p).is_absolute() else str(base / p) for p in parts)


def _is_file_scene(text: str) -> bool:
    return any(p.lower().endswith(SUFFIXES) or "/" in p or "\\" in p for p in text.split("+"))


def _parse_case(table: Mapping[str, Any], where: str, base: Path) -> RegressionCase:
    for key in table:
        if key not in CASE_KEYS:
            unknown = UnknownNameError("[[case]] key", str(key), CASE_KEYS)
            raise InvalidInputError(f"{where}: {unknown}")
    name = _text(table, "name", where)
    if not NAME_PATTERN.fullmatch(name):
        raise InvalidInputError(f"{where}: name = {name!r}; accepted: letters, digits, '_', '-' "
                                "and ':', starting with a letter or digit")
    where = f"{where.rsplit(', ', 1)[0]}, case '{name}'"
    method = _text(table, "method", where)
    try:
        method_cls = METHODS.get(method)
    except PrtbenchError as exc:
        raise InvalidInputError(f"{where}: {exc}") from None
    scene = _text(table, "scene", where)
    variant = _text(table, "variant", where, default=DEFAULT_CASE["variant"])
    if variant not in VARIANTS:
        raise InvalidInputError(f"{where}: {UnknownNameError('variant', variant, VARIANTS)}")
    light = _text(table, "light", where, default=DEFAULT_CASE["light"])
    light_file = light.lower().endswith(HDR_SUFFIXES)
    if not light_file and light not in LIGHTS.names():
        raise InvalidInputError(f"{where}: {UnknownNameError('light', light, LIGHTS.names())} "
                                f"(or a light file: {', '.join(HDR_SUFFIXES)})")
    scene_params = _table(table, "scene_params", where, "a table of scene parameters")
    overrides = _table(table, "overrides", where, "a table of knob = value")
    knobs = [f.name for f in fields(method_cls.Config)]
    for key in overrides:
        if key not in knobs:
            raise InvalidInputError(f"{where}: {UnknownNameError('knob', key, knobs)}")
    scene_file = _is_file_scene(scene)
    if not scene_file:
        try:
            SCENES.check(scene)
        except PrtbenchError as exc:
            raise InvalidInputError(f"{where}: {exc} (or a scene file: "
                                    f"{', '.join(SUFFIXES)})") from None
    job = Job(method=method, scene=_resolve(scene, base) if scene_file else scene,
              variant=variant, light=_resolve(light, base) if light_file else light,
              overrides=overrides, scene_params=scene_params, profile=PROFILE)
    try:  # the whole case, as the run will see it: knob values, scene parameters, files
        prepared = prepare(job, store=False)
    except PrtbenchError as exc:
        raise InvalidInputError(f"{where}: {exc}") from None
    record: dict[str, Any] = {"method": method, "scene": scene, "variant": variant,
                              "light": light, "scene_params": scene_params,
                              "overrides": overrides}
    if scene_file:
        record["scene_sha256"] = prepared.scene.params["file_sha256"]
    if light_file:
        record["light_sha256"] = hashlib.sha256(Path(job.light).read_bytes()).hexdigest()
    return RegressionCase(name, job, record)
