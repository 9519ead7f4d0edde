"""A stability case and the base scene every method's cases start from (issue #15).

:class:`Case` is one extreme setting of one method; :data:`BASE_SCENE` the scene its cases are
measured on unless the method refuses it; :func:`accepts` asks a method whether it takes a
scene. The catalogue that generates cases is :mod:`prtbench.stability.cases`; cases at a
method's own edges are :mod:`prtbench.stability.edges`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from prtbench.api.errors import PrtbenchError
from prtbench.scene.registry import get_scene

#: Profiles the stability matrix runs in (``smoke`` is a subset: fewer values per rule).
PROFILES = ("smoke", "quick")
#: The scene every mesh method is measured on, and its light.
BASE_SCENE = {"scene": "sphere-over-plane", "variant": "diffuse", "light": "sky",
              "scene_params": {"sphere_segments": 32, "plane_size": 4.0}}

@dataclass(frozen=True)
class Case:
    """One extreme setting of one method.

    Attributes
    ----------
    name : str
        Unique within a method, e.g. ``sh_bands=1``, ``light=black``, ``scale=1e-04``.
    group : str
        ``moderate``, ``knob``, ``storage``, ``learning``, ``sampling``, ``material``,
        ``light`` or ``scene``.
    overrides : dict
        Config knobs on top of the moderate config.
    light : str
        A :data:`prtbench.stability.lights.LIGHTS` name, or ``""`` for the base light.
    shininess : float or None
        Phong exponent given to every glossy material (the glossy variant is used).
    scale, translate : float
        The scene (and its views) scaled about the origin, then moved by ``translate`` along
        (1, 1, 1)/√3.
    geometry : str
        ``""``, ``grazing`` (camera 10⁻³ of the diagonal above the ground, looking along it),
        ``edge-on`` (the ground as one triangle, the camera in its plane),
        ``flipped-normals`` (the non-ground objects' normals negated), ``degenerate``
        (zero-area and sliver triangles added to the ground), ``t-junction`` (a T-junction
        on the ground) or ``coincident`` (the ground duplicated in place).
    scene : str
        Another registered scene instead of the base scene (a case that needs its own
        construction: the note says so).
    scene_params : dict
        Builder parameters of ``scene`` (default: its defaults), or, without ``scene``, on top
        of the base scene's.
    distance_factor : float
        An SDF scene's distance field multiplied by this (|∇d| = factor: sphere tracing takes
        1/factor times more steps); the surface, its mesh and the reference are unchanged.
    derived : dict
        Config knobs whose value is derived from the case's scene and moderate artifact when
        the case runs (:func:`prtbench.stability.run.derive_overrides`): ``"signals"`` (the
        scene's vertex count) or ``"dimension"`` (the stored transfer's values per vertex).
    timeout_factor : float
        The case may run this many times the profile's timeout (large scenes, not hangs).
    note, advice : str
        What the case probes; what to do instead when it is degraded.
    compare_image : bool
        The case renders the moderate case's picture (same light and pixels), so the image
        itself is compared with the moderate render too (``psnr_vs_moderate``).
    """

    name: str
    group: str
    overrides: Mapping[str, Any] = field(default_factory=dict)
    light: str = ""
    shininess: float | None = None
    scale: float = 1.0
    translate: float = 0.0
    geometry: str = ""
    scene: str = ""
    scene_params: Mapping[str, Any] = field(default_factory=dict)
    distance_factor: float = 1.0
    derived: Mapping[str, str] = field(default_factory=dict)
    timeout_factor: float = 1.0
    note: str = ""
    advice: str = ""
    compare_image: bool = False

    def to_json(self) -> dict[str, Any]:
        return {**dataclasses.asdict(self), "overrides": dict(self.overrides),
                "scene_params": dict(self.scene_params), "derived": dict(self.derived)}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> "Case":
        return cls(**dict(data))


#: Scenes built while planning, by (name, variant, params): a file is imported once.
_BUILT: dict[tuple, Any] = {}


def case_base_scene(name: str, variant: str, params: Mapping[str, Any]):
    """The built (registered or file) scene ``name``; cached for the planning process (a file
    by its path, size and modification time)."""

    key = (str(name), variant, tuple(sorted((k, str(v)) for k, v in params.items())))
    if Path(str(name)).is_file():
        stat = Path(str(name)).stat()
        key += (stat.st_size, stat.st_mtime_ns)
    if key not in _BUILT:
        _BUILT[key] = get_scene(name, variant=variant, **dict(params))
    return _BUILT[key]


def accepts(method_cls, scene: str, variant: str, scene_params: Mapping[str, Any],
             overrides: Mapping[str, Any] | None = None) -> bool:
    """Whether ``method_cls`` validates ``scene`` (smoke config plus ``overrides``)."""
    try:
        method_cls.validate(case_base_scene(scene, variant, scene_params),
                            method_cls.make_config(dict(overrides or {}), profile="smoke"))
    except PrtbenchError:
        return False
    return True
