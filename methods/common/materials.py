"""Material preconditions shared by the methods that shade constant diffuse albedo."""

from __future__ import annotations

from prtbench.api.errors import InvalidInputError
from prtbench.scene.model import Texture


def check_diffuse_constant_kd(method: str, scene, *, kd_only: bool = False,
                              renders: str = "renders diffuse materials only") -> None:
    """Refuse a glossy or textured object for a method that shades constant diffuse albedo.

    Parameters
    ----------
    method : str
        The method's registered name, for the message.
    scene : Scene
    kd_only : bool
        Only a kd texture counts as textured (the method handles the other maps itself).
    renders : str
        What the method renders, as the message says it.

    Raises
    ------
    InvalidInputError
        One line naming the object, and ``--variant diffuse`` for a glossy one.
    """
    for obj in scene.objects:
        material = obj.material
        if material.is_glossy:
            raise InvalidInputError(
                f"method '{method}' {renders}, but scene '{scene.name}' variant "
                f"'{scene.variant}' has glossy '{obj.name}'; use --variant diffuse")
        if isinstance(material.kd, Texture) if kd_only else material.is_textured:
            raise InvalidInputError(
                f"method '{method}' takes constant kd per object; '{obj.name}' in scene "
                f"'{scene.name}' is textured")


def validate_constant_materials(method: str, scene) -> None:
    """Refuse textured materials and normal maps: ``method`` shades per vertex with constant kd,
    ks and shininess per object."""
    for obj in scene.objects:
        material = obj.material
        if material.is_textured:
            raise InvalidInputError(
                f"method '{method}' takes constant kd, ks and shininess per object; '{obj.name}' "
                f"in scene '{scene.name}' is textured; use a transfer-texture method")
        if material.normal_map is not None:
            raise InvalidInputError(
                f"method '{method}' shades per vertex and cannot apply the normal map of "
                f"'{obj.name}' in scene '{scene.name}'; use a transfer-texture method or a scene "
                "without normal maps")
