"""The scene registry: built-in scene builders by name, and scenes from files (DESIGN.md §16).

Builders register with :func:`register_scene` (the built-in ones are declared lazily in
``pyproject.toml``, group ``prtbench.scenes``); :func:`get_scene` types and checks the builder's
parameters, builds the scene and checks its extent. A name that is a path to an asset file is
imported from that file (:mod:`prtbench.scene.files`).
"""

from __future__ import annotations

import inspect
from collections.abc import Callable
from typing import Any

from prtbench.api.errors import InvalidInputError
from prtbench.api.registry import Registry
from prtbench.scene.files import build_file_scene, is_scene_path
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
            raise InvalidInputError(
                f"scene '{name}' has no parameter '{key}'; accepted: {', '.join(accepted) or '(none)'}")

    # Command-line values arrive as strings: give them the declared type (else the type of the
    # builder's default), so `--scene-param ground_subdivisions=64` and a sweep's int 64 build
    # (and cache) one scene; declared ranges and memory bounds are checked before building.
    specs = getattr(builder, "scene_params", {})
    typed = {key: value if key in specs else _typed_param(name, key, value,
                                                          signature[key].default)
             for key, value in params.items()}
    typed = check_params(name, specs, typed)
    scene = builder(variant=variant, **typed)
    check_extent(scene, typed)
    return scene


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

