"""Belcour et al. 2022, Table 1: per-frame cost of data-driven PRT with 4, 16 and 64 basis elements.

For each scene the method's spot-light dataset is baked once (the basis count does not change
the dataset), then for n = 4, 16, 64 one renderer times its passes *interleaved in one session*
(:meth:`DataDrivenRenderer.pass_times`): the "no GI" shader (direct light only), the final
shader with the basis blend, the fake G-buffer pass, the matrix transfer, the shadow maps (common
to both shaders) and the whole frame, under a held-out spot light from view 0. Every cost is
reported as a ratio to the no-GI shader of the same session. Bake time is the dataset's wall
time (GL direct vectors + embree indirect lightmaps); storage is the resident basis textures and
transfer matrix.

The generic runner cannot time passes separately nor light with spot lights, so this table
measures with its own harness: :meth:`DdprtTable1.measure` runs it and writes one results-store
row per (scene, n) (``metrics`` hold the pass times), and :meth:`DdprtTable1.format` builds the
table from those stored rows.
"""

from __future__ import annotations

import json
import uuid
from dataclasses import asdict

from methods.data_driven.evaluation import held_out, with_knobs
from methods.data_driven.method import DataDrivenPRT
from prtbench.api.config import to_dict
from prtbench.api.errors import AssetMissingError
from prtbench.api.method import load_or_precompute
from prtbench.api.profiles import get_profile
from prtbench.bench.reproduction import Reproduction
from prtbench.bench.runner import device_description, load_average
from prtbench.scene.registry import get_scene
from prtbench.store.results import ResultRow, ResultsStore, git_sha

BASIS_COUNTS = (4, 16, 64)
#: Interleaved samples per pass at least (wall-clock timings on a shared CPU are noisy).
MIN_FRAMES = 25

#: (label, scene, builder params per profile, paper column).
SCENES = (
    ("CORNELL", "cornell", {}, "CORNELL"),
    ("VIKING → room", "room", {}, "VIKING"),
    ("DRAGON", "dragon", {"smoke": "dragon-lo", "quick": "dragon-lo", "paper": "dragon"}, "DRAGON"),
)

#: Paper's Table 1 (RTX 2080, Unity HDRP), microseconds; bake time in minutes.
PAPER = {
    "CORNELL": {"no_gi": 221, 4: 325, 16: 428, 64: 892, "gbuffer": 36, "transfer": 15, "bake_min": 6.48},
    "VIKING": {"no_gi": 232, 4: 348, 16: 483, 64: 1068, "gbuffer": 34, "transfer": 15, "bake_min": 6.89},
    "DRAGON": {"no_gi": 418, 4: 490, 16: 658, 64: 1358, "gbuffer": 32, "transfer": 15, "bake_min": 13.37},
}

#: Method overrides per profile (spot-light datasets; the paper bakes 128 configurations).
OVERRIDES = {
    "smoke": {"configurations": 4, "paths_per_texel": 4, "lightmap_resolution": 256},
    "quick": {"configurations": 16, "paths_per_texel": 16, "lightmap_resolution": 256},
    "paper": {"configurations": 128, "paths_per_texel": 64, "lightmap_resolution": 512},
}


