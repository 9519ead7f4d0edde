"""Thesis table 4.4: GLSL vs CUDA (here: torch) frame rate of the learnt transfer, k = 64 … 512.

Sweep: ``learnt`` on PLANTS (glossy) with l = 4 and k ∈ {64, 128, 256, 512}, rendered by the
GLSL path (weights hard-coded in the fragment shader) and by the torch path (GL G-buffer ->
torch on covered pixels; CUDA on a GPU machine, CPU otherwise). Networks the GLSL path refuses
(more hard-coded constants than ``glsl_weight_limit``) are not run and show N/A with the reason,
as the thesis's GLSL column does for k ≥ 256.
"""

from __future__ import annotations

import numpy as np

from methods.learnt.glsl import hardcoded_floats
from methods.learnt.method import LearntTransfer
from methods.learnt.model import spec_of
from prtbench.bench.job import Job
from prtbench.bench.reproduction import Reproduction
from reproductions.table_4_1 import baseline_bands, ensure_methods

WIDTHS = (64, 128, 256, 512)
RENDERERS = ("glsl", "torch")
SCENE, VARIANT = "plants", "glossy"
#: Thesis table 4.4 (FPS, RTX 3090, plants glossy, l = 4): GLSL and CUDA; None = N/A.
PAPER = {"glsl": (64.4, 12.2, None, None), "torch": (55.1, 29.1, 20.7, 8.0)}
#: Epochs of the k >= 256 networks outside the paper profile: frame time does not depend on
#: the weight values, and training them fully on 2 CPU cores would take hours.
WIDE_EPOCHS_QUICK = 8


def overrides(k: int, renderer: str, profile: str) -> dict:
    """Learnt config of a cell (the k = 64/128 networks are table 4.1's, reused from cache)."""
    values = {"hidden": k, "layers": 4, "sh_bands": baseline_bands(profile), "renderer": renderer}
    if k >= 256 and profile != "paper":
        values["epochs"] = WIDE_EPOCHS_QUICK
    return values


def glsl_refusal(k: int, profile: str) -> str | None:
    """Why the GLSL path refuses width ``k`` (None when it renders it)."""

    config = LearntTransfer.make_config(overrides(k, "glsl", profile), profile=profile)
    count = hardcoded_floats(spec_of(config), 1)
    if count > config.glsl_weight_limit:
        return f"N/A: {count:,} constants > glsl_weight_limit {config.glsl_weight_limit:,}"
    return None


class Table44(Reproduction):
    name = "4.4"
    paper = ("Sirikonda (2023) thesis, table 4.4: FPS of the GLSL and CUDA implementations for "
             "k = 64, 128, 256, 512 (l = 4) on PLANTS, glossy")
    title = "Table 4.4: GLSL vs torch (thesis: CUDA) implementation of the learnt transfer"
    substitutions = ("PLANTS: our procedural potted plants (`plants`), glossy variant.",)
    notes = (
        "FPS = 1000 / median frame time over the views. GLSL: GL wall+finish on Mesa llvmpipe "
        "(a CPU rasteriser) or GL timer queries on a GPU; torch: host wall clock around whole "
        "frames (G-buffer pass, GL -> host -> device transfers, network, shading, result back "
        "into a GL texture), synchronised. Without a GPU both run on the same CPU cores and are "
        "meaningful only as ratios within this table; the paper's numbers are an RTX 3090 with "
        "CUDA-GL interop (no host copies).",
        "The GLSL limit: the path refuses networks with more hard-coded constants than "
        "`glsl_weight_limit` (65,536 by default, i.e. k <= 128 at l = 4), with a message "
        "suggesting `renderer=torch`. Measured behind it (methods/learnt/glsl.py): compile + "
        "JIT time on llvmpipe grows from seconds (k = 64) to minutes (k = 128); the thesis's "
        "k >= 256 failed to render in GLSL on an RTX 3090.",
        f"Outside the `paper` profile, the k >= 256 networks train for {WIDE_EPOCHS_QUICK} "
        "epochs only (frame time does not depend on weight values); k = 64/128 are table 4.1's "
        "networks.",
    )

    def cells(self, profile: str) -> list[Job]:
        ensure_methods()
        cells = []
        for renderer in RENDERERS:
            for k in WIDTHS:
                if renderer == "glsl" and glsl_refusal(k, profile):
                    continue
                cells.append(Job(method="learnt", scene=SCENE, variant=VARIANT,
                                  overrides=overrides(k, renderer, profile), reference="path",
                                  label={"renderer": renderer, "k": k}))
        return cells

    def format(self, frame, *, profile: str):
        header = ["implementation", *(f"k={k} FPS" for k in WIDTHS),
                  *(f"k={k} frame ms" for k in WIDTHS), "device"]
        rows = []
        for renderer in RENDERERS:
            part = frame[frame["label_renderer"] == renderer]
            fps, ms = [], []
            for k in WIDTHS:
                cell = part[part["label_k"] == k]
                refusal = glsl_refusal(k, profile) if renderer == "glsl" else None
                if len(cell):
                    median = float(np.median(cell["frame_ms"]))
                    fps.append(1000.0 / median)
                    ms.append(median)
                else:
                    fps.append(refusal or "not run")
                    ms.append("—")
            devices = sorted(set(part["renderer"])) if len(part) else ["—"]
            label = "GLSL (ours)" if renderer == "glsl" else "torch (ours)"
            rows.append([label, *fps, *ms, "; ".join(devices)])
        for renderer, label in (("glsl", "GLSL (paper)"), ("torch", "CUDA (paper)")):
            rows.append([label, *(v if v is not None else "N/A" for v in PAPER[renderer]),
                         *(["—"] * len(WIDTHS)), "RTX 3090, 1024x1024"])
        return header, rows


TABLE = Table44()
