"""Run one job: precompute (cached) → render each view → reference (cached) → metrics →
timings → memory → files and result rows.

Everything a user can get wrong (method, scene, variant, light, profile, reference kind,
``--set`` keys and values, resolution, view count, and every output location: ``--out``,
``--json``, ``--results``, the cache) is validated by :func:`prepare` before any cache entry,
output file or result row is written.

A view whose measurement is meaningless — a black or non-finite method image, a black
reference, an empty geometry mask, a non-finite masked metric — is still stored, with status
``degenerate`` and the reason (:func:`prtbench.bench.degeneracy.degenerate_reason`); the CLI
then exits 1.
"""

from __future__ import annotations

import math
import os
import platform
import re
import sys
import time
import uuid
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from prtbench.api import config as config_mod
from prtbench.api import strict_json
from prtbench.api.cache import atomic_path
from prtbench.api.errors import InvalidInputError, UnknownNameError
from prtbench.api.method import METHODS, Method, load_or_precompute
from prtbench.api.profiles import Profile, get_profile
from prtbench.bench import metrics
from prtbench.bench.degeneracy import degenerate_reason
from prtbench.bench.intervals import metric_interval
from prtbench.bench.job import NO_OUTPUTS, Job, Outputs
from prtbench.bench.outputs import (
    check_cache,
    check_file,
    check_file_clear_of,
    check_folder,
    check_results_store,
)
from prtbench.bench.protocol import (
    MAX_REFERENCE_BOUNCES,
    panel_of,
    reference_bounces,
    split_of,
    time_light_change,
)
from prtbench.io import imageio
from prtbench.render import renders
from prtbench.render.mitsuba_variant import check_variant
from prtbench.render.reference import render_reference
from prtbench.scene.model import VARIANTS, Scene
from prtbench.scene.registry import SCENES, get_scene
from prtbench.store.results import ResultRow, default_path, git_sha
from prtbench.transport.lights import get_light
from prtbench.transport.parallel import thread_count
from prtbench.transport.raytrace import geometry_mask


@dataclass
class PreparedRun:
    """A validated job with its resolved objects."""

    job: Job
    outputs: Outputs
    method_cls: type[Method]
    config: Any
    profile: Profile
    scene: Scene
    light: Any
    width: int
    height: int
    reference_method: tuple[type[Method], Any] | None


@dataclass
class ViewResult:
    view: int
    metrics: dict[str, float]
    frame_ms: float
    frame_ms_p95: float
    files: dict[str, str]
    timing_source: str = "timer-query"
    #: ``ok`` or ``degenerate`` (see :func:`degenerate_reason`) and why.
    status: str = "ok"
    status_reason: str = ""
    #: Pixels covered by geometry (the masked metrics' support).
    covered_pixels: int | None = None
    #: The masked PSNR's interval from the reference's noise (:mod:`prtbench.bench.intervals`).
    psnr_masked_lo: float | None = None
    psnr_masked_hi: float | None = None
    #: Milliseconds of the frame's parts (the renderer's ``frame_components``).
    frame_components: dict[str, float] = field(default_factory=dict)


@dataclass
class RunSummary:
    method: str
    config: dict[str, Any]
    scene: str
    variant: str
    light: str
    profile: str
    width: int
    height: int
    reference: str
    reference_spp: int | None
    reference_noise_display: float | None
    renderer: str
    memory_bytes: int
    precompute_s: float
    precompute_cached: bool
    run_id: str
    views: list[ViewResult]
    #: The artifact was rebuilt from a corrupt cache file; ``precompute_s`` is the original
    #: build's time when it was recorded, ``precompute_rebuild_s`` the rebuild's.
    precompute_rebuilt: bool = False
    precompute_rebuild_s: float | None = None
    #: Why ``precompute_s`` is not the original build's time (empty when it is).
    rebuilt_note: str = ""
    #: The protocol's facts (docs/PROTOCOL.md): the reference's bounces, the panel, the light
    #: class, the split, the resident parts and the per-light work.
    reference_bounces: int | None = None
    panel: str = ""
    light_class: str = ""
    split: str = ""
    memory_breakdown: dict[str, int] = field(default_factory=dict)
    light_change_ms: float | None = None

    @property
    def status(self) -> str:
        """``degenerate`` if any view is, else ``ok``."""
        return "degenerate" if any(v.status == "degenerate" for v in self.views) else "ok"

    @property
    def status_reason(self) -> str:
        """The degenerate views and why (``view 0: method image is all black``)."""
        return "; ".join(f"view {v.view}: {v.status_reason}" for v in self.views
                         if v.status == "degenerate")

    def mean_metrics(self) -> dict[str, float]:
        keys = self.views[0].metrics.keys() if self.views else []
        return {k: float(np.mean([v.metrics[k] for v in self.views])) for k in keys}

    def to_json(self) -> dict[str, Any]:
        out = asdict(self)
        out["mean_metrics"] = self.mean_metrics()
        out["mean_frame_ms"] = float(np.mean([v.frame_ms for v in self.views])) if self.views else None
        out["status"], out["status_reason"] = self.status, self.status_reason
        return out


