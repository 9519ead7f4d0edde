"""Factored BRDFs against the gloss (Ramamoorthi's lecture, slide 41; Wang, Tran and Luebke 2004).

The lecture lists the factored-BRDF approach's problem as "non-optimal factorization, few
terms — can only handle less glossy materials". Here ``factored-brdf`` with J = 1 and J = 4
separable terms renders the glossy sphere over a plane as its Phong exponent s rises, beside
``sloan-matrix`` (the unfactored glossy transfer matrices at the same SH bands): the factored
method's loss against the path reference as the gloss rises, and its difference to the
unfactored transfer at each gloss.
"""

from __future__ import annotations

import numpy as np

from prtbench.bench.job import Job
from prtbench.bench.reproduction import Reproduction
from reproductions.shared import row_config

#: Phong exponents s of the sphere, from broad to sharp lobes.
SHININESS = (8, 32, 128, 512)
#: (label, method, config overrides) of each row.
SETUPS = (
    ("factored J=1", "factored-brdf", {"terms": 1}),
    ("factored J=4", "factored-brdf", {"terms": 4}),
    ("sloan-matrix", "sloan-matrix", {}),
)
#: Scene parameters besides the gloss: a finer sphere and ground than the defaults' ground, so
#: that per-vertex transfer resolves the highlight and the sphere's shadow.
SCENE = {"sphere_segments": 48, "plane_subdivisions": 24}
LIGHT = "sun"


class FactoredGlossTable(Reproduction):
    name = "factored-gloss"
    paper = ("Ramamoorthi, CSE 168 lecture on precomputed rendering, slide 41 (factored BRDFs, "
             "after Wang, Tran and Luebke 2004): factored BRDFs handle only less glossy "
             "materials; the slide states it without a number")
    title = "Factored BRDF (J = 1, 4) and the unfactored SH matrix against the Phong exponent"
    substitutions = (
        "The lecture names no scene: the glossy `sphere-over-plane` (sphere Phong exponent s "
        "swept, ground s = 32) under the `sun`, which puts a sharp highlight on the sphere.",
    )
    notes = (
        "The lecture has no numbers, so there is no paper column.",
        "Masked PSNR and FLIP of each method against the path reference of the same gloss (one "
        "bounce), mean over the profile's views; the interval of the PSNR is the reference "
        "noise and the spread over views.",
        "`factored − matrix` is the factored configuration's PSNR minus sloan-matrix's at the "
        "same gloss and SH bands: positive where the factored form is closer to the reference "
        "(the matrix also truncates the lobe to the SH bands, which the factored form's "
        "tabulated outgoing factors do not), negative where the factorization costs more.",
    )

    def cells(self, profile: str) -> list[Job]:
        return [Job(method=method, scene="sphere-over-plane", variant="glossy", light=LIGHT,
                    scene_params={**SCENE, "sphere_shininess": float(s)}, overrides=overrides,
                    reference_bounces=1, label={"setup": label, "shininess": s})
                for s in SHININESS for label, method, overrides in SETUPS]

    def format(self, frame, *, profile: str):
        header = ["sphere shininess s", "setup", "PSNR masked (dB)", "PSNR 95 % interval",
                  "FLIP masked", "factored − matrix (dB)", "SH bands", "memory MiB", "views"]
        rows = []
        for s in SHININESS:
            at = frame[frame["label_shininess"] == s]
            matrix = at[at["label_setup"] == "sloan-matrix"]
            for label, _, _ in SETUPS:
                part = at[at["label_setup"] == label]
                if not len(part):
                    continue
                psnr = float(np.mean(part["metric_psnr_masked"]))
                lo = float(np.mean(part["psnr_masked_lo"])) if "psnr_masked_lo" in part else psnr
                hi = float(np.mean(part["psnr_masked_hi"])) if "psnr_masked_hi" in part else psnr
                loss = (psnr - float(np.mean(matrix["metric_psnr_masked"]))
                        if len(matrix) and label != "sloan-matrix" else "")
                config = row_config(part)
                rows.append([s, label, psnr, f"{lo:.2f}–{hi:.2f}",
                             float(np.mean(part["metric_flip_masked"])), loss,
                             int(config.get("sh_bands", 0)),
                             float(part["memory_bytes"].iloc[0]) / 2**20, int(len(part))])
        return header, rows


TABLE = FactoredGlossTable()
