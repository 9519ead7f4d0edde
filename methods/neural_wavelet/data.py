"""Training data of the neural wavelet transport: indirect-only Mitsuba images + GL G-buffers.

**Indirect only.** Mitsuba 3's ``path`` integrator has no minimum depth, so an indirect image is
``full − direct`` of two renders *with the same seed*: ``bounces`` bounces
(``max_depth = bounces + 2``) and direct only (``max_depth = 2``). Both consume the same random
numbers along the camera path up to the first bounce (the integrator samples the emitter, then
the BSDF, at every vertex in the same order), so their direct parts are the same samples and
cancel exactly: the difference is the indirect part of the same paths, not a difference of two
noisy images (``tests/methods/neural_wavelet/test_neural_wavelet.py`` checks that it is non-negative to
rounding and that direct + indirect matches an independent full render within its noise).

**Inputs.** The G-buffer of the same camera from our GL pass (:mod:`.gbuffer`): what the renderer
feeds the network at run time. Only front-facing covered pixels become training rows.

**Lights.** Each training light is a registered light (HDRIs and the analytic ``sky``, ``sun``,
``purple``) rotated about +Y by 360°·i/``light_rotations`` (the paper rotates each map by 120° and
240°: ``light_rotations=3``). A rotation is an exact column shift of the lat-long map. With
``light_tilt`` > 0, turns i ≥ 1 are also tilted by a seeded angle in ±``light_tilt`` degrees
about a seeded horizontal axis (a bilinear resampling): a turn about +Y keeps every source at
its elevation, so a held-out light whose sun sits lower than any training light's is otherwise
an extrapolation. ``random_lights`` > 0 appends that many seeded procedural environments
(:mod:`prtbench.transport.random_lights`: random sky and ground, one to three sources of random size,
elevation and colour) to the named ones. Held-out lights (never in training) are checked to be
disjoint from the training names.

**Views.** Training cameras are the scene's trajectory views moved by a seeded yaw of
±[``view_jitter``/3, ``view_jitter``] degrees about the target, a pitch of ±``view_jitter``/2
and a distance scale in [0.8, 1.2]: never the trajectory's own views, which are the held-out
"far" views the runner evaluates; :func:`near_views` moves those to 0.6 × their distance
(the paper's near views, also held out). Each camera is rendered under ``lights_per_view``
training lights drawn without replacement (the paper: 2).

Everything is cached by :func:`prtbench.api.cache.cached_arrays` (atomic); a non-finite pixel in
any render raises InvalidInputError before anything is stored.
"""

from __future__ import annotations

import json
import math
import os
import time

import numpy as np
from tqdm import tqdm

from methods.neural_wavelet.gbuffer import GBufferPass, pixel_rows
from prtbench.api.cache import cached_arrays, content_key
from prtbench.api.errors import InvalidInputError, UnknownNameError
from prtbench.render.reference import render_reference
from prtbench.scene.model import View
from prtbench.transport.lights import LIGHTS, EnvironmentLight, get_light
from prtbench.transport.random_lights import random_environments
from prtbench.transport.wavelet import haar
from prtbench.transport.wavelet.cubemap import light_cubemap

#: Bump when the data (rendering, G-buffer, views, lights) changes for the same knobs.
DATA_VERSION = 1
#: The knobs of the method config that change the training data.
DATA_KNOBS = ("bounces", "train_lights", "light_rotations", "light_tilt", "random_lights",
              "train_views", "lights_per_view", "view_jitter", "train_width", "train_height",
              "train_spp", "cubemap", "seed")
#: Knobs (of the data or of training) added after datasets and models were cached: at this value
#: each is left out of every key (dataset, model, artifact), so those keep the keys they had.
LATE_KNOB_DEFAULTS = {"light_tilt": 0.0, "random_lights": 0, "relative_eps": 0.01}


