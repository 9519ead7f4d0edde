"""Indirect-only evaluation of the neural wavelet transport (the paper's indirect columns).

The reference indirect image is ``full − direct`` of two cached Mitsuba renders with the same
seed (see :mod:`.data`), at :data:`EVAL_SEED` (neither the training seeds nor the runner's 0).
Metrics are those of DESIGN.md §7 on display images (the scene's exposure), masked to the
pixels whose centre ray hits geometry.
"""

from __future__ import annotations

import numpy as np

from prtbench.api.errors import InvalidInputError
from prtbench.api.method import METHODS, load_or_precompute
from prtbench.bench import metrics
from prtbench.io import imageio
from prtbench.render.reference import render_reference
from prtbench.transport.raytrace import geometry_mask

#: Seed of the reference renders the indirect-only metrics compare against.
EVAL_SEED = 7_777_777


def require_glossy(scene, *, what: str = "the glossy comparison") -> None:
    """One-line error when no object of ``scene`` has a specular lobe (ks > 0)."""
    if not any(obj.material.is_glossy for obj in scene.objects):
        raise InvalidInputError(f"scene '{scene.name}' (variant '{scene.variant}') has no glossy "
                                f"material; {what} needs one: accepted: a glossy variant "
                                "(--variant glossy) or a scene with ks > 0")


def indirect_reference(scene, light, view, *, width: int, height: int, spp: int,
                       bounces: int = 1) -> tuple[np.ndarray, float]:
    """(indirect (H, W, 3) float32, noise_rmse of the full render) at :data:`EVAL_SEED`."""

    full = render_reference(scene, light, view, width=width, height=height, spp=spp,
                            bounces=bounces, seed=EVAL_SEED)
    direct = render_reference(scene, light, view, width=width, height=height, spp=spp,
                              bounces=0, seed=EVAL_SEED)
    return (full.image - direct.image).astype(np.float32), float(full.noise_rmse_display)


def indirect_metrics(renderer, scene, light, views, *, width: int, height: int, spp: int,
                     bounces: int = 1) -> list[dict[str, float]]:
    """Metrics of ``renderer.indirect`` against :func:`indirect_reference`, one dict per view
    (plus ``noise_display``: the full render's display-noise estimate)."""

    out = []
    for view in views:
        ref, noise = indirect_reference(scene, light, view, width=width, height=height, spp=spp,
                                        bounces=bounces)
        got = renderer.indirect(view, light)
        mask = geometry_mask(scene, view, width, height)
        values = metrics.compute_metrics(imageio.display(got, exposure=scene.exposure),
                                         imageio.display(ref, exposure=scene.exposure),
                                         mask=mask)
        out.append({**values, "noise_display": noise})
    return out


class DifferenceIndirect:
    """The indirect part of a method that renders full and direct light separately.

    ``indirect(view, light)`` = ``full.render(view, light) − direct.render(view, light)``: for
    ``sloan-matrix`` with ``bounces=N`` and the same matrices with ``bounces=0`` it is the
    interreflected light the SH transfer adds, measured exactly as the neural indirect is
    (:func:`indirect_metrics` against the same ``full − direct`` reference).

    Parameters
    ----------
    full, direct : prtbench.api.method.Renderer
        Renderers of the same size; each ``render`` returns (H, W, 3) linear radiance.
    """

    def __init__(self, full, direct):
        self.full, self.direct = full, direct

    def indirect(self, view, light) -> np.ndarray:
        """(H, W, 3) float32: full − direct."""
        return (self.full.render(view, light) - self.direct.render(view, light)).astype(
            np.float32)

    def release(self) -> None:
        self.full.release()
        self.direct.release()


def sh_baseline(scene, *, width: int, height: int, bounces: int = 1, sh_bands: int = 5,
                rays_per_point: int = 256, progress: bool = False) -> DifferenceIndirect:
    """The SH transport-matrix baseline of the paper's comparisons: ``sloan-matrix`` with
    ``bounces`` (Sloan 2002 §6, glossy at the bounce) minus the same matrices without
    (:class:`DifferenceIndirect`); precomputed (and cached) on ``scene``."""

    cls = METHODS.get("sloan-matrix")
    renderers = []
    try:
        for b in (int(bounces), 0):
            config = cls.make_config({"sh_bands": int(sh_bands), "bounces": b,
                                      "rays_per_point": int(rays_per_point)})
            artifact = load_or_precompute(cls, scene, config, progress=progress)
            renderers.append(cls.renderer(scene, artifact, config, width=width, height=height))
    except BaseException:
        for r in renderers:
            r.release()
        raise
    return DifferenceIndirect(*renderers)
