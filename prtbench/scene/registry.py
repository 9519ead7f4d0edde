"""The scene registry: built-in scene builders by name, and scenes from files (DESIGN.md §16).

Builders register with :func:`register_scene` (the built-in ones are declared lazily in
``pyproject.toml``, group ``prtbench.scenes``); :func:`get_scene` types and checks the builder's
parameters, builds the scene, checks its extent and puts it in its canonical frame
(:mod:`prtbench.scene.frame`). A name that is a path to an asset file is imported from that
file (:mod:`prtbench.scene.files`), in the canonical frame too.
"""

from __future__ import annotations

import difflib
import inspect
from collections.abc import Callable
from typing import Any

from prtbench.api.errors import InvalidInputError
from prtbench.api.registry import Registry
from prtbench.scene.files import build_file_scene, is_scene_path
from prtbench.scene.frame import canonical_from_world, is_conditioned, moved_scene
from prtbench.scene.model import VARIANTS, Scene
from prtbench.scene.params import check_extent, check_params

SceneBuilder = Callable[..., Scene]


class _SceneRegistry(Registry):
    """The scene registry; :meth:`check` also accepts asset file paths (DESIGN.md §16)."""

    def check(self, name: str) -> str:
        return name if is_scene_path(name) else super().check(name)


#: Scene builders: ``build(*, variant="diffuse", **params) -> Scene``.
SCENES: Registry[SceneBuilder] = _SceneRegistry("scene", entry_point_group="prtbench.scenes")


def register_scene(name: str, *, params: dict[str, Any] | None = None,
                   ) -> Callable[[SceneBuilder], SceneBuilder]:
    """Decorator registering a scene builder under ``name``.

    ``params`` maps each builder parameter to its :class:`~prtbench.scene.params.SceneParam`
    (type, range, memory estimate); :func:`get_scene` checks values against it before building.
    """

    def decorator(builder: SceneBuilder) -> SceneBuilder:
        builder.scene_params = dict(params or {})  # type: ignore[attr-defined]
        return SCENES.register(name)(builder)

    return decorator


def get_scene(name: str, *, variant: str = "diffuse", **params: Any) -> Scene:
    """Build the registered scene ``name`` in material ``variant`` with builder ``params``.

    A ``name`` ending in .glb/.gltf/.obj/.ply/.off/.stl (or a path to an existing file) is
    imported from that file instead (:mod:`prtbench.scene.files`; params ``scale``, ``up``,
    ``ground``).

    A built scene whose bounds are well conditioned (:func:`prtbench.scene.frame.is_conditioned`:
    every built-in scene at its default parameters) is returned as built; any other is moved
    to the canonical frame (centred, bounds diagonal 2), ``world_from_canonical`` recording
    where it was built.
    """

    if is_scene_path(name):
        return build_file_scene(name, variant=variant, **params)
    builder = SCENES.get(name)
    if variant not in VARIANTS:
        raise InvalidInputError(f"unknown variant '{variant}'; known: {', '.join(VARIANTS)}")
    signature = inspect.signature(builder).parameters
    accepted = [p for p in signature if p != "variant"]
    for key in params:
        if key not in accepted:
            # The did-you-mean of prtbench.api.errors.UnknownNameError, in this message's words.
            close = difflib.get_close_matches(key, accepted, n=1, cutoff=0.5)
            hint = f"; did you mean '{close[0]}'?" if close else ";"
            raise InvalidInputError(f"scene '{name}' has no parameter '{key}'{hint} accepted: "
                                    f"{', '.join(accepted) or '(none)'}")

    # Command-line values arrive as strings: give them the declared type (else the type of the
    # builder's default), so `--scene-param ground_subdivisions=64` and a sweep's int 64 build
    # (and cache) one scene; declared ranges and memory bounds are checked before building.
    specs = getattr(builder, "scene_params", {})
    typed = {key: value if key in specs else _typed_param(name, key, value,
                                                          signature[key].default)
             for key, value in params.items()}
    typed = check_params(name, specs, typed)
    scene = builder(variant=variant, **typed)
    if not scene.objects or scene.n_triangles == 0:
        raise InvalidInputError(f"scene '{scene.name}' has no triangles")
    lo, hi = scene.bounds()
    check_extent(scene.name, lo, hi, typed)
    if is_conditioned(lo, hi):  # bit-identical to the scene as built (caches, golden metrics)
        return scene
    return moved_scene(scene, canonical_from_world(lo, hi))


def _typed_param(scene: str, key: str, value: Any, default: Any) -> Any:
    if not isinstance(value, str) or isinstance(default, str) or default is inspect.Parameter.empty:
        return value
    try:
        if isinstance(default, bool):
            low = value.lower()
            if low not in ("true", "false", "1", "0", "yes", "no"):
                raise ValueError
            return low in ("true", "1", "yes")
        if isinstance(default, int):
            return int(value)
        if isinstance(default, float):
            return float(value)
    except ValueError:
        raise InvalidInputError(f"scene '{scene}' parameter {key}={value!r}; accepted: "
                                f"{type(default).__name__}") from None
    return value

