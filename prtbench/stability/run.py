"""Run stability cases through the ordinary runner, one process per case, with a timeout.

Each case runs in a fresh (spawned) process: a crash or a hang of one case is measured as
``failed`` and cannot take the matrix down, and the process's peak resident memory is the
case's own. Inside, the case is an ordinary :func:`prtbench.bench.runner.prepare` /
:func:`prtbench.bench.runner.execute` job (path reference, results rows in the store, images under
the output folder), on the case's scene (:func:`prtbench.stability.scenes.case_scene`) and
light; then the artifact (a cache hit) and the image are inspected for non-finite values,
their peak magnitude against the storage type's range, and the image is compared with the
moderate case's render where the case renders the same picture.
"""

from __future__ import annotations

import dataclasses
import math
import resource
import time
import traceback
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from prtbench.api.errors import PrtbenchError
from prtbench.api.method import load_or_precompute
from prtbench.bench import metrics
from prtbench.bench.executors import Lost, SubprocessExecutor
from prtbench.bench.job import Job, Outputs
from prtbench.bench.runner import execute, prepare, summary_rows
from prtbench.io import imageio
from prtbench.render.reference import render_reference
from prtbench.stability.case import Case
from prtbench.stability.lights import LIGHTS
from prtbench.stability.scenes import case_scene
from prtbench.transport.raytrace import geometry_mask

#: Seconds a case may run before it counts as a hang (``failed``), per profile.
TIMEOUTS = {"smoke": 300.0, "quick": 1200.0}
#: Storage knobs whose value names the dtype the renderer keeps the artifact in.
STORAGE_KNOBS = ("storage", "precision")
#: A display value below half an 8-bit step prints as black (as prtbench.bench.degeneracy).
BLACK_DISPLAY = 0.5 / 255.0


def _storage_dtype(config: Any, arrays: Mapping[str, np.ndarray]) -> np.dtype:
    """The float type the method stores its artifact in: a storage knob's, else the widest."""
    for knob in STORAGE_KNOBS:
        value = getattr(config, knob, None)
        if value in ("float16", "float32", "float64"):
            return np.dtype(value)
    floats = [a.dtype for a in arrays.values() if np.issubdtype(a.dtype, np.floating)]
    return max(floats, key=lambda d: d.itemsize) if floats else np.dtype(np.float32)


def artifact_stats(arrays: Mapping[str, np.ndarray], dtype: np.dtype) -> dict[str, Any]:
    """Non-finite count, peak |value| and overflow/underflow counts of ``arrays`` in ``dtype``.

    Parameters
    ----------
    arrays : mapping of str to ndarray
        The artifact's arrays (non-float arrays are skipped).
    dtype : numpy dtype
        The storage type: ``overflow`` counts finite values above its maximum, ``underflow``
        non-zero values below its smallest normal number (stored subnormal or as 0).

    Returns
    -------
    dict
        ``artifact_nonfinite``, ``artifact_peak``, ``storage_dtype``, ``storage_max``,
        ``overflow``, ``underflow``, ``artifact_values``.
    """
    info = np.finfo(dtype)
    nonfinite = overflow = underflow = values = 0
    peak = 0.0
    for array in arrays.values():
        if not np.issubdtype(array.dtype, np.floating) or array.size == 0:
            continue
        a = np.abs(np.asarray(array, dtype=np.float64))
        finite = np.isfinite(a)
        nonfinite += int(a.size - np.count_nonzero(finite))
        values += int(a.size)
        a = a[finite]
        if a.size:
            peak = max(peak, float(a.max()))
            overflow += int(np.count_nonzero(a > float(info.max)))
            underflow += int(np.count_nonzero((a > 0) & (a < float(info.tiny))))
    return {"artifact_nonfinite": nonfinite, "artifact_peak": peak, "storage_dtype": str(dtype),
            "storage_max": float(info.max), "overflow": overflow, "underflow": underflow,
            "artifact_values": values}