class DdprtTable1(Reproduction):
    name = "ddprt-1"
    paper = ("Belcour, Deliot, Barbier, Soler: A Data-Driven Paradigm for Precomputed Radiance "
             "Transfer (SIGGRAPH 2022), Table 1 (per-frame costs on an RTX 2080 in Unity HDRP)")
    title = "Data-driven PRT: per-frame costs with 4, 16 and 64 basis elements"
    substitutions = (
        "`cornell`: our procedural Cornell box (ceiling skylight, open front) for the paper's "
        "CORNELL.",
        "`room`: our procedural room (table, chairs, rug, about 20k triangles) for the VIKING room.",
        "`dragon-lo` (Stanford dragon, 46k triangles) in the smoke and quick profiles and the full "
        "`dragon` (871k triangles) in the paper profile, diffuse, for the paper's scanned DRAGON "
        "(which the paper renders with subsurface scattering). HAIRBALL is not reproduced.",
    )
    notes = (
        "Lights: the dataset is the `spot` family (random spot lights aimed at measurement points "
        "they see, or around the view target); timings use one held-out spot light.",
        "'No GI' is the same deferred direct-light shader without the basis blend, timed in the "
        "same session; ratios divide by it. 'Ours (n basis)' is the final shader with the blend "
        "(the paper's rows), 'whole frame' adds shadow maps, fake G-buffer and transfer.",
        "Timings are medians of interleaved single-frame samples. On llvmpipe (a CPU rasteriser; "
        "timing source wall+finish) only the ratios within one session mean anything.",
        "Bake time: the dataset (GL direct vectors + embree path-traced indirect lightmaps) on "
        "the CPU; the paper bakes 128 configurations with Unity's GPU path tracer.",
        "Paper numbers are microseconds and minutes as printed; their ratios are computed from them.",
    )

    def __init__(self) -> None:
        self._run_id: str | None = None

    # -- measurement ---------------------------------------------------------------------------

    def measure(self, profile: str, *, results_path=None) -> list[str]:
        """Time every (scene, n) and append the rows to the results store; returns the run id."""

        prof = get_profile(profile)
        run_id = f"ddprt1-{uuid.uuid4().hex[:8]}"
        sha, device = git_sha(), device_description()
        rows = []
        for label, name, params, column in SCENES:
            scene_name = params.get(profile, name) if params else name
            try:
                scene = get_scene(scene_name).with_views(1)
            except AssetMissingError as exc:
                rows.append(ResultRow(method="data-driven", scene=scene_name, profile=profile,
                                      run_id=run_id, metrics={"missing": 1.0},
                                      scene_params={"missing": str(exc), "column": column}))
                continue
            base = DataDrivenPRT.make_config({**OVERRIDES[profile], "light_family": "spot"},
                                             profile=profile)
            DataDrivenPRT.validate(scene, base)
            light = held_out(scene, base, 1)[0]
            view = scene.trajectory.views[0]
            for n in BASIS_COUNTS:
                config = with_knobs(base, basis=n)
                artifact = load_or_precompute(DataDrivenPRT, scene, config, progress=False)
                renderer = DataDrivenPRT.renderer(scene, artifact, config, width=prof.width,
                                                  height=prof.height)
                try:
                    times = renderer.pass_times(view, light, warmup=prof.timing_warmup,
                                                frames=max(prof.timing_frames, MIN_FRAMES))
                    storage = renderer.storage()
                    memory = renderer.memory_bytes()
                    renderer_string = renderer.renderer_string
                finally:
                    renderer.release()
                metrics = {f"ms_{k}": v.median_ms for k, v in times.items()}
                metrics.update({"bake_s": float(artifact.meta["bake_seconds"]),
                                **{f"bytes_{k}": float(v) for k, v in storage.items()}})
                rows.append(ResultRow(
                    method="data-driven", scene=scene.name, config=to_dict(config),
                    scene_variant=scene.variant, light=light.name, view=0,
                    view_json=asdict(view), width=prof.width, height=prof.height,
                    reference_kind="path", metrics=metrics, frame_ms=times["frame"].median_ms,
                    frame_ms_p95=times["frame"].p95_ms, memory_bytes=memory,
                    precompute_s=float(artifact.meta["bake_seconds"]), renderer=renderer_string,
                    device=device, git_sha=sha, profile=profile, run_id=run_id,
                    load_average=load_average(),
                    scene_triangles=scene.n_triangles,
                    scene_params={"column": column, "label": label, "substitution": scene.substitution},
                    timing_source=times["frame"].source))
        ResultsStore(results_path).append(rows)
        self._run_id = run_id
        return [run_id]

    # -- report --------------------------------------------------------------------------------

    def format(self, frame, *, profile: str):
        columns = []  # (paper column, our rows by n or None)
        for label, name, params, column in SCENES:
            part = frame[[json.loads(p).get("column") == column if isinstance(p, str) else
                          p.get("column") == column for p in frame["scene_params"]]] \
                if len(frame) else frame
            columns.append((label, column, part))
        header = ["quantity"]
        for label, column, part in columns:
            scene = part["scene"].iloc[0] if len(part) else "—"
            header += [f"{label} ({scene}) ours ms", "ours ×no-GI", f"{column} paper µs",
                       "paper ×no-GI"]
        quantities = [("No GI shader", "no_gi", "no_gi"),
                      *[(f"Ours ({n} basis) shader", ("shading", n), n) for n in BASIS_COUNTS],
                      ("Fake G-buffer (n=16)", ("gbuffer", 16), "gbuffer"),
                      ("Matrix transfer (n=16)", ("transfer", 16), "transfer"),
                      ("Matrix transfer (n=64)", ("transfer", 64), None),
                      ("Shadow maps (n=16)", ("shadows", 16), None),
                      ("Whole frame (n=16)", ("frame", 16), None)]
        rows = []
        for title, key, paper_key in quantities:
            row = [title]
            for label, column, part in columns:
                ours, ratio = self._ours(part, key)
                paper = PAPER[column].get(paper_key) if paper_key is not None else None
                paper_ratio = paper / PAPER[column]["no_gi"] if paper is not None else None
                row += [ours, ratio, paper if paper is not None else "—",
                        paper_ratio if paper_ratio is not None else "—"]
            rows.append(row)
        bake = ["Bake time (s / paper min)"]
        storage = ["Basis textures n=16 (MiB) / transfer matrix (KiB)"]
        for label, column, part in columns:
            ok = part[part["metrics"].map(lambda m: "missing" not in json.loads(m))] if len(part) else part
            if len(ok):
                bake += [float(ok["metric_bake_s"].iloc[0]), "—", PAPER[column]["bake_min"], "—"]
                n16 = ok[ok["config"].map(lambda c: json.loads(c).get("basis") == 16)]
                storage += [f"{float(n16['metric_bytes_basis'].iloc[0]) / 2**20:.3g} / "
                            f"{float(n16['metric_bytes_transfer_matrix'].iloc[0]) / 2**10:.3g}",
                            "—", "64 MiB / 36 KiB (1024², 256 points)", "—"]
            else:
                bake += ["asset missing", "—", PAPER[column]["bake_min"], "—"]
                storage += ["—", "—", "—", "—"]
        rows += [bake, storage]
        return header, rows

    @staticmethod
    def _ours(part, key):
        if not len(part) or "metric_ms_no_gi" not in part:
            return "asset missing", "—"
        if key == "no_gi":
            sel = part[part["config"].map(lambda c: json.loads(c).get("basis") == 16)]
            return float(sel["metric_ms_no_gi"].iloc[0]), 1.0
        what, n = key
        sel = part[part["config"].map(lambda c: json.loads(c).get("basis") == n)]
        if not len(sel):
            return "—", "—"
        ms = float(sel[f"metric_ms_{what}"].iloc[0])
        return ms, ms / float(sel["metric_ms_no_gi"].iloc[0])

    def markdown(self, header, rows, *, profile: str, frame) -> str:
        text = super().markdown(header, rows, profile=profile, frame=frame)
        sources = sorted(set(frame["timing_source"])) if len(frame) else []
        res = sorted({f"{w}x{h}" for w, h in zip(frame["width"], frame["height"])}) if len(frame) else []
        extra = (f"\nTiming source: {', '.join(sources) or 'n/a'}; resolution {', '.join(res) or 'n/a'}; "
                 f"results-store run id `{self._run_id}`.\n")
        return text + extra


TABLE = DdprtTable1()
