"""Material mapping of asset files onto the one BRDF of DESIGN.md §4 (table in the package doc)."""

from __future__ import annotations

from typing import Any

import numpy as np

from prtbench.api.errors import InvalidInputError
from prtbench.scene.files.report import ImportReport
from prtbench.scene.model import Material, Texture

#: Materials of files without any (DESIGN §4 values).
DEFAULT_KD = 0.7
GLOSSY_DEFAULT = {"kd": 0.7, "ks": 0.3, "shininess": 64.0}


def _srgb_to_linear(c: np.ndarray) -> np.ndarray:
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def _image(img, name: str, *, srgb: bool, factor=None):
    """A :class:`Texture` from a PIL image (flipped so row 0 is v = 0), or None."""

    if img is None:
        return None
    try:
        rgb = np.asarray(img.convert("RGB"), dtype=np.float32) / 255.0
    except Exception as exc:  # PIL raises on truncated or undecodable data
        raise InvalidInputError(f"texture '{name}' cannot be decoded ({exc})") from None
    rgb = _srgb_to_linear(rgb) if srgb else rgb
    if factor is not None:
        rgb = rgb * np.asarray(factor, dtype=np.float32)[:3]
    return Texture(np.ascontiguousarray(np.clip(rgb[::-1], 0.0, 1.0)), name=name)


def _rgb(value, default: float) -> tuple[float, float, float]:
    if value is None:
        return (default,) * 3
    v = np.asarray(value, dtype=np.float64).ravel()[:3]
    if np.asarray(value).dtype == np.uint8 or v.max() > 1.0:
        v = v / 255.0
    return tuple(float(c) for c in np.clip(v, 0.0, 1.0))


def material_of(geom, variant: str, has_uv: bool, report: ImportReport, node: str):
    from trimesh.visual.material import PBRMaterial, SimpleMaterial

    visual = geom.visual
    mat = getattr(visual, "material", None)
    glossy = variant == "glossy"
    if isinstance(mat, PBRMaterial):
        return _pbr(mat, glossy, has_uv, report, node)
    if isinstance(mat, SimpleMaterial):
        return _mtl(mat, glossy, has_uv, report, node)
    if getattr(visual, "kind", None) not in (None, "texture"):  # per-vertex or per-face colours
        report.warnings.append(f"{node}: vertex/face colours ignored (default material)")
    if glossy:
        g = GLOSSY_DEFAULT
        return Material(kd=(g["kd"],) * 3, ks=(g["ks"],) * 3, shininess=g["shininess"],
                        name="default-glossy")
    return Material(kd=(DEFAULT_KD,) * 3, name="default")


def _mtl(mat, glossy: bool, has_uv: bool, report: ImportReport, node: str):
    extra = getattr(mat, "kwargs", {}) or {}
    kd = _rgb(extra["kd"], 1.0) if "kd" in extra else _rgb(mat.diffuse, 1.0)
    ks = _rgb(extra["ks"], 0.0) if "ks" in extra else (0.0, 0.0, 0.0)
    ns = float(extra.get("ns", mat.glossiness if mat.glossiness is not None else 1.0))
    name = str(mat.name or node)
    kd_value: Any = kd
    if mat.image is not None:
        if has_uv:
            kd_value = _image(mat.image, f"{name}:map_Kd", srgb=True,
                              factor=kd if "kd" in extra else None)
        else:
            report.warnings.append(f"{node}: map_Kd ignored (no texture coordinates)")
    if not glossy:
        return Material(kd=kd_value, name=name)
    return Material(kd=kd_value, ks=ks, shininess=float(np.clip(ns, 0.0, 1e4)), name=name)


def phong_exponent(roughness: float) -> float:
    """Phong exponent of a glTF roughness: α = r², s = 2/α² − 2, clamped to [1, 10⁴]."""
    alpha = max(float(roughness), 0.0) ** 2
    if alpha <= 0.0:
        return 1e4
    return float(np.clip(2.0 / alpha ** 2 - 2.0, 1.0, 1e4))


def _pbr(mat, glossy: bool, has_uv: bool, report: ImportReport, node: str):
    name = str(mat.name or node)
    base = np.asarray(_rgb(mat.baseColorFactor, 1.0))
    metallic = 1.0 if mat.metallicFactor is None else float(np.clip(mat.metallicFactor, 0, 1))
    if mat.metallicFactor is None:
        report.warnings.append(f"{node}: no metallicFactor, glTF's default 1 (metal) gives kd 0")
    roughness = 1.0 if mat.roughnessFactor is None else float(np.clip(mat.roughnessFactor, 0, 1))
    kd = tuple(float(c) for c in base * (1.0 - metallic))
    ks = tuple(float(c) for c in 0.04 * (1.0 - metallic) + base * metallic)
    kd_value: Any = kd
    normal_map = None
    if getattr(mat, "baseColorTexture", None) is not None:
        if has_uv:
            kd_value = _image(mat.baseColorTexture, f"{name}:baseColor", srgb=True, factor=kd)
        else:
            report.warnings.append(f"{node}: baseColorTexture ignored (no texture coordinates)")
    if getattr(mat, "normalTexture", None) is not None and has_uv:
        normal_map = _image(mat.normalTexture, f"{name}:normal", srgb=False)
    if getattr(mat, "metallicRoughnessTexture", None) is not None:
        report.warnings.append(f"{node}: metallicRoughnessTexture ignored (factors used)")
    emissive = getattr(mat, "emissiveFactor", None)
    if getattr(mat, "emissiveTexture", None) is not None or (
            emissive is not None and np.any(np.asarray(emissive) > 0)):
        report.warnings.append(f"{node}: emission ignored (no emitters in the radiance model)")
    if not glossy:
        return Material(kd=kd_value, normal_map=normal_map, name=name)
    return Material(kd=kd_value, ks=ks, shininess=phong_exponent(roughness),
                    normal_map=normal_map, name=name)