def case_job(method: str, case: Case, *, profile: str, base: Mapping[str, Any]) -> Job:
    """The job of ``case``: the method's moderate setting on the base scene, with the case's
    overrides, light, material variant and scene parameters (one view)."""
    light = LIGHTS[case.light].build() if case.light else base["light"]
    variant = "glossy" if case.shininess is not None else base["variant"]
    params = (dict(case.scene_params) if case.scene else
              {**base.get("scene_params", {}), **case.scene_params})
    return Job(method=method, scene=case.scene or base["scene"], label={"case": case.name},
               variant=variant, light=light, views=1, profile=profile,
               overrides={**base.get("overrides", {}), **case.overrides}, scene_params=params)


def _inspect(prepared, summary, case: Case, moderate_exr: str | None) -> dict[str, Any]:
    """Artifact and image facts of a finished run (the artifact is a cache hit)."""

    scene, config = prepared.scene, prepared.config
    artifact = load_or_precompute(prepared.method_cls, scene, config, progress=False)
    out = artifact_stats(artifact.arrays, _storage_dtype(config, artifact.arrays))
    out["artifact_bytes"] = artifact.nbytes
    view = summary.views[0]
    image = imageio.read_exr(view.files["exr"])
    finite = np.isfinite(image)
    out["image_nonfinite"] = int(image.size - np.count_nonzero(finite))
    out["image_peak"] = float(np.abs(image[finite]).max()) if finite.any() else math.nan
    test_d = imageio.display(np.where(finite, image, 0.0), exposure=scene.exposure)
    out["image_black"] = bool(test_d.max() < BLACK_DISPLAY)
    ref = render_reference(scene, prepared.light, scene.trajectory.views[0],
                           width=prepared.width, height=prepared.height,
                           spp=prepared.profile.reference_spp,
                           bounces=int(getattr(config, "bounces", 0)))
    ref_d = imageio.display(ref.image, exposure=scene.exposure)
    out["reference_black"] = bool(ref_d.max() < BLACK_DISPLAY)
    out["reference_peak"] = float(np.abs(ref.image).max())
    out["covered_pixels"] = view.covered_pixels
    if case.compare_image and moderate_exr and out["image_nonfinite"] == 0:
        moderate = imageio.read_exr(moderate_exr)
        if moderate.shape == image.shape and np.isfinite(moderate).all():
            mask = geometry_mask(scene, scene.trajectory.views[0], prepared.width,
                                 prepared.height)
            vs = metrics.compute_metrics(test_d, imageio.display(moderate, exposure=scene.exposure),
                                         mask=mask, names=("psnr", "flip"))
            out["psnr_vs_moderate"] = vs.get("psnr_masked")
            out["flip_vs_moderate"] = vs.get("flip_masked")
    return out


