"""Shared harness of the Raghavan et al. 2023 reproductions (table-nw-1 … 4, figure-nw-6).

Not a table itself. The generic runner cannot measure these tables: it precomputes on the
scene of the cell, so a "far" cell would train on cameras jittered from the far trajectory,
and it has no indirect-only metrics. Here every neural-wavelet model is trained once on the
**near** (training) trajectory of the scene, all of its views, and evaluated on

* ``far``: a held-out trajectory (four-animals: its ``far`` helix; other scenes:
  :func:`far_views`), the paper's "far views";
* ``near``: the training trajectory's own views, which no training camera sits on (the
  method jitters its training cameras 1/3 to 1 × ``view_jitter`` away), the paper's
  "held-out (near) views in training trajectories";

always under the method's held-out lights (never trained on).

Per (view, light) three Mitsuba renders are cached: full (``bounces``) and direct-only with
the same seed :data:`~reproductions.nw_evaluate.EVAL_SEED` — their difference is the
indirect-only reference, exactly as :mod:`reproductions.nw_evaluate` forms it — and
the method's own direct term (seed ``DIRECT_SEED``, ``direct_spp``). Every row's **full** image
is its indirect + that same direct image, so the full columns compare the indirect transports
alone, as the paper's variants share one direct term:

* ``neural-wavelet`` (hash grid or vertex features): ``renderer.render`` (its
  ``direct="mitsuba"``), and ``renderer.indirect`` for the indirect column;
* the SH baseline ``sloan-matrix``: its render with ``bounces`` minus its render with
  ``bounces=0`` (its own direct SH light) is its indirect part.

Metrics (DESIGN.md §7) on display images at the scene's exposure; the tables read the
``_masked`` ones (geometry pixels). Each measured (configuration, view set, light, view) is
one results-store row whose ``metrics`` hold the full-image metrics and ``indirect_<name>``
for the indirect-only ones; the row's ``cell_key`` is ``nw:`` + JSON of its table label.
"""

from __future__ import annotations

import json
import math
import sys
import time
import uuid
from collections.abc import Mapping
from dataclasses import asdict, dataclass, replace

import numpy as np

from methods.neural_wavelet.method import DIRECT_SEED
from methods.vertex.glossy import matrix_bytes, matrix_channels
from prtbench.api import config as config_mod
from prtbench.api import strict_json
from prtbench.api.errors import InvalidInputError
from prtbench.api.method import METHODS, load_or_precompute
from prtbench.api.profiles import get_profile
from prtbench.bench import metrics
from prtbench.bench.reproduction import Reproduction
from prtbench.bench.runner import device_description, load_average
from prtbench.io import imageio
from prtbench.render import gl
from prtbench.render.reference import render_reference
from prtbench.scene.model import Trajectory, View
from prtbench.scene.registry import get_scene
from prtbench.store.results import ResultRow, ResultsStore, git_sha
from prtbench.transport.lights import get_light
from prtbench.transport.raytrace import geometry_mask
from reproductions.nw_evaluate import EVAL_SEED, require_glossy

#: Per profile: scene, builder parameters, views per view set, held-out lights used, SH
#: baseline knobs. ``smoke`` runs in seconds on a procedural scene (no assets); ``quick`` is
#: four-animals reduced to fit tens of minutes on 2 CPU cores; ``paper`` every view.
SETUPS = {
    "smoke": {"scene": "sphere-over-plane", "params": {"sphere_segments": 16,
                                                       "plane_subdivisions": 4},
              "views": 1, "lights": 1, "sloan": {"sh_bands": 3, "rays_per_point": 64}},
    # quick: 3 bands, since four-animals' 84,702 vertices × 4⁴ floats × RGB (bounces) are
    # 248 MiB of matrices, over llvmpipe's 128 MiB shader-storage block limit.
    "quick": {"scene": "four-animals", "params": {"ground_subdivisions": 16},
              "views": 2, "lights": 1, "sloan": {"sh_bands": 3, "rays_per_point": 128}},
    "paper": {"scene": "four-animals", "params": {"ground_subdivisions": 64},
              "views": 30, "lights": 2, "sloan": {"sh_bands": 6, "rays_per_point": 4096}},
}
VARIANT = "glossy"
VIEW_SETS = ("far", "near")
CELL_PREFIX = "nw:"
#: Training facts of the model (its cached stats) stored with each of its rows.
TRAINING_FACTS = ("train_s", "pixels_per_s", "data_render_s", "loss_first", "loss_last")


