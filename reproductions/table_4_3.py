"""Thesis table 4.3: FPS on the STANFORD-BUNNY neural SDF, neural-SDF size x transfer-MLP size.

Sweep: ``learnt-sdf`` (GLSL path) on ``sdf-bunny-neural`` with the neural SDF in its two sizes
(small: k = 32, l = 2; large: k = 64, l = 2, the thesis's rows) and the transfer MLP at
k ∈ {64, 128}, l = 4 (its columns), diffuse and glossy. Per pixel the shader sphere-traces the
neural SDF (a network evaluation per step) and then evaluates the transfer network once, so the
frame time is the product of both sizes. Needs the CGAL bunny (``prtbench assets fetch
cgal-meshes``).

Entry point: ``"4.3" = "reproductions.table_4_3:TABLE"``.
"""

from __future__ import annotations

from prtbench.bench.job import Job
from prtbench.bench.reproduction import Reproduction
from reproductions.table_4_2 import (
    MC_RESOLUTION,
    TIMING_NOTE,
    TRAINING_NOTE,
    VARIANTS,
    VIEWS,
    WIDTHS,
    ensure_method,
    fps,
    learnt_sdf_overrides,
    mean,
    ratio,
    select,
)

SCENE = "sdf-bunny-neural"
SIZES = ("small", "large")
SIZE_LABELS = {"small": "neural SDF k=32, l=2", "large": "neural SDF k=64, l=2"}

#: The thesis's table 4.3 (RTX 3090, 1024x1024, GLSL), copied from its text:
#: (neural-SDF size, transfer k, variant) -> FPS.
PAPER_FPS = {
    ("small", 64, "diffuse"): 320.0, ("small", 64, "glossy"): 200.0,
    ("small", 128, "diffuse"): 77.0, ("small", 128, "glossy"): 20.1,
    ("large", 64, "diffuse"): 50.0, ("large", 64, "glossy"): 25.0,
    ("large", 128, "diffuse"): 26.5, ("large", 128, "glossy"): 15.2,
}


class Table43(Reproduction):
    name = "4.3"
    paper = ("Sirikonda (2023) thesis, table 4.3: FPS on the STANFORD-BUNNY neural SDF for two "
             "neural-SDF sizes (rows) and two transfer-MLP sizes k = 64 / 128, l = 4 (columns)")
    title = "Table 4.3: learnt transfer on a neural SDF (FPS, plus accuracy vs path)"
    substitutions = (
        "STANFORD-BUNNY neural SDF of Davies et al. 2021 (not available here) replaced by our own "
        "sine MLP of the same two sizes (k = 32 / 64, l = 2) fitted to the CGAL bunny "
        "(`sdf-bunny-neural`, prtbench.transport.neural_sdf), on a ground plane that is part of the SDF.",
    )

    @property
    def notes(self):
        return (
            TIMING_NOTE,
            "PSNR masked (dB): against the Mitsuba 3 direct-only path reference of the neural "
            "SDF's marching-cubes mesh, masked to geometry pixels; the thesis reports FPS only.",
            "The 'neural SDF ratio large/small' column (on the large rows) divides the FPS with "
            "the large neural SDF by the small one's at transfer k = 64 and the same material "
            "(the paper column: the same from its numbers).",
            f"Views per cell: {VIEWS['quick']} in `quick` (320x240), the profile's 30 in "
            "`paper` (1920x1080).",
            TRAINING_NOTE,
        )

    def cells(self, profile: str) -> list[Job]:
        ensure_method()
        return [Job(method="learnt-sdf", scene=SCENE, variant=variant,
                     overrides=learnt_sdf_overrides(k), views=VIEWS.get(profile),
                     scene_params={"size": size, "mc_resolution": MC_RESOLUTION.get(profile, 256)},
                     label={"size": size, "variant": variant, "k": k})
                for size in SIZES for variant in VARIANTS for k in WIDTHS]

    def format(self, frame, *, profile: str):
        header = ["surface", "material", "FPS k=64", "FPS k=128", "FPS ratio k=128/k=64",
                  "neural SDF ratio large/small k=64", "PSNR masked k=64 (dB)",
                  "PSNR masked k=128 (dB)", "paper FPS k=64", "paper FPS k=128",
                  "paper FPS ratio k=128/k=64", "paper neural SDF ratio large/small k=64",
                  "views"]
        ours = {(size, variant, k): fps(select(frame, size=size, variant=variant, k=k))
                for size in SIZES for variant in VARIANTS for k in WIDTHS}
        rows = []
        for size in SIZES:
            for variant in VARIANTS:
                parts = {k: select(frame, size=size, variant=variant, k=k) for k in WIDTHS}
                theirs = {k: PAPER_FPS[(size, k, variant)] for k in WIDTHS}
                rows.append([
                    SIZE_LABELS[size], variant, ours[(size, variant, 64)],
                    ours[(size, variant, 128)],
                    ratio(ours[(size, variant, 128)], ours[(size, variant, 64)]),
                    ratio(ours[("large", variant, 64)], ours[("small", variant, 64)])
                    if size == "large" else float("nan"),
                    mean(parts[64], "metric_psnr_masked"), mean(parts[128], "metric_psnr_masked"),
                    theirs[64], theirs[128], ratio(theirs[128], theirs[64]),
                    ratio(PAPER_FPS[("large", 64, variant)], PAPER_FPS[("small", 64, variant)])
                    if size == "large" else float("nan"),
                    int(max(len(parts[k]) for k in WIDTHS))])
        return header, rows


TABLE = Table43()
