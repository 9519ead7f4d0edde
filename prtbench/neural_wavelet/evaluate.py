"""Indirect-only evaluation of the neural wavelet transport (the paper's indirect columns).

The reference indirect image is ``full − direct`` of two cached Mitsuba renders with the same
seed (see :mod:`.data`), at :data:`EVAL_SEED` (neither the training seeds nor the runner's 0).
Metrics are those of DESIGN.md §7 on display images (the scene's exposure), masked to the
pixels whose centre ray hits geometry.
"""

from __future__ import annotations

import numpy as np

from prtbench.errors import InvalidInputError

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
    from prtbench.reference import render_reference

    full = render_reference(scene, light, view, width=width, height=height, spp=spp,
                            bounces=bounces, seed=EVAL_SEED)
    direct = render_reference(scene, light, view, width=width, height=height, spp=spp,
                              bounces=0, seed=EVAL_SEED)
    return (full.image - direct.image).astype(np.float32), float(full.noise_rmse_display)


def indirect_metrics(renderer, scene, light, views, *, width: int, height: int, spp: int,
                     bounces: int = 1) -> list[dict[str, float]]:
    """Metrics of ``renderer.indirect`` against :func:`indirect_reference`, one dict per view
    (plus ``noise_display``: the full render's display-noise estimate)."""
    from prtbench import imageio, metrics
    from prtbench.runner import geometry_mask

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