@dataclass
class Setup:
    """What one profile measures on: the training scene and the two evaluation view sets."""

    profile: str
    train_scene: object  # all views of the near trajectory: what the model trains around
    scenes: dict  # view set -> Scene holding exactly the evaluated views
    lights: tuple[str, ...]
    width: int
    height: int
    reference_spp: int


def nw_class():
    if "neural-wavelet" not in METHODS.names():
        pass
    return METHODS.get("neural-wavelet")


def sloan_class():
    if "sloan-matrix" not in METHODS.names():
        pass
    return METHODS.get("sloan-matrix")


def nw_config(profile: str, **overrides):
    """The method's ``profile`` config with ``overrides`` (the table's variants)."""
    return nw_class().make_config(overrides, profile=profile)


def far_views(scene, n: int):
    """A held-out trajectory for a scene without one: each view turned half a step about +Y
    around its target, raised by 15° and moved 1.3 × further out."""

    views = scene.trajectory.views
    step = 360.0 / max(len(views), 1)
    out = []
    for v in views:
        target = np.asarray(v.target, np.float64)
        off = np.asarray(v.eye, np.float64) - target
        dist = float(np.linalg.norm(off)) * 1.3
        az = math.atan2(off[0], off[2]) + math.radians(step / 2)
        el = min(math.atan2(off[1], math.hypot(off[0], off[2])) + math.radians(15.0),
                 math.radians(80.0))
        eye = target + dist * np.array([math.cos(el) * math.sin(az), math.sin(el),
                                        math.cos(el) * math.cos(az)])
        out.append(View(eye=tuple(float(c) for c in eye), target=v.target, up=v.up,
                        fov_y=v.fov_y))
    return replace(scene, trajectory=Trajectory(tuple(out))).with_views(n)


def setup(profile: str) -> Setup:
    """The training scene, the far/near evaluation scenes and held-out lights of ``profile``."""

    prof = get_profile(profile)
    spec = SETUPS[profile]
    params = dict(spec["params"])
    if spec["scene"] == "four-animals":
        train = get_scene("four-animals", variant=VARIANT, trajectory="near", **params)
        far = get_scene("four-animals", variant=VARIANT, trajectory="far", **params)
        far = far.with_views(min(spec["views"], len(far.trajectory)))
    else:
        train = get_scene(spec["scene"], variant=VARIANT, **params)
        far = far_views(train, min(spec["views"], len(train.trajectory)))
    require_glossy(train, what="the neural-wavelet comparisons")
    near = train.with_views(min(spec["views"], len(train.trajectory)))
    lights = tuple(nw_config(profile).heldout_lights[:spec["lights"]])
    return Setup(profile, train, {"far": far, "near": near}, lights, prof.width, prof.height,
                 prof.reference_spp)


def train(config, st: Setup, *, progress: bool = True):
    """(artifact, precompute_s) of ``config`` trained around ``st.train_scene``'s trajectory.

    Calls the method's precompute directly rather than the artifact cache: the trained model
    itself is cached by its data (training cameras included) and knobs
    (:mod:`methods.neural_wavelet.train`), so this is a cache hit when trained before, and the
    precompute_s it returns is the recorded data + training time.
    """
    cls = nw_class()
    cls.validate(st.train_scene, config)
    artifact = cls.precompute(st.train_scene, config, progress=progress)
    meta = artifact.meta
    return artifact, float(meta["data_render_s"]) + float(meta["train_s"])


