"""Mitsuba 3 path-traced reference renders, cached as EXRs (DESIGN.md §6).

The reference is rendered from the same :class:`~prtbench.scene.model.Scene` every method uses:

* meshes from our arrays (positions, CCW faces, *our* vertex normals as Mitsuba's shading
  normals, ``face_normals`` off, UVs where present), one-sided materials (DESIGN.md §4 BRDF:
  Mitsuba's ``diffuse`` where ks = 0, which is exactly kd/π, else the ``prtphong`` plug-in of
  :mod:`prtbench.render.mitsuba_bsdf`);
* the camera: ``perspective`` with ``fov_axis='y'`` and ``to_world = look_at(eye, target, up)``;
* the light: an ``envmap`` emitter on the light's lat-long image (same mapping, DESIGN.md §3),
  ``hide_emitters`` so the background is 0 like in every method;
* ``hdrfilm`` with a one-pixel ``box`` reconstruction filter: each pixel is the plain average of
  the samples inside its footprint (what a supersampled rasteriser converges to; no sample
  leaks into neighbouring pixels), ``independent`` sampler;
* the ``path`` integrator with ``max_depth = bounces + 2`` (``bounces=0`` is direct lighting
  only) and ``rr_depth = max_depth + 1``: Russian roulette never starts, so it adds no noise.

Each reference is two independent half-spp renders A and B (different seeds). Their average is
the reference; RMS(A − B) over geometry pixels, scaled to the full spp, estimates the
reference's own per-pixel Monte-Carlo error (``noise_rmse`` on linear radiance,
``noise_rmse_display`` on display images), so metrics are never reported tighter than that.

Cached EXRs carry their metadata (spp, noise, variant, ...) in the header together with a
SHA-256 over the pixels and that metadata (:func:`reference_checksum`): an entry whose checksum
does not match is not usable, said once on stderr and rendered again, never trusted.

Variant: ``$PRTBENCH_MITSUBA_VARIANT`` if set, else the first of ``cuda_ad_rgb``,
``llvm_ad_rgb`` (with ``$DRJIT_LIBLLVM_PATH`` pointed at Debian's libLLVM-19 when unset),
``scalar_rgb`` that works; :func:`check_variant` validates it before any work.
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from prtbench.api.cache import cache_root, content_key, entry_lock, record_use
from prtbench.api.errors import InvalidInputError
from prtbench.io.imageio import display, read_exr, read_exr_metadata, write_exr
from prtbench.render.mitsuba_bsdf import material_bsdf
from prtbench.render.mitsuba_variant import one_line, select_variant
from prtbench.scene.model import Scene, View
from prtbench.transport.lights import get_light

log = logging.getLogger(__name__)

#: Bump when a change here changes reference pixels (invalidates cached references).
REFERENCE_VERSION = 1

#: Samples traced per ``mi.render`` call (pixels × spp): bounds JIT-variant memory.
LANES_PER_PASS = 1 << 21



@dataclass
class Reference:
    """A cached path-traced reference image.

    Attributes
    ----------
    image : ndarray, shape (H, W, 3), float32
        Linear radiance, row 0 at the top; background pixels are 0.
    spp : int
        Samples per pixel (both halves together).
    noise_rmse : float
        Estimated RMS Monte-Carlo error of ``image`` over geometry pixels (linear).
    noise_rmse_display : float
        The same on display images (scene exposure, sRGB, clip); PSNR ceiling is
        −20·log10(noise_rmse_display).
    variant : str
        Mitsuba variant that rendered it.
    path : Path
        The cached EXR.
    seconds : float
        Render wall time (the original render's, also for cache hits).
    cache_hit : bool
        Whether this call loaded the EXR instead of rendering.
    """

    image: np.ndarray
    spp: int
    noise_rmse: float
    noise_rmse_display: float
    variant: str
    path: Path
    seconds: float
    cache_hit: bool = False


def reference_kind() -> str:
    """The reference kind recorded with metrics computed against these images."""
    return "path"


# --------------------------------------------------------------------------------------------
# Scene conversion
# --------------------------------------------------------------------------------------------

def mitsuba_scene_dict(scene: Scene, light: Any, view: View, *, width: int, height: int,
                       bounces: int = 0, spp: int = 1, use_builtin_diffuse: bool = True,
                       ) -> dict[str, Any]:
    """The ``mi.load_dict`` description of ``scene`` seen from ``view`` under ``light``.

    Needs an active variant (:func:`select_variant`). ``spp`` is the sampler's per-pass count.
    """
    import mitsuba as mi

    diag = max(scene.diagonal(), 1e-6)
    lo, hi = scene.bounds()
    reach = float(np.linalg.norm(np.asarray(view.eye) - 0.5 * (lo + hi))) + diag
    out: dict[str, Any] = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": bounces + 2, "rr_depth": bounces + 3,
                       "hide_emitters": True},
        "sensor": {
            "type": "perspective",
            "fov": float(view.fov_y),
            "fov_axis": "y",
            "near_clip": 1e-4 * diag,
            "far_clip": 10.0 * reach,
            "to_world": mi.ScalarTransform4f().look_at(
                origin=[float(c) for c in view.eye], target=[float(c) for c in view.target],
                up=[float(c) for c in view.up]),
            "film": {"type": "hdrfilm", "width": int(width), "height": int(height),
                     "pixel_format": "rgba", "rfilter": {"type": "box"},
                     "sample_border": False},
            "sampler": {"type": "independent", "sample_count": int(spp)},
        },
        "light": {"type": "envmap", "bitmap": mi.Bitmap(_light_image(light))},
    }
    for index, obj in enumerate(scene.objects):
        if obj.mesh.n_triangles == 0:
            continue
        bsdf = material_bsdf(obj.material, has_uvs=obj.mesh.uvs is not None,
                             use_builtin_diffuse=use_builtin_diffuse)
        out[f"object_{index:04d}"] = _mesh(obj.name, obj.mesh, mi.load_dict(bsdf))
    return out


def _light_image(light: Any) -> np.ndarray:
    # A writable copy: mi.Bitmap wraps the buffer.
    image = np.array(getattr(light, "image"), dtype=np.float32, order="C", copy=True)
    if image.ndim != 3 or image.shape[2] != 3 or not np.all(np.isfinite(image)):
        raise InvalidInputError(
            f"light '{getattr(light, 'name', '?')}' image has shape {image.shape}; "
            "accepted: finite float (H, W, 3)")
    return image


def _mesh(name: str, mesh: Any, bsdf: Any) -> Any:
    """A Mitsuba mesh on our buffers; our vertex normals are its shading normals."""
    import mitsuba as mi

    props = mi.Properties("mesh")
    props["face_normals"] = False
    props["bsdf"] = bsdf
    has_uvs = mesh.uvs is not None
    m = mi.Mesh(name, mesh.n_vertices, mesh.n_triangles, props, has_vertex_normals=True,
                has_vertex_texcoords=has_uvs)
    params = mi.traverse(m)
    params["vertex_positions"] = np.ascontiguousarray(mesh.positions, np.float32).ravel()
    params["faces"] = np.ascontiguousarray(mesh.faces, np.uint32).ravel()
    # Setting the normals in the same update keeps Mitsuba from recomputing them.
    params["vertex_normals"] = np.ascontiguousarray(mesh.normals, np.float32).ravel()
    if has_uvs:
        params["vertex_texcoords"] = np.ascontiguousarray(mesh.uvs, np.float32).ravel()
    params.update()
    return m


# --------------------------------------------------------------------------------------------
# Rendering
# --------------------------------------------------------------------------------------------

def _pass_seed(seed: int, half: int, index: int) -> int:
    digest = hashlib.sha256(f"prtbench-reference:{seed}:{half}:{index}".encode()).digest()
    return int.from_bytes(digest[:4], "little")


def _render_half(mi_scene: Any, *, width: int, height: int, spp: int, seed: int, half: int,
                 bar: Any) -> np.ndarray:
    """Average of passes with ``spp`` samples per pixel in total; (H, W, 4) float64."""
    import mitsuba as mi

    per_pass = max(1, LANES_PER_PASS // (width * height))
    acc = np.zeros((height, width, 4), np.float64)
    done, index = 0, 0
    while done < spp:
        n = min(per_pass, spp - done)
        img = mi.render(mi_scene, spp=n, seed=_pass_seed(seed, half, index))
        acc += np.asarray(img, np.float64).reshape(height, width, 4) * n
        done += n
        index += 1
        if bar is not None:
            bar.update(n)
    return acc / spp


def _noise(a: np.ndarray, b: np.ndarray, mask: np.ndarray, scale: float) -> float:
    if not mask.any():
        return 0.0
    diff = (a - b)[mask]
    return float(np.sqrt(np.mean(diff * diff)) * scale)


def reference_key(scene: Scene, light: Any, view: View, *, width: int, height: int,
                  bounces: int, spp: int, seed: int) -> str:
    """Content key of a reference (scene, light, view, resolution, bounces, spp, seed, versions)."""
    import mitsuba as mi

    return content_key("reference", scene.content_hash(), light.content_hash(), view, width,
                       height, bounces, spp, seed, mi.__version__, REFERENCE_VERSION)


#: EXR header attribute holding :func:`reference_checksum` of the pixels and the metadata.
CHECKSUM_KEY = "prtbench_checksum"


def reference_checksum(image: np.ndarray, metadata: dict[str, str]) -> str:
    """SHA-256 over the float32 pixels (H, W, 3) and the canonical JSON of ``metadata``.

    Stored in the cached EXR's header, so an edited header (spp, noise, ...) or edited pixels
    make the entry corrupt instead of being trusted; the checksum key itself is excluded.
    """
    pixels = np.ascontiguousarray(image, dtype=np.float32)
    fields = {k: str(v) for k, v in metadata.items() if k != CHECKSUM_KEY}
    digest = hashlib.sha256(b"prtbench-reference-checksum-v1\0")
    digest.update(json.dumps(list(pixels.shape)).encode())
    digest.update(pixels.tobytes())
    digest.update(json.dumps(fields, sort_keys=True, separators=(",", ":")).encode())
    return digest.hexdigest()


def _load_cached(path: Path) -> Reference | None:
    if not path.is_file():
        return None
    try:
        meta = read_exr_metadata(path)
        image = read_exr(path)
        if meta.get("prtbench_reference") != str(REFERENCE_VERSION):
            raise ValueError("missing prtbench metadata")
        if meta.get(CHECKSUM_KEY) != reference_checksum(image, meta):
            raise ValueError("checksum of pixels and metadata does not match"
                             if CHECKSUM_KEY in meta else "no checksum: written by an older prtbench")
        ref = Reference(image=image, spp=int(meta["spp"]), noise_rmse=float(meta["noise_rmse"]),
                        noise_rmse_display=float(meta["noise_rmse_display"]),
                        variant=meta["variant"], path=path, seconds=float(meta["seconds"]),
                        cache_hit=True)
        if image.shape != (int(meta["height"]), int(meta["width"]), 3) \
                or not np.all(np.isfinite(image)):
            raise ValueError("image does not match its metadata")
    except Exception as exc:  # noqa: BLE001 - any failure means a corrupt or partial file
        # Said on stderr whatever the logging setup: the user sees why it renders again.
        # Said once on stderr whatever the logging setup (a log.warning as well printed the
        # same news twice under the CLI's stderr handler): the user sees why it renders again.
        print(f"[prtbench] cached reference {path.name} is not usable ({one_line(exc)}); "
              "rendering it again", file=sys.stderr, flush=True)
        log.debug("discarded cached reference %s (%s)", path, one_line(exc))
        path.unlink(missing_ok=True)
        return None
    record_use(path)  # a hit: last use for the cache's LRU eviction
    return ref


def render_reference(scene: Scene, light: Any, view: View, *, width: int, height: int,
                     spp: int, bounces: int = 0, seed: int = 0, use_cache: bool = True,
                     progress: bool = False) -> Reference:
    """Path-traced reference of ``scene`` under ``light`` from ``view`` (cached).

    Parameters
    ----------
    scene : Scene
    light : EnvironmentLight or str
        A light (``.name``, ``.image`` (H, W, 3) lat-long, ``.content_hash()``) or its name.
    view : View
    width, height : int
        Image size in pixels.
    spp : int
        Samples per pixel, at least 2 (split into two independent halves).
    bounces : int
        Interreflection bounces; 0 is direct lighting only (``max_depth = bounces + 2``).
    seed : int
        Base random seed.
    use_cache : bool
        Load / store ``cache_root()/references/<key>.exr``.
    progress : bool
        Show a progress bar over samples.

    Returns
    -------
    Reference
    """
    if isinstance(light, str):

        light = get_light(light)
    width, height, spp, bounces = int(width), int(height), int(spp), int(bounces)
    if width < 1 or height < 1:
        raise InvalidInputError(f"reference resolution {width}x{height}; accepted: positive")
    if spp < 2:
        raise InvalidInputError(f"reference spp={spp}; accepted: 2 or more (two halves "
                                "estimate the reference's own noise)")
    if bounces < 0:
        raise InvalidInputError(f"bounces={bounces}; accepted: 0 or more")
    variant = select_variant()

    path = cache_root() / "references" / (reference_key(
        scene, light, view, width=width, height=height, bounces=bounces, spp=spp,
        seed=seed) + ".exr")
    if not use_cache:
        return _render(scene, light, view, width=width, height=height, spp=spp,
                       bounces=bounces, seed=seed, path=path, variant=variant, store=False,
                       progress=progress)
    hit = _load_cached(path)
    if hit is not None:
        return hit
    with entry_lock(path):  # another process may be rendering it: wait, then look again
        hit = _load_cached(path)
        if hit is not None:
            return hit
        return _render(scene, light, view, width=width, height=height, spp=spp,
                       bounces=bounces, seed=seed, path=path, variant=variant, store=True,
                       progress=progress)


def _render(scene: Scene, light: Any, view: View, *, width: int, height: int, spp: int,
            bounces: int, seed: int, path: Path, variant: str, store: bool,
            progress: bool) -> Reference:
    import mitsuba as mi

    start = time.perf_counter()
    mi_scene = mi.load_dict(mitsuba_scene_dict(scene, light, view, width=width, height=height,
                                               bounces=bounces))
    spp_a = spp // 2
    spp_b = spp - spp_a
    bar = None
    if progress:

        bar = tqdm(total=spp, desc=f"reference {scene.name} {width}x{height}", unit="spp",
                   leave=False)
    try:
        half_a = _render_half(mi_scene, width=width, height=height, spp=spp_a, seed=seed,
                              half=0, bar=bar)
        half_b = _render_half(mi_scene, width=width, height=height, spp=spp_b, seed=seed,
                              half=1, bar=bar)
    finally:
        if bar is not None:
            bar.close()
    seconds = time.perf_counter() - start
    combined = (half_a * spp_a + half_b * spp_b) / spp
    image = combined[..., :3].astype(np.float32)
    if not np.all(np.isfinite(image)):
        # The lights layer bounds radiance (lights.MAX_RADIANCE); this guards what slips past
        # it, so a non-finite image never reaches the cache.
        raise InvalidInputError(
            f"light '{getattr(light, 'name', '?')}' makes the reference of scene '{scene.name}' "
            f"overflow float32 ({int((~np.isfinite(image)).any(axis=-1).sum())} pixels not "
            "finite); accepted: lights whose radiance fits float32 sums")
    # Alpha is the fraction of a pixel's samples that hit geometry (background is hidden).
    mask = combined[..., 3] > 0
    # Var(A − B) = σ²(1/n_a + 1/n_b) and Var(combined) = σ²/spp for per-sample variance σ².
    scale = math.sqrt(spp_a * spp_b) / spp
    noise = _noise(half_a[..., :3], half_b[..., :3], mask, scale)
    noise_display = _noise(display(half_a[..., :3], exposure=scene.exposure).astype(np.float64),
                           display(half_b[..., :3], exposure=scene.exposure).astype(np.float64),
                           mask, scale)
    ref = Reference(image=image, spp=spp, noise_rmse=noise, noise_rmse_display=noise_display,
                    variant=variant, path=path, seconds=seconds)
    if store:
        metadata = {
            "prtbench_reference": str(REFERENCE_VERSION), "kind": reference_kind(),
            "spp": str(spp), "variant": variant, "mitsuba_version": mi.__version__,
            "noise_rmse": repr(noise), "noise_rmse_display": repr(noise_display),
            "seconds": repr(seconds), "width": str(width), "height": str(height),
            "bounces": str(bounces), "seed": str(seed), "scene": scene.name,
            "light": str(getattr(light, "name", "")), "exposure": repr(scene.exposure)}
        metadata[CHECKSUM_KEY] = reference_checksum(image, metadata)
        write_exr(path, image, metadata=metadata)
    log.info("reference %s %dx%d spp=%d bounces=%d: %.1f s (%s), noise display %.5f",
             scene.name, width, height, spp, bounces, seconds, variant, noise_display)
    return ref


def render_references(scene: Scene, light: Any, views: Sequence[View], *, width: int,
                      height: int, spp: int, bounces: int = 0, progress: bool = True,
                      ) -> list[Reference]:
    """:func:`render_reference` for each view, with a progress bar over views."""
    views = list(views)
    iterator: Any = views
    if progress:

        iterator = tqdm(views, desc=f"references {scene.name}", unit="view")
    return [render_reference(scene, light, view, width=width, height=height, spp=spp,
                             bounces=bounces, progress=False) for view in iterator]