def parse_resolution(text: str) -> tuple[int, int]:
    """``"WxH"`` → (W, H) with both in 8..8192 (whole numbers in digits: not ``1e3``,
    ``1_000`` or ``64.0``)."""
    found = re.fullmatch(r"([+-]?\d+)x([+-]?\d+)", text.strip().lower())
    if found is None:
        raise InvalidInputError(f"--res '{text}'; accepted: WxH, e.g. 320x240")
    w, h = int(found[1]), int(found[2])
    if not (8 <= w <= 8192 and 8 <= h <= 8192):
        raise InvalidInputError(f"--res '{text}'; accepted: width and height in 8..8192")
    return w, h


def _reference_method(kind: str, profile: str) -> tuple[type[Method], Any] | None:
    if kind == "path":
        return None
    prefix, _, name = kind.partition(":")
    if prefix != "method" or not name:
        raise InvalidInputError(f"--reference '{kind}'; accepted: path, method:<name> "
                                f"(methods: {', '.join(METHODS.names())})")
    cls = METHODS.get(name)
    return cls, cls.make_config(profile=profile)


def resolve_views(scene: Scene, profile: Profile, views: int | None) -> Scene:
    """``scene`` keeping ``views`` trajectory views (None: the profile's count, capped by the
    scene's); a count outside 1..len(trajectory) raises. Shared by ``run`` and ``reference``."""
    n_views = views if views is not None else min(profile.views, len(scene.trajectory))
    return scene.with_views(n_views)


def check_outputs(outputs: Outputs, *, results_path: Path | None, store: bool) -> None:
    """Every location a job will write to is usable (see :mod:`prtbench.bench.outputs`),
    ``--json`` not the ``--out`` folder the run makes for its images (nor one above it)."""
    if outputs.out_dir is not None:
        check_folder("--out", outputs.out_dir)
    if outputs.json_path is not None:
        check_file("--json", outputs.json_path)
        if outputs.out_dir is not None:
            check_file_clear_of("--json", outputs.json_path, folder_option="--out",
                                folder=outputs.out_dir)
    if store:
        check_results_store("--results", results_path or default_path())
    check_cache()


def prepare(job: Job, *, outputs: Outputs = NO_OUTPUTS, results_path: Path | None = None,
            store: bool = True, profile: str = "quick") -> PreparedRun:
    """Validate and resolve ``job`` (in ``profile`` unless it names its own); writes nothing.

    ``results_path`` and ``store`` say where the rows will go (checked here; the rows are
    written by :func:`prtbench.bench.submit.submit`, never by the run itself).
    """
    job = job.in_profile(profile)
    profile_obj = get_profile(job.profile)
    SCENES.check(job.scene)
    method_cls = METHODS.get(job.method)
    config = method_cls.make_config(job.overrides, profile=job.profile)
    if job.variant not in VARIANTS:
        raise UnknownNameError("variant", job.variant, VARIANTS)
    reference_method = _reference_method(job.reference, job.profile)
    rb = job.reference_bounces
    if rb is not None and (isinstance(rb, bool) or not isinstance(rb, int)
                           or not 0 <= rb <= MAX_REFERENCE_BOUNCES):
        raise InvalidInputError(f"reference bounces {rb!r}; accepted: a whole number 0.."
                                f"{MAX_REFERENCE_BOUNCES}")
    if rb is not None and reference_method is not None:
        raise InvalidInputError(f"reference bounces {rb} with reference '{job.reference}'; "
                                "accepted: reference bounces only with the path reference")
    thread_count()  # a bad $PRTBENCH_THREADS fails here, not at the first ray query
    if reference_method is None:  # only the path-traced reference needs Mitsuba
        check_variant()  # a bad $PRTBENCH_MITSUBA_VARIANT fails before the precompute
    scene = get_scene(job.scene, variant=job.variant, **dict(job.scene_params))
    light = get_light(job.light or scene.default_light)
    scene = resolve_views(scene, profile_obj, job.views)
    width, height = job.resolution or (profile_obj.width, profile_obj.height)
    method_cls.validate(scene, config)
    method_cls.validate_resolution(config, width=width, height=height)
    if reference_method is not None:
        reference_method[0].validate(scene, reference_method[1])
    check_outputs(outputs, results_path=results_path, store=store)
    return PreparedRun(job, outputs, method_cls, config, profile_obj, scene, light, width, height,
                       reference_method)