def without_late_defaults(knobs: dict) -> dict:
    """``knobs`` less the entries that hold their :data:`LATE_KNOB_DEFAULTS` value."""
    return {k: v for k, v in knobs.items() if LATE_KNOB_DEFAULTS.get(k, object()) != v}


def rotated_light(light, degrees: float):
    """``light`` turned about +Y by ``degrees`` (an exact column shift; name ``name@deg``)."""

    width = light.image.shape[1]
    shift = int(round(width * float(degrees) / 360.0)) % width
    if shift == 0:
        return light
    image = np.roll(light.image, shift, axis=1)
    return EnvironmentLight(f"{light.name}@{round(360.0 * shift / width)}", image,
                            source=f"{light.source} rotated by {shift} columns")


def tilted_light(light, degrees: float, *, axis_azimuth_deg: float):
    """``light`` turned by ``degrees`` about the horizontal axis at ``axis_azimuth_deg`` from +X
    towards +Z (bilinear resampling of the lat-long map; name ``name~deg``).

    The tilted map's radiance from direction d is ``light``'s from R⁻¹d, R the rotation, so a
    source at direction s moves to R s.
    """

    if float(degrees) == 0.0:
        return light
    phi, theta = math.radians(float(axis_azimuth_deg)), math.radians(float(degrees))
    axis = np.array([math.cos(phi), 0.0, math.sin(phi)])
    # Rodrigues: R = I cos t + sin t [a]x + (1 - cos t) a aT; R⁻¹ = Rᵀ.
    cross = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]],
                      [-axis[1], axis[0], 0.0]])
    rotation = (np.eye(3) * math.cos(theta) + math.sin(theta) * cross
                + (1.0 - math.cos(theta)) * np.outer(axis, axis))
    dirs = light.texel_directions().reshape(-1, 3)
    image = light.radiance(dirs @ rotation).reshape(light.image.shape)  # rows: Rᵀ d
    return EnvironmentLight(f"{light.name}~{float(degrees):.0f}", image.astype(np.float32),
                            source=f"{light.source} tilted by {float(degrees):.3g} degrees "
                                   f"about the horizontal axis at {float(axis_azimuth_deg):.3g}")


def training_lights(names, rotations: int, *, tilt: float = 0.0, seed: int = 0,
                    random: int = 0) -> list:
    """Every training light: each name at ``rotations`` turns about +Y; with ``tilt`` > 0,
    turns i ≥ 1 also tilted by a seeded angle in ±``tilt`` degrees; then ``random`` seeded
    procedural environments (:mod:`prtbench.transport.random_lights`; module docstring)."""

    if int(rotations) != rotations or rotations < 1:
        raise InvalidInputError(f"light_rotations={rotations!r}; accepted: integers >= 1")
    if not 0.0 <= float(tilt) <= 180.0:
        raise InvalidInputError(f"light_tilt={tilt!r}; accepted: degrees in [0, 180]")
    if int(random) != random or random < 0:
        raise InvalidInputError(f"random_lights={random!r}; accepted: integers >= 0")
    rng = np.random.default_rng([int(seed), 0x544C])  # stream tag "TL"
    out = []
    for name in names:
        base = get_light(name)
        for i in range(int(rotations)):
            light = rotated_light(base, 360.0 * i / rotations)
            if tilt and i:
                angle, azimuth = float(tilt) * rng.uniform(-1.0, 1.0), rng.uniform(0.0, 360.0)
                light = tilted_light(light, angle, axis_azimuth_deg=azimuth)
            out.append(light)
    return out + random_environments(int(random), seed=seed)


def check_light_split(train, heldout) -> None:
    """Held-out lights must never be trained on; at least one of each."""

    if not train:
        raise InvalidInputError("train_lights is empty; accepted: one or more light names")
    known = LIGHTS.names()
    for name in (*train, *heldout):  # names only: loading HDRIs waits for the precompute
        if name not in known and not os.path.isfile(name):
            raise UnknownNameError("light", name, known)
    common = sorted(set(train) & set(heldout))
    if common:
        raise InvalidInputError(f"lights {', '.join(common)} are both train_lights and "
                                "heldout_lights; accepted: disjoint sets (held-out lights are "
                                "never seen in training)")


