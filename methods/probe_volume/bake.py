"""Tracing the probes: visibility SH, validity, virtual offset, dilation, the ambient cube's
cosine visibilities and the DDGI depth moments; and folding a light into the probes.

* Validity (Unity APV): the fraction of a probe's rays whose first hit is a back face; above
  ``invalid_backface_fraction`` the probe is inside geometry.
* Virtual offset (Unity APV): an invalid probe whose nearest back-face hit lies within
  ``virtual_offset`` × its spacing is captured from just past that hit instead (the geometry
  bias: 1 % of its spacing beyond the surface) and traced again there; its lookup position
  stays on the lattice.
* Dilation (Unity APV): each iteration gives every invalid probe the inverse-square-distance
  weighted mean of the data of the valid (or already dilated) probes within 1.8 of its
  spacings, which covers its 26 lattice neighbours.
* Depth moments (Majercik et al. 2019, DDGI): per probe an octahedral map of D × D texels of
  the mean and mean square of the ray hit distances (clamped to 1.5 × the spacing's diagonal,
  escaping rays at that clamp), each texel weighting the rays by max(0, ω_t·ω)^50 as DDGI's
  depth blending does (``depthSharpness``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from methods.common.sphere_rays import trace_sphere
from methods.probe_volume.encoding import CUBE_AXES, SH_ENCODING_BANDS
from methods.probe_volume.placement import ProbeLayout
from prtbench.transport.raytrace import Tracer
from prtbench.transport.sh import (
    band_norms,
    clamped_cosine_zonal,
    eval_sh,
    lm_of,
    tpfl_matrix,
)

#: The sphere pattern's random stream (``trace_sphere``'s ``stream``): "PRBV".
PROBE_STREAM = 0x5052_4256
#: DDGI's depth-blending exponent (rtxgi-sdk ``probeDistanceExponent``).
DEPTH_SHARPNESS = 50.0
#: Hit distances are clamped to this many spacing diagonals (DDGI's probeMaxRayDistance scale).
DEPTH_RANGE = 1.5
#: Unity's geometry bias: how far past the back face a virtually offset probe is captured.
OFFSET_BIAS = 0.01
#: A dilation source is within this many spacings (the 26 lattice neighbours).
DILATION_RADIUS = 1.8


def oct_decode(uv: np.ndarray) -> np.ndarray:
    """Octahedral map [0, 1]² → unit directions (N, 3) (the inverse of ``oct_encode`` in
    probe_volume.frag)."""
    f = np.asarray(uv, np.float64) * 2.0 - 1.0
    n = np.stack([f[:, 0], f[:, 1], 1.0 - np.abs(f[:, 0]) - np.abs(f[:, 1])], axis=1)
    t = np.maximum(-n[:, 2], 0.0)
    n[:, 0] -= np.where(n[:, 0] >= 0.0, t, -t)
    n[:, 1] -= np.where(n[:, 1] >= 0.0, t, -t)
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def depth_texel_directions(texels: int) -> np.ndarray:
    """(D², 3) directions of the texel centres of a D × D octahedral map, row-major (v, u)."""
    c = (np.arange(texels) + 0.5) / texels
    v, u = np.meshgrid(c, c, indexing="ij")
    return oct_decode(np.stack([u.ravel(), v.ravel()], axis=1))


@dataclass(frozen=True, eq=False)
class ProbeBake:
    """The light-independent data of every probe.

    Attributes
    ----------
    visibility : ndarray, shape (P, b²), float64
        Sphere visibility SH (dilated into invalid probes).
    cube : ndarray, shape (P, 6), float64
        Cosine-weighted visibility 1/π ∫ V max(d·ω, 0) dω about the six axes (dilated).
    valid : ndarray, shape (P,), bool
    backface_fraction : ndarray, shape (P,)
    capture : ndarray, shape (P, 3)
        Where each probe was traced from (its lattice position, or its virtual offset).
    depth : ndarray, shape (P, D, D, 2), float32, or None
        Mean and mean square hit distance per octahedral texel.
    """

    visibility: np.ndarray
    cube: np.ndarray
    valid: np.ndarray
    backface_fraction: np.ndarray
    capture: np.ndarray
    depth: np.ndarray | None


def _reducer(layout: ProbeLayout, ids: np.ndarray, *, search: float, depth_texels: int):
    """The per-ray reduction of :func:`trace_sphere` for the probes ``ids``."""
    directions = depth_texel_directions(depth_texels).astype(np.float32) if depth_texels else None

    def reduce(sl, dirs, distances, backface):
        k, m = distances.shape
        spacing = layout.spacing[ids[sl]]
        # a_d = 1 − 1/π ∫ (1 − V) max(d·ω, 0) dω: exact for an unoccluded probe (as V's SH).
        blocked = np.isfinite(distances).astype(np.float64)
        out = {"cube": 1.0 - np.einsum("pm,pmd->pd", blocked,
                                       np.maximum(dirs @ CUBE_AXES.T, 0.0)) * (4.0 / m)}
        # Nearest back-face hit within the search distance (virtual offset).
        reach = search * spacing.min(axis=1)[:, None]
        back = np.where(backface & (distances < reach), distances, np.inf)
        nearest = back.argmin(axis=1)
        out["offset_t"] = back[np.arange(k), nearest]
        out["offset_dir"] = dirs[np.arange(k), nearest]
        if directions is not None:
            clamp = (DEPTH_RANGE * np.linalg.norm(spacing, axis=1))[:, None].astype(np.float32)
            d = np.minimum(distances, clamp)
            moments = np.zeros((k, len(directions), 2), np.float32)
            for s in range(0, k, 256):  # (256, D², M) float32 weights at a time
                w = np.maximum(np.einsum("td,pmd->ptm", directions, dirs[s:s + 256]), 0.0)
                w = w**DEPTH_SHARPNESS
                total = np.maximum(w.sum(axis=2), 1e-30)
                moments[s:s + 256, :, 0] = np.einsum("ptm,pm->pt", w, d[s:s + 256]) / total
                moments[s:s + 256, :, 1] = np.einsum("ptm,pm->pt", w, d[s:s + 256]**2) / total
            out["depth"] = moments.reshape(k, depth_texels, depth_texels, 2)
        return out

    return reduce


def bake_probes(scene, layout: ProbeLayout, *, bands: int, rays: int, seed: int,
                occlusion: bool, invalid_backface_fraction: float, virtual_offset: float,
                dilation_iterations: int, depth_texels: int, progress: bool) -> ProbeBake:
    """Trace every probe (then the virtually offset ones again), flag, dilate.

    Parameters
    ----------
    scene : Scene
    layout : ProbeLayout
    bands : int
        SH bands of the visibility.
    rays : int
    seed : int
    occlusion : bool
        False: every ray escapes (unshadowed, every probe valid).
    invalid_backface_fraction, virtual_offset : float
    dilation_iterations, depth_texels : int
        ``depth_texels`` 0: no depth moments.
    progress : bool
    """
    tracer = Tracer.from_scene(scene)
    ids = np.arange(layout.probes)

    def trace(which: np.ndarray, positions: np.ndarray, stream: int):
        return trace_sphere(tracer, positions, bands=bands, rays=rays, seed=seed, stream=stream,
                            occlusion=occlusion, progress=progress, desc="probes",
                            per_ray=_reducer(layout, which, search=virtual_offset,
                                             depth_texels=depth_texels))

    first = trace(ids, layout.positions, PROBE_STREAM)
    visibility, backface = first.visibility, first.backface_fraction
    cube, depth = first.reduced["cube"], first.reduced.get("depth")
    capture = layout.positions.copy()
    moved = np.flatnonzero((backface > invalid_backface_fraction)
                           & np.isfinite(first.reduced["offset_t"]))
    if len(moved):
        bias = OFFSET_BIAS * layout.spacing[moved].min(axis=1)
        capture[moved] += first.reduced["offset_dir"][moved] * (
            first.reduced["offset_t"][moved] + bias)[:, None]
        again = trace(moved, capture[moved], PROBE_STREAM + 1)
        visibility[moved], backface[moved] = again.visibility, again.backface_fraction
        cube[moved] = again.reduced["cube"]
        if depth is not None:
            depth[moved] = again.reduced["depth"]
    valid = backface <= invalid_backface_fraction
    visibility, cube = dilate(layout, valid, [visibility, cube], iterations=dilation_iterations)
    return ProbeBake(visibility, cube, valid, backface, capture, depth)


def dilate(layout: ProbeLayout, valid: np.ndarray, arrays: list[np.ndarray], *,
           iterations: int) -> list[np.ndarray]:
    """Invalid probes' rows of ``arrays`` replaced by the 1/d²-weighted mean of the valid (or
    already dilated) probes within :data:`DILATION_RADIUS` spacings, ``iterations`` times."""
    from scipy.spatial import cKDTree

    arrays = [np.array(a, np.float64, copy=True) for a in arrays]
    filled = np.asarray(valid, bool).copy()
    if iterations == 0 or filled.all() or not filled.any():
        return arrays
    tree = cKDTree(layout.positions)
    for _ in range(int(iterations)):
        todo = np.flatnonzero(~filled)
        if len(todo) == 0:
            break
        radius = DILATION_RADIUS * layout.spacing[todo].max(axis=1)
        reached = []
        for probe, r, near in zip(todo, radius, tree.query_ball_point(layout.positions[todo], r=radius)):
            sources = [q for q in near if filled[q]]
            if not sources:
                continue
            d2 = np.sum((layout.positions[sources] - layout.positions[probe]) ** 2, axis=1)
            w = 1.0 / np.maximum(d2, 1e-12 * r * r)
            reached.append((probe, sources, w / w.sum()))
        for probe, sources, w in reached:
            for a in arrays:
                a[probe] = np.tensordot(w, a[sources], axes=1)
        filled[[probe for probe, _, _ in reached]] = True
    return arrays


def cosine_convolution(bands: int) -> np.ndarray:
    """Â_l per coefficient (n²,): √(4π/(2l+1)) g_l, the clamped cosine's convolution."""
    l, _ = lm_of(bands)
    return (clamped_cosine_zonal(bands) / band_norms(bands))[l]


def fold(visibility: np.ndarray, light_sh: np.ndarray, *, encoding: str,
         bake_bands: int) -> np.ndarray:
    """The baked radiance coefficients (P, K, 3) of probes with visibility SH at ``bake_bands``.

    SH: R_k = Σ_ij Γ_ijk V_i L_j truncated to the encoding's bands; ambient cube: the irradiance
    E(d) = Σ_k Â_l R_k Y_k(d) about each axis d over all the bake's bands.
    """
    matrix = tpfl_matrix(np.asarray(light_sh, np.float64)[: bake_bands**2], bake_bands)
    v = np.asarray(visibility, np.float64)
    if encoding in SH_ENCODING_BANDS:
        return np.einsum("pi,ikc->pkc", v, matrix[:, : SH_ENCODING_BANDS[encoding] ** 2])
    radiance = np.einsum("pi,ikc->pkc", v, matrix) * cosine_convolution(bake_bands)[:, None]
    return np.einsum("dk,pkc->pdc", eval_sh(CUBE_AXES, bake_bands), radiance)