def _log(echo: bool, message: str) -> None:
    if echo:
        print(message, file=sys.stderr, flush=True)


def execute(prepared: PreparedRun, *, progress: bool = True, echo: bool = True) -> RunSummary:
    """Run a prepared job; returns its summary and writes its files (never the store: the
    rows, :func:`summary_rows`, go to the client that submitted the job)."""
    job, scene, light = prepared.job, prepared.scene, prepared.light
    method_cls, config = prepared.method_cls, prepared.config
    width, height = prepared.width, prepared.height
    _log(echo, f"[prtbench] profile={prepared.profile.name} method={method_cls.name} "
               f"scene={scene.name}/{scene.variant} ({scene.n_triangles} tris) light={light.name} "
               f"views={len(scene.trajectory)} res={width}x{height} reference={job.reference}")
    artifact = load_or_precompute(method_cls, scene, config, progress=progress)
    _log(echo, f"[prtbench] precompute: {artifact.precompute_s:.1f} s"
               f"{' (cached)' if artifact.cache_hit else ''}"
               f"{f' (rebuilt from a corrupt cache file in {artifact.rebuild_s:.2f} s)' if artifact.rebuilt else ''}"
               f", {artifact.nbytes / 2**20:.2f} MiB")
    renderer = method_cls.renderer(scene, artifact, config, width=width, height=height)
    ref_renderer = None
    bounces = reference_bounces(job, config)
    if prepared.reference_method is not None:
        ref_cls, ref_config = prepared.reference_method
        ref_artifact = load_or_precompute(ref_cls, scene, ref_config, progress=progress)
        ref_renderer = ref_cls.renderer(scene, ref_artifact, ref_config, width=width, height=height)
    run_id = uuid.uuid4().hex[:12]
    out_dir = None
    if prepared.outputs.out_dir is not None:
        out_dir = (Path(prepared.outputs.out_dir) / method_cls.name
                   / f"{scene.name}-{scene.variant}" / light.name)
    view_results: list[ViewResult] = []
    ref_spp, ref_noise = None, None
    try:
        for index, view in enumerate(scene.trajectory.views):
            image = renderer.render(view, light)
            if ref_renderer is None:
                ref = render_reference(scene, light, view, width=width, height=height,
                                       spp=prepared.profile.reference_spp, bounces=bounces,
                                       progress=progress)
                ref_image, ref_spp = ref.image, ref.spp
                ref_noise = max(ref_noise or 0.0, float(ref.noise_rmse_display))
            else:
                ref_image = ref_renderer.render(view, light)
            mask = geometry_mask(scene, view, width, height)
            test_d = imageio.display(image, exposure=scene.exposure)
            ref_d = imageio.display(ref_image, exposure=scene.exposure)
            if np.isfinite(image).all():
                values = metrics.compute_metrics(test_d, ref_d, mask=mask)
            else:  # the metrics refuse non-finite pixels: nothing here is measured
                values = {key: math.nan for name in metrics.LDR_METRICS
                          for key in (name, f"{name}_masked")}
                test_d = np.nan_to_num(test_d, nan=0.0)  # for the PNGs
            reason = degenerate_reason(image, test_d, ref_d, mask, values)
            lo, hi = metric_interval(values.get("psnr_masked"),
                                     noise_rmse=None if ref_renderer is not None
                                     else float(ref.noise_rmse_display),
                                     pixels=int(np.count_nonzero(mask)))
            # Kept for the comparison site (sweeps write no image files): prtbench/renders.py.
            renders.store(run_id, index, image, exposure=scene.exposure,
                          reference_file=ref.path if ref_renderer is None else None,
                          reference_image=ref_image if ref_renderer is not None else None)
            times = renderer.frame_time(view, light, warmup=prepared.profile.timing_warmup,
                                        frames=prepared.profile.timing_frames)
            files: dict[str, str] = {}
            if out_dir is not None:
                stem = out_dir / f"view{index:02d}"
                imageio.write_exr(f"{stem}.exr", image)
                imageio.write_png(f"{stem}.png", test_d)
                imageio.write_png(f"{stem}-reference.png", ref_d)
                imageio.write_png(f"{stem}-flip.png", metrics.error_map(test_d, ref_d))
                files = {k: f"{stem}{suffix}" for k, suffix in
                         (("exr", ".exr"), ("png", ".png"), ("reference", "-reference.png"),
                          ("flip", "-flip.png"))}
            components = dict(renderer.frame_components) or {"frame": times.median_ms}
            view_results.append(ViewResult(index, values, times.median_ms, times.p95_ms, files,
                                           times.source, "degenerate" if reason else "ok", reason,
                                           int(np.count_nonzero(mask)), lo, hi, components))
            _log(echo, f"[prtbench] view {index}: psnr_masked={values.get('psnr_masked', float('nan')):.2f} dB "
                       f"frame={times.median_ms:.3f} ms{f' DEGENERATE: {reason}' if reason else ''}")
        memory = renderer.memory_bytes()
        breakdown = {k: int(v) for k, v in renderer.memory_breakdown().items()}
        light_change_ms = time_light_change(renderer, scene.trajectory.views[0], light)
    finally:
        renderer.release()
        if ref_renderer is not None:
            ref_renderer.release()
    summary = RunSummary(
        method=method_cls.name, config=config_mod.to_dict(config), scene=scene.name,
        variant=scene.variant, light=light.name, profile=prepared.profile.name, width=width,
        height=height, reference=job.reference, reference_spp=ref_spp,
        reference_noise_display=ref_noise, renderer=renderer.renderer_string,
        memory_bytes=memory, precompute_s=artifact.precompute_s,
        precompute_cached=artifact.cache_hit, run_id=run_id, views=view_results,
        precompute_rebuilt=artifact.rebuilt, precompute_rebuild_s=artifact.rebuild_s,
        reference_bounces=bounces if ref_renderer is None else None,
        panel=panel_of(prepared, ref_spp=ref_spp, bounces=bounces),
        light_class=method_cls.light_class_of(config),
        split=split_of(method_cls, config, light, scene=scene), memory_breakdown=breakdown,
        light_change_ms=light_change_ms)
    summary.rebuilt_note = (
        "" if artifact.original_time_known else
        "precompute rebuilt from a corrupt cache file; precompute_s is the rebuild's time"
        if artifact.rebuilt else
        "precompute reused cached parts whose compute time was never recorded (an older "
        "cache); precompute_s understates the cost from scratch")
    if out_dir is not None or prepared.outputs.json_path is not None:
        json_path = (Path(prepared.outputs.json_path) if prepared.outputs.json_path
                     else out_dir / "summary.json")

        with atomic_path(json_path) as tmp:
            tmp.write_text(strict_json.dumps(summary.to_json(), indent=2))
    return summary