def _orbit(view, *, yaw_deg: float, pitch_deg: float, scale: float):
    """``view`` with its eye turned about the target (yaw about +Y, then pitch) and scaled."""

    target = np.asarray(view.target, np.float64)
    offset = np.asarray(view.eye, np.float64) - target
    dist = float(np.linalg.norm(offset))
    horiz = math.hypot(offset[0], offset[2])
    azimuth = math.atan2(offset[0], offset[2]) + math.radians(yaw_deg)
    elevation = math.atan2(offset[1], horiz) + math.radians(pitch_deg)
    elevation = max(min(elevation, math.radians(80.0)), math.radians(-80.0))
    d = dist * scale
    eye = target + d * np.array([math.cos(elevation) * math.sin(azimuth), math.sin(elevation),
                                 math.cos(elevation) * math.cos(azimuth)])
    return View(eye=tuple(float(c) for c in eye), target=view.target, up=view.up,
                fov_y=view.fov_y)


def training_views(scene, *, count: int, jitter: float, seed: int) -> list:
    """``count`` cameras near (never on) the trajectory's views, see the module docstring."""
    base = scene.trajectory.views
    rng = np.random.default_rng([int(seed), 0x4E57])  # stream tag "NW"
    out = []
    for i in range(int(count)):
        sign = 1.0 if rng.random() < 0.5 else -1.0
        yaw = sign * jitter * (1.0 / 3.0 + 2.0 / 3.0 * rng.random())
        pitch = jitter * (rng.random() - 0.5)
        out.append(_orbit(base[i % len(base)], yaw_deg=yaw, pitch_deg=pitch,
                          scale=0.8 + 0.4 * rng.random()))
    return out


def near_views(scene, *, scale: float = 0.6) -> list:
    """The trajectory's views at ``scale`` × their distance to the target (held-out "near")."""
    return [_orbit(v, yaw_deg=0.0, pitch_deg=0.0, scale=scale) for v in scene.trajectory.views]


def light_coefficients(light, n: int) -> np.ndarray:
    """Haar coefficients (6N², 3) float32 of ``light``'s texel-mean cubemap (no solid angles:
    the transport learns them, as the paper and :mod:`prtbench.transport.wavelet` both state)."""

    cube = np.moveaxis(light_cubemap(light, n), -1, 0)  # (3, 6, N, N)
    return haar.forward(cube).reshape(3, -1).T.astype(np.float32)


def check_finite_image(image: np.ndarray, what: str) -> None:
    bad = ~np.isfinite(image)
    if bad.any():
        raise InvalidInputError(f"{what} has {int(bad.any(axis=-1).sum())} non-finite pixels "
                                "(NaN/Inf); accepted: finite training images only (nothing "
                                "was cached)")


def indirect_image(scene, light, view, *, width: int, height: int, spp: int, bounces: int,
                   seed: int) -> tuple[np.ndarray, np.ndarray, dict]:
    """(indirect, direct, facts): ``bounces``-bounce minus direct-only render, same seed.

    Returns
    -------
    indirect, direct : ndarray, shape (H, W, 3), float32
    facts : dict
        ``seconds``, ``negative`` (the most negative indirect value), ``noise_rmse`` of the
        full render.
    """

    if bounces < 1:
        raise InvalidInputError(f"bounces={bounces}; accepted: >= 1 (the network learns "
                                "indirect light)")
    start = time.perf_counter()
    full = render_reference(scene, light, view, width=width, height=height, spp=spp,
                            bounces=bounces, seed=seed, use_cache=False)
    direct = render_reference(scene, light, view, width=width, height=height, spp=spp,
                              bounces=0, seed=seed, use_cache=False)
    for name, img in (("full", full.image), ("direct", direct.image)):
        check_finite_image(img, f"training render ({name}) of light '{light.name}'")
    indirect = full.image - direct.image
    facts = {"seconds": time.perf_counter() - start, "negative": float(indirect.min()),
             "noise_rmse": float(full.noise_rmse)}
    return indirect.astype(np.float32), direct.image, facts