def derive_overrides(prepared, scene, derived: Mapping[str, str]) -> dict[str, int]:
    """The values of a case's derived knobs (:attr:`Case.derived`) on ``scene``.

    ``"signals"`` is the scene's vertex count; ``"dimension"`` the values per vertex of the
    method's uncompressed artifact at the case's config without the derived knobs (the
    moderate case's artifact: a cache hit once it ran), i.e. the d of its CPCA signals, or
    what the method's ``compress_dimension(config)`` declares where its artifact is not a
    dense per-vertex array (sparse Haar rows).
    """

    out = {}
    for knob, what in derived.items():
        if what == "signals":
            out[knob] = int(scene.n_vertices)
        elif what == "dimension":
            config = dataclasses.replace(prepared.config, compress="none", clusters=None,
                                         pca_vectors=None)
            declared = prepared.method_cls.compress_dimension(config)
            if declared is not None:  # signals that are not an artifact array (sparse rows)
                out[knob] = int(declared)
                continue
            arrays = load_or_precompute(prepared.method_cls, scene, config,
                                        progress=False).arrays
            n = int(scene.n_vertices)
            per_vertex = [a for a in arrays.values()
                          if np.issubdtype(a.dtype, np.floating) and a.ndim >= 1 and len(a) == n]
            out[knob] = int(max(per_vertex, key=lambda a: a.size).size // n)
        else:
            raise ValueError(f"derived knob value '{what}'")  # a catalogue bug, not user input
    return out


def measure_case(method: str, case: Case, *, profile: str, base: Mapping[str, Any],
                 results_path: Path | None, out_dir: Path,
                 moderate_exr: str | None = None) -> dict[str, Any]:
    """Run one case in this process; every number the report prints.

    Returns
    -------
    dict
        ``error_kind`` (``""``, ``refused`` or ``exception``) and ``error``; for a run that
        finished, the run id, masked PSNR/FLIP/SSIM against the reference, frame ms, memory,
        precompute time, status, and the facts of :func:`_inspect`; always ``wall_s`` and
        ``peak_rss_bytes``.
    """

    start = time.perf_counter()
    out: dict[str, Any] = {"error_kind": "", "error": ""}
    try:
        outputs = Outputs(out_dir=out_dir)
        if case.derived:  # resolved on the case's scene, then run as fixed overrides
            first = prepare(case_job(method, dataclasses.replace(case, derived={}),
                                     profile=profile, base=base), outputs=outputs, store=False)
            derived = derive_overrides(first, case_scene(first.scene, case), case.derived)
            out["derived_overrides"] = derived
            case = dataclasses.replace(case, overrides={**case.overrides, **derived}, derived={})
        prepared = prepare(case_job(method, case, profile=profile, base=base), outputs=outputs,
                           store=False)
        scene = case_scene(prepared.scene, case)
        prepared.method_cls.validate(scene, prepared.config)
        prepared = dataclasses.replace(prepared, scene=scene)
        summary = execute(prepared, progress=False, echo=False)
        # The rows go back to the process that runs the matrix, which alone writes the store.
        out["rows"] = summary_rows(summary, scene)
        view = summary.views[0]
        out.update(run_id=summary.run_id, status=summary.status,
                   status_reason=summary.status_reason, frame_ms=view.frame_ms,
                   memory_bytes=summary.memory_bytes, precompute_s=summary.precompute_s,
                   renderer=summary.renderer,
                   precompute_cached=summary.precompute_cached,
                   reference_noise=summary.reference_noise_display,
                   **{k: view.metrics.get(k) for k in ("psnr_masked", "flip_masked",
                                                       "ssim_masked", "psnr")})
        out.update(_inspect(prepared, summary, case, moderate_exr))
        if "psnr_masked" in out and view.status == "ok":
            out["image_exr"] = view.files.get("exr", "")
    except PrtbenchError as exc:
        out.update(error_kind="refused", error=str(exc))
    except Exception as exc:  # noqa: BLE001 - any other exception is the bug being measured
        frames = traceback.extract_tb(exc.__traceback__)
        where = f" at {Path(frames[-1].filename).name}:{frames[-1].lineno}" if frames else ""
        out.update(error_kind="exception", error=f"{type(exc).__name__}: {exc}{where}")
    out["wall_s"] = time.perf_counter() - start
    out["peak_rss_bytes"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    return out


def _measure_case_json(item: tuple[str, dict, dict]) -> dict[str, Any]:
    """:func:`measure_case` of ``(method, case as JSON, keyword arguments)`` (picklable)."""
    method, case_json, kwargs = item
    return measure_case(method, Case.from_json(case_json), **kwargs)


def run_case(method: str, case: Case, *, profile: str, base: Mapping[str, Any],
             results_path: Path | None, out_dir: Path, moderate_exr: str | None = None,
             timeout_s: float | None = None) -> dict[str, Any]:
    """:func:`measure_case` in a fresh spawned process, killed after ``timeout_s``
    (:class:`prtbench.bench.executors.SubprocessExecutor`).

    A process that dies without an answer is ``error_kind="crash"`` (with its exit code); one
    still running after the timeout is killed and ``error_kind="timeout"``.
    """
    timeout_s = (TIMEOUTS[profile] if timeout_s is None else float(timeout_s)) * case.timeout_factor
    kwargs = {"profile": profile, "base": dict(base), "results_path": results_path,
              "out_dir": out_dir, "moderate_exr": moderate_exr}
    result = SubprocessExecutor.run_one(_measure_case_json, (method, case.to_json(), kwargs),
                                        timeout_s=timeout_s)
    if isinstance(result, Lost):
        return {"error_kind": result.kind, "error": result.error, "wall_s": result.seconds}
    return result