def device_description() -> str:
    """The measuring machine: CPU model and core count (the GPU is in the renderer string)."""

    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as fh:
            cpu = next((l.split(":", 1)[1].strip() for l in fh if l.startswith("model name")), cpu)
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} cores"


def load_average() -> float | None:
    """The 1-minute load average (None where the OS has none), stored with every row so a
    report can say when its timings were taken on a busy machine."""

    try:
        return float(os.getloadavg()[0])
    except (AttributeError, OSError):
        return None


def summary_rows(summary: RunSummary, scene: Scene, *, workers: int = 1,
                 cell_key: str = "") -> list:
    """The result rows (one per view) of a run, without storing them.

    A sweep's workers return these to the client, which alone writes the store.

    Parameters
    ----------
    summary : RunSummary
        What :func:`execute` returned.
    scene : Scene
        The prepared scene of that run (its views and counts go into the rows).
    workers : int
        Workers measuring concurrently (recorded: they distort frame times).
    cell_key : str
        The sweep cell's key, empty outside sweeps.

    Returns
    -------
    list of prtbench.store.results.ResultRow
    """

    rebuilt_note = summary.rebuilt_note

    sha = git_sha()
    stamp = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
    rows = []
    for v in summary.views:
        view = scene.trajectory.views[v.view]
        nulls = strict_json.non_finite_keys(v.metrics)
        reason = "; ".join(r for r in (v.status_reason, f"{', '.join(nulls)} stored as null" if nulls else "",
                                       rebuilt_note) if r)
        rows.append(ResultRow(
            method=summary.method, config=summary.config,
            scene=summary.scene, scene_variant=summary.variant, light=summary.light,
            view=v.view, view_json=asdict(view), width=summary.width,
            height=summary.height, reference_kind=summary.reference,
            metrics=dict(v.metrics), frame_ms=v.frame_ms,
            frame_ms_p95=v.frame_ms_p95, memory_bytes=summary.memory_bytes,
            precompute_s=summary.precompute_s, renderer=summary.renderer,
            device=device_description(), git_sha=sha, profile=summary.profile,
            run_id=summary.run_id, timestamp=stamp, reference_spp=summary.reference_spp,
            reference_noise=summary.reference_noise_display,
            scene_triangles=scene.n_triangles, scene_params=dict(scene.params),
            timing_source=v.timing_source, status=v.status, status_reason=reason,
            precompute_rebuilt=summary.precompute_rebuilt, covered_pixels=v.covered_pixels,
            scene_vertices=scene.n_vertices, workers=workers, cell_key=cell_key,
            load_average=load_average(), reference_bounces=summary.reference_bounces,
            panel=summary.panel, light_class=summary.light_class, split=summary.split,
            psnr_masked_lo=v.psnr_masked_lo, psnr_masked_hi=v.psnr_masked_hi,
            frame_components=dict(v.frame_components),
            memory_breakdown=dict(summary.memory_breakdown),
            light_change_ms=summary.light_change_ms))
    return rows