class References:
    """Cached Mitsuba renders of one (scene, view, light): full, indirect, the method's direct."""

    def __init__(self, st: Setup, *, bounces: int, direct_spp: int):
        self.st, self.bounces, self.direct_spp = st, int(bounces), int(direct_spp)

    def get(self, scene, light, view):
        kw = dict(width=self.st.width, height=self.st.height)
        full = render_reference(scene, light, view, spp=self.st.reference_spp,
                                bounces=self.bounces, seed=EVAL_SEED, **kw)
        direct = render_reference(scene, light, view, spp=self.st.reference_spp, bounces=0,
                                  seed=EVAL_SEED, **kw)
        own = render_reference(scene, light, view, spp=self.direct_spp, bounces=0,
                               seed=DIRECT_SEED, **kw)
        return full, (full.image - direct.image).astype(np.float32), own.image


def image_metrics(scene, view, *, full, indirect, ref_full, ref_indirect, width, height):
    """Full-image metrics and ``indirect_``-prefixed indirect-only ones (masked and not)."""

    mask = geometry_mask(scene, view, width, height)

    def shown(x):
        return imageio.display(np.nan_to_num(x, nan=0.0), exposure=scene.exposure)

    out = metrics.compute_metrics(shown(full), shown(ref_full), mask=mask)
    ind = metrics.compute_metrics(shown(indirect), shown(ref_indirect), mask=mask)
    out.update({f"indirect_{k}": v for k, v in ind.items()})
    return out, int(np.count_nonzero(mask))


def label_key(label: dict) -> str:
    return CELL_PREFIX + json.dumps(dict(label), sort_keys=True)


def labels(frame) -> list[dict]:
    """The table label of every row of ``frame`` (from ``cell_key``)."""
    return [json.loads(k[len(CELL_PREFIX):]) if isinstance(k, str) and k.startswith(CELL_PREFIX)
            else {} for k in frame["cell_key"]]


class RowWriter:
    """Builds the results-store rows of one reproduction run (one run id)."""

    def __init__(self, profile: str, tag: str):
        self.profile, self.tag = profile, tag
        self.run_id = f"{tag}-{uuid.uuid4().hex[:8]}"
        self.sha, self.device = git_sha(), device_description()
        self.rows: list = []

    def add(self, *, method: str, config, scene, light: str, view_index: int, view, label: dict,
            metrics: dict, width: int, height: int, memory_bytes, precompute_s, renderer: str,
            reference=None, frame=None, covered=None) -> None:

        nulls = strict_json.non_finite_keys(metrics)
        self.rows.append(ResultRow(
            method=method, scene=scene.name, config=config_mod.to_dict(config),
            scene_variant=scene.variant, light=light, view=view_index, view_json=asdict(view),
            width=width, height=height, reference_kind="path", metrics=dict(metrics),
            frame_ms=None if frame is None else frame.median_ms,
            frame_ms_p95=None if frame is None else frame.p95_ms,
            memory_bytes=None if memory_bytes is None else int(memory_bytes),
            precompute_s=precompute_s, renderer=renderer, device=self.device,
            git_sha=self.sha, profile=self.profile, run_id=self.run_id,
            reference_spp=None if reference is None else int(reference.spp),
            reference_noise=None if reference is None else float(reference.noise_rmse_display),
            scene_triangles=scene.n_triangles, scene_params=dict(scene.params),
            timing_source="" if frame is None else frame.source,
            status_reason=f"{', '.join(nulls)} stored as null" if nulls else "",
            covered_pixels=covered, scene_vertices=scene.n_vertices, cell_key=label_key(label),
            load_average=load_average()))

    def store(self, results_path) -> list[str]:
        ResultsStore(results_path).append(self.rows)
        return [self.run_id]


def log(tag: str, message: str) -> None:
    print(f"[{tag}] {time.strftime('%H:%M:%S')} {message}", file=sys.stderr, flush=True)


