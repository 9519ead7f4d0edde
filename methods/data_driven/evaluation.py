"""Experiments shared by the data-driven reproductions (figures 8, 12, 14 and table 1).

* :func:`lightmap_study`: held-out lights of a family; per basis count, the RMSE over lightmap
  texels of the method's prediction and of the projection of the path-traced lightmap onto the
  basis (the paper's Fig. 14 "projecting the reference in the basis"). The held-out lightmaps
  are baked with ``reference_factor`` × more paths than the training data.
* :func:`image_study`: the same in image space, against Mitsuba's *indirect-only* reference
  (``max_depth = bounces + 2`` minus ``max_depth = 2`` with shared seeds): the method's GL
  render, and the GL render of the projected coefficients (the same shading path).

RMSE is on linear radiance (indirect light only), over covered texels or geometry pixels.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from methods.data_driven.basis import decode, encode, predict, project, projected, to_examples
from methods.data_driven.dataset import bake_lightmaps, build_dataset, family_lights, measure_direct
from methods.data_driven.lights import light_spec
from methods.data_driven.method import DataDrivenPRT, fit_basis
from methods.data_driven.reference import render_light_reference
from prtbench.api.cache import cached_arrays, content_key
from prtbench.api.method import load_or_precompute
from prtbench.transport.raytrace import geometry_mask


def with_knobs(config: Any, **changes: Any) -> Any:
    """A copy of a (frozen) config with some knobs changed."""
    return dataclasses.replace(config, **changes)


def rmse(a: np.ndarray, b: np.ndarray, mask: np.ndarray | None = None) -> float:
    d = np.asarray(a, np.float64) - np.asarray(b, np.float64)
    if mask is not None:
        d = d[mask]
    return float(np.sqrt(np.mean(d * d))) if d.size else float("nan")


@dataclass
class LightmapStudy:
    """Per basis count: RMSE of prediction and projection over held-out lightmaps."""

    counts: list[int]
    prediction_rmse: list[float]
    projection_rmse: list[float]
    reference_rms: float
    reference_noise_rmse: float
    lights: list
    eigenvalues: np.ndarray


def held_out(scene: Any, config: Any, count: int) -> list:
    """``count`` lights of the config's family not in its dataset (another seed stream)."""
    return list(family_lights(scene, config, count, seed_offset=7919))


