"""The prtbench BRDF as a Mitsuba 3 plug-in (``prtphong``) and Material -> Mitsuba conversion.

DESIGN.md §4 fixes one BRDF for every method and for the reference:

    f(ωi, ωo) = kd/π + ks·(s+1)/(2π)·max(ωi·r, 0)^s,   r = reflect(ωo, n)

Mitsuba names the directions the other way round: ``si.wi`` points to the viewer (our ωo) and
the ``wo`` argument / sampled direction points to the light (our ωi), both in the local shading
frame (n = +Z), and :meth:`eval` returns f·cos θ of the light direction. The lobe is symmetric,
so max(ωi·r, 0) = max(wo·reflect(si.wi), 0) either way.

The surface is one-sided like Mitsuba's own BSDFs: zero whenever the viewer or the light is on
or below the shading horizon. Importance sampling is a one-sample mixture of a cosine-weighted
hemisphere (probability ∝ mean(kd)) and the exact Phong lobe around r (probability ∝ mean(ks),
pdf (s+1)/(2π)·cos^s α); the returned pdf is the mixture pdf, so MIS in the path tracer sees one
consistent density. Lobe samples below the horizon get weight 0 (their mass is the part of the
lobe that leaves the hemisphere, which the pdf keeps: it is a density over the whole sphere).

Mitsuba classes depend on the active variant, so the plug-in class is built per variant by
:func:`ensure_registered`; importing this module does not import mitsuba.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from prtbench.api.errors import InvalidInputError
from prtbench.scene.model import Material, Texture
from prtbench.transport.sh import phong_lobe

#: Name of the registered plug-in (``{"type": PLUGIN_NAME, ...}`` in ``mi.load_dict``).
PLUGIN_NAME = "prtphong"

_REGISTERED: dict[str, type] = {}


def ensure_registered() -> type:
    """Register ``prtphong`` for the active Mitsuba variant (idempotent); return its class."""
    import mitsuba as mi

    variant = mi.variant()
    if variant is None:
        raise InvalidInputError("no Mitsuba variant is set; call mi.set_variant(...) first")
    if variant not in _REGISTERED:
        cls = _make_class()
        mi.register_bsdf(PLUGIN_NAME, lambda props: cls(props))
        _REGISTERED[variant] = cls
    return _REGISTERED[variant]


def _make_class() -> type:
    import drjit as dr
    import mitsuba as mi

    inv_pi = 1.0 / math.pi
    inv_two_pi = 0.5 / math.pi

    class PrtPhongBSDF(mi.BSDF):
        """f = kd/π + ks·(s+1)/(2π)·max(wo·reflect(wi), 0)^s, front side only."""

        def __init__(self, props: Any) -> None:
            mi.BSDF.__init__(self, props)
            self.kd = props.get_texture("kd") if "kd" in props else _uniform(0.5)
            self.ks = props.get_texture("ks") if "ks" in props else _uniform(0.0)
            self.shininess = (props.get_unbounded_texture("shininess")
                              if "shininess" in props else _uniform(1.0))
            varying = any(t.is_spatially_varying() for t in (self.kd, self.ks, self.shininess))
            extra = mi.BSDFFlags.FrontSide | (mi.BSDFFlags.SpatiallyVarying if varying
                                              else mi.BSDFFlags.Empty)
            diffuse = mi.BSDFFlags.DiffuseReflection | extra
            glossy = mi.BSDFFlags.GlossyReflection | extra
            self.m_components = [diffuse, glossy]
            self.m_flags = diffuse | glossy

        # -- pieces shared by eval / pdf / sample ---------------------------------------------
        def _params(self, ctx, si, active):
            """kd, ks, s, diffuse-selection probability, enabled components."""
            has_d = ctx.is_enabled(mi.BSDFFlags.DiffuseReflection, 0)
            has_g = ctx.is_enabled(mi.BSDFFlags.GlossyReflection, 1)
            kd = self.kd.eval(si, active)
            ks = self.ks.eval(si, active)
            s = self.shininess.eval_1(si, active)
            mean_d = (kd[0] + kd[1] + kd[2]) * (1.0 / 3.0)
            mean_s = (ks[0] + ks[1] + ks[2]) * (1.0 / 3.0)
            if has_d and has_g:
                total = mean_d + mean_s
                prob_d = dr.select(total > 0, mean_d / dr.maximum(total, 1e-30), 1.0)
            else:
                prob_d = mi.Float(1.0 if has_d else 0.0)
            return kd, ks, s, prob_d, has_d, has_g

        @staticmethod
        def _lobe(si, wo, s):
            """Normalised Phong lobe (s+1)/(2π)·max(cos α, 0)^s about reflect(si.wi)."""
            cos_alpha = dr.dot(wo, mi.reflect(si.wi))
            positive = cos_alpha > 0
            power = dr.power(dr.select(positive, cos_alpha, 1.0), s)
            return dr.select(positive, (s + 1.0) * inv_two_pi * power, 0.0)

        def _eval_pdf(self, ctx, si, wo, active):
            kd, ks, s, prob_d, has_d, has_g = self._params(ctx, si, active)
            cos_view = mi.Frame3f.cos_theta(si.wi)
            cos_light = mi.Frame3f.cos_theta(wo)
            valid = active & (cos_view > 0) & (cos_light > 0)
            lobe = self._lobe(si, wo, s)
            f = mi.Color3f(0.0)
            if has_d:
                f += kd * inv_pi
            if has_g:
                f += ks * lobe
            pdf = prob_d * cos_light * inv_pi + (1.0 - prob_d) * lobe
            value = dr.select(valid, f * cos_light, 0.0)
            return value, dr.select(valid, pdf, 0.0)

        # -- the mi.BSDF interface ------------------------------------------------------------
        def eval(self, ctx, si, wo, active=True):
            return self._eval_pdf(ctx, si, wo, active)[0]

        def pdf(self, ctx, si, wo, active=True):
            return self._eval_pdf(ctx, si, wo, active)[1]

        def eval_pdf(self, ctx, si, wo, active=True):
            return self._eval_pdf(ctx, si, wo, active)

        def sample(self, ctx, si, sample1, sample2, active=True):
            _, _, s, prob_d, _, _ = self._params(ctx, si, active)
            choose_d = sample1 < prob_d
            wo_diffuse = mi.warp.square_to_cosine_hemisphere(sample2)
            # Exact Phong-lobe sample: cos α = u^(1/(s+1)), φ = 2πv, about r.
            cos_a = dr.power(sample2.x, 1.0 / (s + 1.0))
            sin_a = dr.safe_sqrt(1.0 - cos_a * cos_a)
            sin_phi, cos_phi = dr.sincos(2.0 * math.pi * sample2.y)
            local = mi.Vector3f(sin_a * cos_phi, sin_a * sin_phi, cos_a)
            wo_glossy = mi.Frame3f(mi.reflect(si.wi)).to_world(local)
            wo = dr.select(choose_d, wo_diffuse, wo_glossy)

            value, pdf = self._eval_pdf(ctx, si, wo, active)
            ok = active & (pdf > 0)
            bs = dr.zeros(mi.BSDFSample3f)
            bs.wo = wo
            bs.pdf = dr.select(ok, pdf, 0.0)
            bs.eta = 1.0
            bs.sampled_component = dr.select(choose_d, mi.UInt32(0), mi.UInt32(1))
            bs.sampled_type = dr.select(choose_d, mi.UInt32(+mi.BSDFFlags.DiffuseReflection),
                                        mi.UInt32(+mi.BSDFFlags.GlossyReflection))
            weight = dr.select(ok, value / dr.select(ok, pdf, 1.0), 0.0)
            return bs, weight

        def eval_diffuse_reflectance(self, si, active=True):
            return self.kd.eval(si, active)

        def traverse(self, callback):
            callback.put("kd", self.kd, mi.ParamFlags.Differentiable)
            callback.put("ks", self.ks, mi.ParamFlags.Differentiable)
            callback.put("shininess", self.shininess, mi.ParamFlags.Differentiable)

        def parameters_changed(self, keys=None):
            pass

        def to_string(self):
            return f"PrtPhongBSDF[kd={self.kd}, ks={self.ks}, shininess={self.shininess}]"

    def _uniform(value: float):
        return mi.load_dict({"type": "uniform", "value": float(value)})

    return PrtPhongBSDF


# --------------------------------------------------------------------------------------------
# Material -> load_dict description
# --------------------------------------------------------------------------------------------

def _texture_dict(texture: Texture, *, channels: int) -> dict[str, Any]:
    """A ``bitmap`` texture on our image: row 0 is v = 0 in both conventions, linear, repeat."""
    import mitsuba as mi

    img = texture.image
    if channels == 3:
        if img.shape[2] == 1:
            img = np.repeat(img, 3, axis=2)
        img = img[..., :3]
    else:
        img = img[..., :1]
    bitmap = mi.Bitmap(np.ascontiguousarray(img, dtype=np.float32))
    # raw: the values are linear data, not sRGB-encoded colours.
    return {"type": "bitmap", "bitmap": bitmap, "raw": True, "filter_type": "bilinear",
            "wrap_mode": "repeat"}


def _color(value: Any) -> Any:
    if isinstance(value, Texture):
        return _texture_dict(value, channels=3)
    return {"type": "rgb", "value": [float(c) for c in value]}


def material_bsdf(material: Material, *, has_uvs: bool, use_builtin_diffuse: bool = True,
                  ) -> dict[str, Any]:
    """``mi.load_dict`` description of ``material``'s BRDF (DESIGN.md §4).

    Parameters
    ----------
    material : Material
    has_uvs : bool
        Whether the mesh carries texture coordinates (textured parameters need them).
    use_builtin_diffuse : bool
        With ks = 0 the BRDF is Lambertian and Mitsuba's ``diffuse`` is exactly equal (and
        faster: no Python calls); ``False`` forces ``prtphong`` (used to test they agree).

    Raises
    ------
    InvalidInputError
        For a normal map (not rendered by the reference) or a textured parameter on a mesh
        without UVs.
    """
    if material.normal_map is not None:
        raise InvalidInputError(
            f"material '{material.name}': normal maps are not supported by the Mitsuba "
            "reference; accepted: materials without normal_map")
    if material.is_textured and not has_uvs:
        raise InvalidInputError(
            f"material '{material.name}' is textured but its mesh has no uvs; accepted: "
            "textured materials on meshes with uvs")
    if use_builtin_diffuse and not material.is_glossy:
        return {"type": "diffuse", "reflectance": _color(material.kd)}
    ensure_registered()
    shininess = (_texture_dict(material.shininess, channels=1)
                 if isinstance(material.shininess, Texture)
                 else {"type": "uniform", "value": float(material.shininess)})
    return {"type": PLUGIN_NAME, "kd": _color(material.kd), "ks": _color(material.ks),
            "shininess": shininess}


def brdf(kd: np.ndarray, ks: np.ndarray, s: np.ndarray | float, normal: np.ndarray,
         light_dir: np.ndarray, view_dir: np.ndarray) -> np.ndarray:
    """NumPy f(ωi, ωo) of DESIGN.md §4 (no horizon test), for checking the plug-in.

    Parameters
    ----------
    kd, ks : ndarray, shape (..., 3)
    s : float or ndarray, shape (...)
    normal, light_dir, view_dir : ndarray, shape (..., 3)
        Unit vectors; ``light_dir`` is ωi, ``view_dir`` is ωo.

    Returns
    -------
    ndarray, shape (..., 3), float64
    """
    n = np.asarray(normal, np.float64)
    wo = np.asarray(view_dir, np.float64)
    wi = np.asarray(light_dir, np.float64)
    r = 2.0 * np.sum(wo * n, axis=-1, keepdims=True) * n - wo
    lobe = phong_lobe(np.sum(wi * r, axis=-1), s)
    return np.asarray(kd, np.float64) / np.pi + np.asarray(ks, np.float64) * lobe[..., None]