def measure_nw(writer: RowWriter, st: Setup, config, label: dict, *, view_sets=VIEW_SETS,
               progress: bool = True) -> None:
    """Train (or load) ``config`` and add one row per (view set, held-out light, view)."""
    cls = nw_class()
    artifact, precompute_s = train(config, st, progress=progress)
    refs = References(st, bounces=config.bounces, direct_spp=config.direct_spp)
    for view_set in view_sets:
        scene = st.scenes[view_set]
        renderer = cls.renderer(scene, artifact, config, width=st.width, height=st.height)
        try:
            for light_name in st.lights:
                light = get_light(light_name)
                for index, view in enumerate(scene.trajectory.views):
                    ref, ref_indirect, _ = refs.get(scene, light, view)
                    # = renderer.render(view, light) without computing the network twice
                    indirect, direct = renderer.frame(view, light)
                    full = indirect + direct
                    if config.direct == "offline-reference":  # the diagnostic, never ranked
                        full = full + renderer.offline_direct(view, light)
                    values, covered = image_metrics(scene, view, full=full, indirect=indirect,
                                                    ref_full=ref.image, ref_indirect=ref_indirect,
                                                    width=st.width, height=st.height)
                    values.update({f"bytes_{k}": float(v)
                                   for k, v in renderer.model.resident_bytes().items()})
                    values.update({k: float(artifact.meta[k]) for k in TRAINING_FACTS})
                    writer.add(method=cls.name, config=config, scene=scene, light=light.name,
                               view_index=index, view=view,
                               label={**label, "views": view_set}, metrics=values,
                               width=st.width, height=st.height,
                               memory_bytes=renderer.memory_bytes(),
                               precompute_s=precompute_s, renderer=renderer.renderer_string,
                               reference=ref, covered=covered)
                    log(writer.tag, f"{label} {view_set} {light.name} view {index}: indirect "
                        f"{values['indirect_psnr_masked']:.2f} dB, full "
                        f"{values['psnr_masked']:.2f} dB")
        finally:
            renderer.release()


def sloan_config(profile: str, *, bounces: int):
    return sloan_class().make_config({**SETUPS[profile]["sloan"], "bounces": int(bounces)},
                                     profile=profile)


def check_sloan(st: Setup, *, bounces: int) -> None:
    """Refuse before any training or reference render if the SH baseline cannot run here:
    this GL's shader-storage block limit (named with the profile, before the method's own
    validate checks it in its terms), then its validate (``max_bytes``); InvalidInputError,
    exit 2."""

    cls = sloan_class()  # registers methods.vertex.glossy

    limit = gl.storage_block_limit()
    for b in (bounces, 0):
        cfg = sloan_config(st.profile, bounces=b)
        size = matrix_bytes(st.train_scene.n_vertices, cfg.sh_bands,
                            channels=matrix_channels(cfg))
        if limit and size > limit:
            raise InvalidInputError(
                f"profile '{st.profile}': the SH baseline sloan-matrix sh_bands={cfg.sh_bands} "
                f"bounces={b} needs {size / 2**20:.1f} MiB of matrices on "
                f"{st.train_scene.n_vertices} vertices, over this GL's shader storage block limit "
                f"of {limit / 2**20:.1f} MiB ({gl.renderer_string()}); accepted: a profile whose "
                "baseline fits (smoke or quick here; paper needs a GPU driver)")
        cls.validate(st.train_scene, cfg)