def reference_lightmaps(scene: Any, config: Any, dataset: Any, lights: Sequence, *,
                        factor: int = 4, seed: int = 99) -> tuple[np.ndarray, np.ndarray]:
    """Two independent path-traced lightmap sets (N, T, 3) of ``lights`` at ``factor``× paths.

    Their mean is the reference; half their difference estimates its noise.
    """

    paths = config.paths_per_texel * factor
    key = content_key("ddprt-reflightmaps", scene.content_hash(), config.lightmap_resolution,
                      config.lightmap_padding, config.bounces, paths, config.env_samples, seed,
                      [light_spec(light) for light in lights])

    def compute() -> dict[str, np.ndarray]:
        a = bake_lightmaps(scene, dataset.lightmap, lights, bounces=config.bounces,
                           paths=paths // 2, env_samples=config.env_samples, seed=seed)
        b = bake_lightmaps(scene, dataset.lightmap, lights, bounces=config.bounces,
                           paths=paths - paths // 2, env_samples=config.env_samples,
                           seed=seed + 1)
        return {"a": a, "b": b}

    arrays = cached_arrays("ddprt-reflightmaps", key, compute)
    return arrays["a"], arrays["b"]


def lightmap_study(scene: Any, config: Any, counts: Sequence[int], *, test_lights: int = 8,
                   reference_factor: int = 4, progress: bool = False) -> LightmapStudy:
    """Prediction and projection RMSE over held-out lightmaps, per basis count."""
    dataset = build_dataset(scene, config, progress=progress)
    lights = held_out(scene, config, test_lights)
    x = measure_direct(scene, dataset.points, config, lights)
    a, b = reference_lightmaps(scene, config, dataset, lights, factor=reference_factor)
    y = 0.5 * (a + b)
    noise = 0.5 * rmse(a, b)
    pred, proj = [], []
    basis = None
    for n in counts:
        basis = fit_basis(dataset, with_knobs(config, basis=int(n)))
        pred.append(rmse(predict(basis, x), y))
        proj.append(rmse(projected(basis, y), y))
    return LightmapStudy(list(counts), pred, proj, rmse(y, 0 * y), noise, lights,
                         basis.eigenvalues if basis is not None else np.zeros(0))


def projected_weights(basis: Any, lightmap: np.ndarray) -> np.ndarray:
    """Element weights of the least-squares projection of one lightmap (T, 3).

    Returns (n, 3) for the mono layout (one column per channel) or (n, 1) interleaved, in the
    layout the GL coefficient texture takes.
    """
    y = np.asarray(lightmap, np.float64)[None]
    _, enc = to_examples(np.zeros((1, 1, 3)), y, layout=basis.layout)
    enc = encode(enc, basis.gamma)
    elements = basis.elements()
    keep = np.linalg.norm(elements, axis=0) > 0
    weights = np.zeros((elements.shape[1], enc.shape[1]))
    if keep.any():
        w, *_ = np.linalg.lstsq(elements[:, keep], enc, rcond=None)
        weights[keep] = w
    return weights


def write_coefficients(renderer: Any, weights: np.ndarray) -> None:
    """Load element weights (n, 3) or (n, 1) into the renderer's coefficient texture."""
    t = renderer.transfer
    n = weights.shape[0]
    padded = np.zeros((t.groups * 4, weights.shape[1]), np.float32)
    padded[:n] = weights
    data = padded.T.reshape(t.rows, t.groups, 4) if not t.multi else \
        padded[:, 0].reshape(1, t.groups, 4)
    t.output.write(np.ascontiguousarray(data, np.float32).tobytes())
    renderer.coefficient_scale = 1.0  # these weights are of the light itself, not rescaled


@dataclass
class ImageStudy:
    """Indirect-only images of one light from one view (linear, (H, W, 3))."""

    ours: np.ndarray
    projection: np.ndarray
    reference: np.ndarray
    reference_noise_rmse: float
    mask: np.ndarray
    ours_rmse: float
    projection_rmse: float
    direct_ours: np.ndarray | None = None
    direct_reference: np.ndarray | None = None


def image_study(scene: Any, config: Any, light: Any, *, view: Any, width: int, height: int,
                spp: int, reference_lightmap: np.ndarray | None = None,
                with_direct: bool = False, progress: bool = False) -> ImageStudy:
    """Indirect images of ``light``: ours (GL), the projection (GL) and Mitsuba's.

    Parameters
    ----------
    reference_lightmap : ndarray, shape (T, 3), optional
        The path-traced lightmap to project; baked here (4× the training paths) if None.
    with_direct : bool
        Also render direct light (ours and Mitsuba's ``max_depth = 2``).
    """

    artifact = load_or_precompute(DataDrivenPRT, scene, config, progress=progress)
    dataset = build_dataset(scene, config, progress=progress)
    basis = fit_basis(dataset, config)
    if reference_lightmap is None:
        a, b = reference_lightmaps(scene, config, dataset, [light])
        reference_lightmap = 0.5 * (a[0] + b[0])
    renderer = DataDrivenPRT.renderer(scene, artifact, config, width=width, height=height)
    try:
        ours = renderer.render(view, light, direct=False)
        direct = renderer.render(view, light, indirect=False) if with_direct else None
        renderer.prepare_light(light)
        write_coefficients(renderer, projected_weights(basis, reference_lightmap))
        renderer.pass_shading(view, direct=False)
        proj = np.ascontiguousarray(renderer.target.read()[..., :3])
    finally:
        renderer.release()
    ref = render_light_reference(scene, light, view, width=width, height=height, spp=spp,
                                 bounces=config.bounces, component="indirect")
    direct_ref = render_light_reference(scene, light, view, width=width, height=height, spp=spp,
                                        bounces=config.bounces, component="direct") \
        if with_direct else None
    mask = geometry_mask(scene, view, width, height)
    return ImageStudy(ours, proj, ref.image, ref.noise_rmse, mask, rmse(ours, ref.image, mask),
                      rmse(proj, ref.image, mask), direct,
                      direct_ref.image if direct_ref is not None else None)


__all__ = ["LightmapStudy", "ImageStudy", "lightmap_study", "image_study", "held_out",
           "reference_lightmaps", "projected_weights", "write_coefficients", "rmse",
           "with_knobs", "decode", "project"]