def dataset_key(scene, config, views) -> str:
    knobs = without_late_defaults({k: getattr(config, k) for k in DATA_KNOBS})
    eyes = [[v.eye, v.target, v.fov_y] for v in views]
    return content_key("nw-data", DATA_VERSION, scene.content_hash(), knobs, eyes)


def build_dataset(scene, config, *, progress: bool = True) -> dict[str, np.ndarray]:
    """Training rows of ``scene`` for ``config`` (cached): see the module docstring.

    Returns
    -------
    dict of ndarray
        Per row: ``positions``, ``normals``, ``wo``, ``kd``, ``ks`` (R, 3), ``shininess`` (R,),
        ``triangles`` (R,) int64, ``target`` (R, 3) indirect radiance, ``light`` (R,) int32
        index into the training lights, ``image`` (R,) int32. Per light: ``coeffs``
        (n_lights, 6N², 3). ``stats``: JSON facts (render seconds, most negative indirect).
    """

    lights = training_lights(config.train_lights, config.light_rotations,
                             tilt=config.light_tilt, seed=config.seed,
                             random=config.random_lights)
    views = training_views(scene, count=config.train_views, jitter=config.view_jitter,
                           seed=config.seed)

    def compute() -> dict[str, np.ndarray]:
        rng = np.random.default_rng([int(config.seed), 0x4C49])  # "LI"
        per_view = min(int(config.lights_per_view), len(lights))
        jobs = [(v, int(l)) for v, view in enumerate(views)
                for l in rng.choice(len(lights), size=per_view, replace=False)]
        gpass = GBufferPass(scene, width=config.train_width, height=config.train_height)
        rows: dict[str, list] = {}
        seconds, negative = 0.0, 0.0
        bar = None
        if progress:

            bar = tqdm(total=len(jobs), desc=f"neural-wavelet data {scene.name}", unit="image",
                       leave=False)
        try:
            for index, (v, l) in enumerate(jobs):
                view = views[v]
                indirect, _, facts = indirect_image(
                    scene, lights[l], view, width=config.train_width,
                    height=config.train_height, spp=config.train_spp, bounces=config.bounces,
                    seed=(1_000_003 + int(config.seed) * 7919 + index) % (2**32 - 1))
                seconds += facts["seconds"]
                negative = min(negative, facts["negative"])
                px = pixel_rows(gpass.read(view), view.eye)
                px["target"] = indirect.reshape(-1, 3)[px["pixel"]]
                px["light"] = np.full(len(px["pixel"]), l, np.int32)
                px["image"] = np.full(len(px["pixel"]), index, np.int32)
                for key, value in px.items():
                    rows.setdefault(key, []).append(value)
                if bar is not None:
                    bar.update(1)
        finally:
            if bar is not None:
                bar.close()
            gpass.release()
        out = {k: np.concatenate(v) for k, v in rows.items()}
        if not len(out.get("pixel", [])):
            raise InvalidInputError(f"scene '{scene.name}': no training view sees any front "
                                    "face; accepted: a scene its trajectory looks at")
        out["coeffs"] = np.stack([light_coefficients(light, config.cubemap) for light in lights])
        out["stats"] = np.array(json.dumps({
            "render_s": seconds, "images": len(jobs), "rows": int(len(out["pixel"])),
            "most_negative_indirect": negative, "lights": [lt.name for lt in lights]}))
        return out

    return cached_arrays("nw-data", dataset_key(scene, config, views), compute)