def measure_sloan(writer: RowWriter, st: Setup, label: dict, *, bounces: int, direct_spp: int,
                  view_sets=VIEW_SETS, progress: bool = True) -> None:
    """The SH baseline: ``sloan-matrix`` with ``bounces`` minus its ``bounces=0`` render is its
    indirect; its full image is that + the neural rows' direct image (same call, cached)."""

    cls = sloan_class()
    configs = {b: sloan_config(st.profile, bounces=b) for b in (bounces, 0)}
    arts = {}
    for b, cfg in configs.items():
        cls.validate(st.train_scene, cfg)
        arts[b] = load_or_precompute(cls, st.train_scene.with_views(1), cfg, progress=progress)
    refs = References(st, bounces=bounces, direct_spp=direct_spp)
    for view_set in view_sets:
        scene = st.scenes[view_set]
        rend = {b: cls.renderer(scene, arts[b], cfg, width=st.width, height=st.height)
                for b, cfg in configs.items()}
        try:
            for light_name in st.lights:
                light = get_light(light_name)
                for index, view in enumerate(scene.trajectory.views):
                    ref, ref_indirect, own_direct = refs.get(scene, light, view)
                    indirect = rend[bounces].render(view, light) - rend[0].render(view, light)
                    values, covered = image_metrics(
                        scene, view, full=indirect + own_direct, indirect=indirect,
                        ref_full=ref.image, ref_indirect=ref_indirect, width=st.width,
                        height=st.height)
                    writer.add(method=cls.name, config=configs[bounces], scene=scene,
                               light=light.name, view_index=index, view=view,
                               label={**label, "views": view_set}, metrics=values,
                               width=st.width, height=st.height,
                               memory_bytes=rend[bounces].memory_bytes(),
                               precompute_s=float(arts[bounces].precompute_s),
                               renderer=rend[bounces].renderer_string, reference=ref,
                               covered=covered)
                    log(writer.tag, f"{label} {view_set} {light.name} view {index}: indirect "
                        f"{values['indirect_psnr_masked']:.2f} dB, full "
                        f"{values['psnr_masked']:.2f} dB")
        finally:
            for r in rend.values():
                r.release()


def mean_of(part, column: str) -> float:
    """Mean of a metric column over rows (NaN for none), as the tables print it."""
    if column not in part:
        return math.nan
    values = [float(v) for v in part[column] if v is not None and v == v]
    return float(np.mean(values)) if values else math.nan


def select(frame, **label):
    """Rows of ``frame`` whose label has every given key/value."""
    keep = [all(lab.get(k) == v for k, v in label.items()) for lab in labels(frame)]
    return frame[keep] if len(frame) else frame


class AblationTable(Reproduction):
    """Base of the neural-wavelet ablation tables (table-nw-3, table-nw-4): one model per value
    of :attr:`knob` in :attr:`values` ``[profile]``, the rest the profile's config, trained on
    the same data and evaluated on the far views (:func:`measure_ablation`); one run id,
    tagged :attr:`tag`. Subclasses set those and write :meth:`format` with
    :func:`ablation_rows`."""

    knob: str = ""
    values: Mapping[str, tuple] = {}
    tag: str = ""

    def measure(self, profile: str, *, results_path=None) -> list[str]:
        st = setup(profile)
        writer = RowWriter(profile, self.tag)
        measure_ablation(writer, st, self.knob, self.values[profile], tag=self.tag)
        return writer.store(results_path)


def measure_ablation(writer: RowWriter, st: Setup, knob: str, values, *, tag: str,
                     view_sets=("far",), progress: bool = True) -> None:
    """One neural-wavelet model per value of ``knob`` (the rest the profile's), evaluated on
    ``view_sets``; the value equal to the profile's default shares table-nw-1's model."""
    for value in values:
        log(tag, f"{knob}={value}: training / evaluating")
        measure_nw(writer, st, nw_config(st.profile, **{knob: value}), {knob: value},
                   view_sets=view_sets, progress=progress)


ABLATION_METRICS = ("psnr", "ssim", "flip")


def ablation_rows(frame, knob: str, values, *, extra=None) -> tuple[list[str], list[list]]:
    """Header and rows of an ablation table: per value the masked full / indirect metrics."""
    header = [knob, "rows"]
    for m in ABLATION_METRICS:
        header += [f"{m.upper()} full", f"{m.upper()} indirect"]
    header += ["resident bytes", "precompute s"] + [name for name, _ in (extra or ())]
    rows = []
    for value in values:
        part = select(frame, **{knob: value})
        if not len(part):
            continue
        row = [value, len(part)]
        for m in ABLATION_METRICS:
            row += [mean_of(part, f"metric_{m}_masked"),
                    mean_of(part, f"metric_indirect_{m}_masked")]
        row += [int(part["memory_bytes"].iloc[0]), float(part["precompute_s"].iloc[0])]
        row += [fn(part, value) for _, fn in (extra or ())]
        rows.append(row)
    return header, rows
