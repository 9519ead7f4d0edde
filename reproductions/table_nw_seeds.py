"""Neural wavelet PRT: how much of an ablation's spread is the training seed?

Not a table of the paper. table-nw-3 and table-nw-4 train one model per value of their knob,
so a difference between two rows mixes the knob's effect with the run-to-run variance of the
whole pipeline. This table measures that variance: the profile's own config trained with
several values of ``seed``, which draws the training views, the light per view, the Mitsuba
sample seeds of the training images, the network initialisation and the batches. Evaluation is
that of table-nw-3 (far views, held-out lights, fixed reference and direct seeds), so the rows
differ only by the seed. The seed equal to the profile's default is table-nw-1's model.

Below the table: mean and sample standard deviation of each metric over the seeds, and the
range (largest − smallest) of indirect PSNR, the number to compare an ablation's spread with.

Entry point: ``"nw-seeds" = "reproductions.table_nw_seeds:TABLE"``.
"""

from __future__ import annotations

import math

import numpy as np

from reproductions import table_nw_common as nw

VALUES = {"smoke": (0, 1), "quick": (0, 1, 2), "paper": (0, 1, 2)}


def seed_spread(rows, header) -> dict[str, tuple[float, float]]:
    """Metric column -> (mean, sample std) over the seed rows (NaN std for one row)."""
    out = {}
    for column in header:
        if column.split()[0].lower() not in nw.ABLATION_METRICS:  # ablation_rows' metric columns
            continue
        values = np.array([float(r[header.index(column)]) for r in rows], np.float64)
        values = values[np.isfinite(values)]
        std = float(np.std(values, ddof=1)) if len(values) > 1 else math.nan
        out[column] = (float(np.mean(values)) if len(values) else math.nan, std)
    return out


class TableNwSeeds(nw.AblationTable):
    knob, values, tag = "seed", VALUES, "nwseed"
    name = "nw-seeds"
    paper = ("our own control for Raghavan, Wang, Ramamoorthi et al. 2023 (Neural "
             "Free-Viewpoint Relighting for Glossy Indirect Illumination), Tables 3 and 4: "
             "the paper reports no seed variance")
    title = "Neural wavelet PRT: run-to-run variance over training seeds"
    substitutions = ("`four-animals` stands in for the paper's Four Animals (smoke: glossy "
                     "`sphere-over-plane`).", "FLIP stands in for LPIPS (no weights here).")
    notes = (
        "Far views (held-out trajectory), held-out lights; masked metrics; full = learnt "
        "indirect + the method's Mitsuba direct term (as table-nw-1).",
        "The seed changes the training data (views, lights, Mitsuba samples) and the "
        "training (initialisation, batches); evaluation seeds are fixed.",
    )

    def format(self, frame, *, profile: str):
        return nw.ablation_rows(frame, self.knob, self.values[profile])

    def markdown(self, header, rows, *, profile: str, frame) -> str:
        text = super().markdown(header, rows, profile=profile, frame=frame)
        if len(rows) < 2:
            return text
        spread = seed_spread(rows, header)
        lines = ["", f"Over {len(rows)} seeds ({profile} profile), mean ± sample std:", ""]
        lines += [f"- {column}: {mean:.4g} ± {std:.2g}" for column, (mean, std) in spread.items()]
        column = header.index("PSNR indirect")
        psnr = [float(r[column]) for r in rows if math.isfinite(float(r[column]))]  # as spread
        lines += ["", f"Indirect PSNR range over the seeds: {max(psnr) - min(psnr):.2f} dB "
                      f"({min(psnr):.2f} to {max(psnr):.2f}); a knob's rows in table-nw-3 or "
                      "table-nw-4 that differ by less are not told apart by one training "
                      "each.", ""]
        return text + "\n".join(lines)


TABLE = TableNwSeeds()
