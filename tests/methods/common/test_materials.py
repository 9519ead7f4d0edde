"""The constant-diffuse-albedo precondition shared by vertex, irradiance-volume, data-driven and
the wavelet methods: glossy and textured objects are refused in one line, before any work."""

from __future__ import annotations

import copy
import dataclasses

import numpy as np
import pytest

from prtbench.api.errors import InvalidInputError
from prtbench.api.method import METHODS
from prtbench.scene.model import Texture
from prtbench.scene.registry import get_scene

DIFFUSE_ONLY = ["vertex", "irradiance-volume", "data-driven", "wavelet-vertex", "wavelet-texture"]


def _with_material(scene, **changes):
    """``scene`` with its first object's material changed (a shallow copy: nothing shared)."""
    out = copy.copy(scene)
    first = scene.objects[0]
    out.objects = [dataclasses.replace(first, material=dataclasses.replace(first.material,
                                                                           **changes)),
                   *scene.objects[1:]]
    return out


@pytest.mark.parametrize("name", DIFFUSE_ONLY)
def test_diffuse_only_methods_refuse_glossy_and_textured_kd_naming_the_object(name):
    method = METHODS.get(name)
    config = method.make_config(profile="smoke")
    scene = get_scene("sphere-over-plane")
    obj = scene.objects[0].name
    glossy = _with_material(scene, ks=(0.3, 0.3, 0.3), shininess=20.0)
    with pytest.raises(InvalidInputError) as err:
        method.validate(glossy, config)
    message = str(err.value)
    assert message.startswith(f"method '{name}' ") and f"has glossy '{obj}'" in message
    assert message.endswith("use --variant diffuse") and "\n" not in message
    textured = _with_material(scene, kd=Texture(np.full((4, 4, 3), 0.5, np.float32)))
    with pytest.raises(InvalidInputError, match=rf"^method '{name}' takes constant kd per "
                                                rf"object; '{obj}' in scene '.*' is textured$"):
        method.validate(textured, config)


def test_irradiance_volume_says_it_stores_irradiance():
    method = METHODS.get("irradiance-volume")
    glossy = _with_material(get_scene("sphere-over-plane"), ks=(0.3,) * 3, shininess=20.0)
    with pytest.raises(InvalidInputError, match="stores irradiance and renders diffuse "
                                                "materials only, but scene"):
        method.validate(glossy, method.make_config(profile="smoke"))


def test_only_wavelet_texture_accepts_a_textured_shininess_on_a_diffuse_object():
    # ks = 0 makes the shininess irrelevant; wavelet-texture checks only kd's texture.
    scene = _with_material(get_scene("sphere-over-plane"),
                           shininess=Texture(np.full((4, 4, 1), 8.0, np.float32)))
    METHODS.get("wavelet-texture").validate(
        scene, METHODS.get("wavelet-texture").make_config(profile="smoke"))
    with pytest.raises(InvalidInputError, match="is textured"):
        METHODS.get("vertex").validate(scene, METHODS.get("vertex").make_config(profile="smoke"))