def format_summary(summary: RunSummary, *, metric_names: Sequence[str] = (
        "psnr_masked", "ssim_masked", "flip_masked", "psnr", "mae")) -> str:
    """A plain text table: one row per view and a mean row."""
    header = ["view", *metric_names, "frame ms"]
    rows = [[str(v.view), *(f"{v.metrics.get(m, float('nan')):.4f}" for m in metric_names),
             f"{v.frame_ms:.3f}"] for v in summary.views]
    mean = summary.mean_metrics()
    rows.append(["mean", *(f"{mean.get(m, float('nan')):.4f}" for m in metric_names),
                 f"{np.mean([v.frame_ms for v in summary.views]):.3f}"])
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header))]
    lines = ["  ".join(c.rjust(w) for c, w in zip(r, widths)) for r in [header, *rows]]
    facts = (f"method={summary.method} scene={summary.scene}/{summary.variant} light={summary.light} "
             f"profile={summary.profile} {summary.width}x{summary.height} reference={summary.reference}"
             f"{f' (spp {summary.reference_spp}, noise {summary.reference_noise_display:.4f})' if summary.reference_spp else ''}\n"
             f"timing={summary.views[0].timing_source if summary.views else '-'} "
             f"memory={summary.memory_bytes / 2**20:.3f} MiB precompute={summary.precompute_s:.1f} s"
             f"{' (cached)' if summary.precompute_cached else ''}"
             f"{' (rebuilt)' if summary.precompute_rebuilt else ''} renderer={summary.renderer}"
             f"{f'{chr(10)}status={summary.status}: {summary.status_reason}' if summary.status != 'ok' else ''}")
    return facts + "\n" + "\n".join(lines)
