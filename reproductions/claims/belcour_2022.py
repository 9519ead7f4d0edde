"""Claims of Belcour, Deliot, Barbier and Soler 2022 (data-driven PRT).

Measured by table-ddprt-1 (per-pass costs and storage), figure-ddprt-8 (a light outside the
dataset's family), figure-ddprt-12 (against classic vertex PRT under a sun) and figure-ddprt-14
(RMSE against the basis count, with the projection onto the basis).
"""

from __future__ import annotations

import json
import math

from prtbench.bench.claims import Claim, Estimate, Measured, Missing
from reproductions.claims.measures import (
    cases_text,
    device_text,
    is_gpu,
    log_ratio,
    present,
    records,
    versus_paper,
)
from reproductions.claims.rules import (
    in_range,
    near_ratio,
    ratio_within,
    same_sign,
    within_tolerance,
)
from reproductions.claims.sources import DDPRT
from reproductions.table_ddprt_1 import PAPER as TABLE1

#: §6.5: 16 basis elements at 1024² are 64MB on the GPU; the matrix for 256 points is 36KB.
BASIS_MIB, MATRIX_KIB, PAPER_TEXELS, PAPER_POINTS = 64.0, 36.0, 1024 * 1024, 256


def _table1(ev) -> tuple[dict[str, dict[int, dict]], object]:
    """(paper column -> basis count -> the stored row's metrics and config, the timed rows)."""
    frame = ev.frame()
    out: dict[str, dict[int, dict]] = {}
    keep = []
    for i, (_, row) in enumerate(frame.iterrows()):
        metrics, config = json.loads(row["metrics"]), json.loads(row["config"])
        if "missing" in metrics or "basis" not in config:
            continue
        column = json.loads(row["scene_params"]).get("column")
        out.setdefault(column, {})[int(config["basis"])] = {"metrics": metrics, "config": config}
        keep.append(i)
    if not out:
        raise Missing("no table-ddprt-1 rows with pass times")
    return out, frame.iloc[keep]


def shading_over_no_gi(ev) -> Measured:
    (cells, timed), cases = _table1(ev), []
    for column, per in cells.items():
        for n in (16, 64):
            if n in per and 16 in per:
                m = per[n]["metrics"]
                cases.append(Estimate(m["ms_shading"] / m["ms_no_gi"], label=f"{column} n={n}"))
    if not cases:
        raise Missing("no shader timings for n = 16 / 64")
    gpu, device = is_gpu(timed), device_text([timed])
    return Measured(cases, text="final shader / no-GI shader: " + cases_text(cases), gpu=gpu,
                    device=device)


PAPER_SHADING = {f"{c} n={n}": TABLE1[c][n] / TABLE1[c]["no_gi"] for c in TABLE1 for n in (16, 64)}


def gbuffer_over_no_gi(ev) -> Measured:
    (cells, timed), cases = _table1(ev), []
    for column, per in cells.items():
        if 16 in per:
            m = per[16]["metrics"]
            cases.append(Estimate(m["ms_gbuffer"] / m["ms_no_gi"], label=column))
    if not cases:
        raise Missing("no fake G-buffer timings at n = 16")
    gpu, device = is_gpu(timed), device_text([timed])
    return Measured(cases, text="fake G-buffer / no-GI shader: " + cases_text(cases), gpu=gpu,
                    device=device)


PAPER_GBUFFER = {c: TABLE1[c]["gbuffer"] / TABLE1[c]["no_gi"] for c in TABLE1}


def transfer_constant(ev) -> Measured:
    (cells, timed), cases, predicted = _table1(ev), [], []
    for column, per in cells.items():
        if 16 in per and 64 in per:
            cases.append(log_ratio(per[64]["metrics"]["ms_transfer"],
                                   per[16]["metrics"]["ms_transfer"], label=column))
            points = int(per[16]["config"].get("measurement_points", 0))
            predicted.append(f"{column} ×{(64 - 1) / (16 - 1):.2f} ((n − 1)·P·3 multiply-adds, "
                             f"P = {points})")
    if not cases:
        raise Missing("no transfer timings at n = 16 and 64")
    gpu, device = is_gpu(timed), device_text([timed])
    return Measured(cases, text="matrix transfer n=64 / n=16: " + ", ".join(
        f"{c.label} ×{math.exp(c.value):.3g}" for c in cases), gpu=gpu, device=device,
        prediction="; ".join(predicted) + " (the paper's 15 µs at every n reads as a fixed "
                                          "per-dispatch cost, which a CPU does not have)")


def basis_storage(ev) -> Measured:
    cells, cases = _table1(ev)[0], []
    for column, per in cells.items():
        if 16 in per:
            resolution = int(per[16]["config"]["lightmap_resolution"])
            mib = per[16]["metrics"]["bytes_basis"] * PAPER_TEXELS / resolution**2 / 2**20
            cases.append(versus_paper(mib, BASIS_MIB, label=column,
                                      detail=f"{mib:.3g} MiB at 1024² from {resolution}²"))
    if not cases:
        raise Missing("no stored basis bytes at n = 16")
    return Measured(cases, text="16-element basis scaled to 1024² texels: " + "; ".join(
        f"{c.label} {c.detail}" for c in cases))


def matrix_storage(ev) -> Measured:
    cells, cases = _table1(ev)[0], []
    for column, per in cells.items():
        if 16 in per:
            points = int(per[16]["config"]["measurement_points"])
            kib = per[16]["metrics"]["bytes_transfer_matrix"] * PAPER_POINTS / points / 2**10
            cases.append(versus_paper(kib, MATRIX_KIB, label=column,
                                      detail=f"{kib:.3g} KiB at 256 points from {points}"))
    if not cases:
        raise Missing("no stored transfer-matrix bytes at n = 16")
    return Measured(cases, text="transfer matrix (n = 16) scaled to 256 points: " + "; ".join(
        f"{c.label} {c.detail}" for c in cases))


# --- figures 8, 12 and 14 ---------------------------------------------------------------------------

def _curves(ev) -> list[dict]:
    return [r for r in records(ev.table("figure-ddprt-14"), "figure ddprt-14")
            if r["space"] == "lightmap"]


def _by_curve(rows: list[dict]) -> dict[tuple[str, float], list[dict]]:
    out: dict[tuple[str, float], list[dict]] = {}
    for r in rows:
        out.setdefault((r["family"], float(r["ridge"])), []).append(r)
    return {k: sorted(v, key=lambda r: r["basis"]) for k, v in out.items()}


def rmse_decreases(ev) -> Measured:
    cases = []
    for (family, ridge), rows in _by_curve(_curves(ev)).items():
        cases.append(log_ratio(rows[0]["ours_rmse"], rows[-1]["ours_rmse"],
                               label=f"{family} λ={ridge:g} n={rows[0]['basis']}→{rows[-1]['basis']}"))
    if not cases:
        raise Missing("no lightmap curves stored")
    return Measured(cases, text="RMSE(fewest) / RMSE(most basis elements): " + ", ".join(
        f"{c.label} ×{math.exp(c.value):.3g}" for c in cases))


def near_projection(ev) -> Measured:
    curves, cases = _by_curve(_curves(ev)), []
    for family in sorted({f for f, _ in curves}):
        ridge = min(r for f, r in curves if f == family)  # the paper's λ = 10⁻³ where stored
        ratios = [r["ours_rmse"] / r["projection_rmse"] for r in curves[(family, ridge)]
                  if r["basis"] >= 16 and r["projection_rmse"] > 0]
        if ratios:
            cases.append(Estimate(max(ratios), label=f"{family} λ={ridge:g}"))
    if not cases:
        raise Missing("no curve reaches n = 16")
    return Measured(cases, text="largest ours / projection RMSE for n ≥ 16: " + cases_text(cases))


def low_dimensional(ev) -> Measured:
    curves, cases = _by_curve(_curves(ev)), []
    for family in sorted({f for f, _ in curves}):
        ridge = min(r for f, r in curves if f == family)
        at16 = [r for r in curves[(family, ridge)] if r["basis"] == 16]
        if at16:
            r = at16[0]
            cases.append(Estimate((r["projection_rmse"] / r["reference_rms"]) ** 2, label=family))
    if not cases:
        raise Missing("no curve stores n = 16")
    return Measured(cases, text="energy left outside a 16-element basis (projection RMSE² / "
                    "RMS²): " + cases_text(cases))


def _ood(ev) -> tuple[dict, dict]:
    rows = records(ev.table("figure-ddprt-8"), "figure ddprt-8")
    inside = [r for r in rows if str(r["case"]).startswith("in distribution")]
    outside = [r for r in rows if str(r["case"]).startswith("out of distribution")]
    if not inside or not outside:
        raise Missing("figure-ddprt-8 lacks a case")
    return inside[0], outside[0]


def out_of_distribution(ev) -> Measured:
    inside, outside = _ood(ev)
    case = log_ratio(outside["indirect_rmse_relative"], inside["indirect_rmse_relative"],
                     label="relative indirect RMSE, out / in")
    return Measured([case], text=f"relative indirect RMSE: held-out spot "
                    f"{inside['indirect_rmse_relative']:.3g}, directional "
                    f"{outside['indirect_rmse_relative']:.3g}",
                    facts={"inside": inside, "outside": outside})


def explain_out_of_distribution(ev, measured) -> str:
    i, o = measured.facts["inside"], measured.facts["outside"]
    return (f"figure-ddprt-8: in distribution the basis itself already misses much of the "
            f"indirect light (projection {i['projection_rmse_relative']:.3g} of the reference's "
            f"RMS; out of distribution {o['projection_rmse_relative']:.3g}); beyond the "
            f"projection the transfer adds ×{i['indirect_rmse'] / i['projection_rmse']:.3g} in "
            f"and ×{o['indirect_rmse'] / o['projection_rmse']:.3g} out of distribution, so the "
            "departure the paper shows appears in the transfer step, hidden by a basis this "
            "dataset fits poorly")


def _leak_rows(ev) -> dict[str, dict]:
    rows = {str(r["image"]): r for r in records(ev.table("figure-ddprt-12"), "figure ddprt-12")}
    vertex = [k for k in rows if k.startswith("vertex PRT")]
    if "data-driven" not in rows or not vertex:
        raise Missing("figure-ddprt-12 lacks an image")
    return {"data-driven": rows["data-driven"], "vertex": rows[vertex[0]]}


def sh_leaks(ev) -> Measured:
    rows = _leak_rows(ev)
    case = log_ratio(rows["vertex"]["unlit_vs_reference"], rows["data-driven"]["unlit_vs_reference"],
                     label="unlit radiance, vertex PRT / data-driven")
    return Measured([case], text=f"radiance where the sun cannot reach, × the reference's: "
                    f"vertex PRT {rows['vertex']['unlit_vs_reference']:.3g}, data-driven "
                    f"{rows['data-driven']['unlit_vs_reference']:.3g}")


def beats_classical(ev) -> Measured:
    rows = _leak_rows(ev)
    a, b = rows["data-driven"]["psnr_masked_db"], rows["vertex"]["psnr_masked_db"]
    if not (present(a) and present(b)):
        raise Missing("no masked PSNR stored")
    return Measured([Estimate(a - b, label="data-driven − vertex PRT")],
                    text=f"masked PSNR: data-driven {a:.1f} dB, vertex PRT {b:.1f} dB")


CLAIMS = (
    Claim("ddprt-t1-transfer-independent-of-basis", DDPRT, "§6.5, Table 1",
          "We found that this later part is independent of the number of basis elements in "
          "the 3 tested configurations.", "matrix transfer 15 µs at n = 4, 16, 64 (ratio 1); "
          "band ×1.25", "table ddprt-1", transfer_constant, within_tolerance(math.log(1.25)),
          timing=True),
    Claim("ddprt-t1-shading-grows-with-basis", DDPRT, "§6.5, Table 1",
          "We report the timings when using 4, 16, 64 basis elements",
          "final shader / no-GI: n=16 1.6-2.1, n=64 3.2-4.6 (Table 1)", "table ddprt-1",
          shading_over_no_gi, ratio_within(PAPER_SHADING, factor=2.0), timing=True),
    Claim("ddprt-t1-fake-gbuffer-cheap", DDPRT, "§6.5, Table 1",
          "Fake G-buffer 36 μs / 34 μs / 32 μs", "fake G-buffer / no-GI: 0.08-0.16",
          "table ddprt-1", gbuffer_over_no_gi, ratio_within(PAPER_GBUFFER, factor=3.0),
          timing=True),
    Claim("ddprt-6.5-basis-64mb", DDPRT, "§6.5",
          "The storage footprint for a 16 monochannel basis at 1024×1024 resolution with 32 "
          "bits per channel is 64MB on GPU", "64MB (4 RGBA float textures); band ×4/3",
          "table ddprt-1", basis_storage, near_ratio(4 / 3)),
    Claim("ddprt-6.5-matrix-36kb", DDPRT, "§6.5",
          "the associated transfer matrix for 256 measurement points weighs 36KB",
          "36KB at 256 points; band ×4/3", "table ddprt-1", matrix_storage, near_ratio(4 / 3)),
    Claim("ddprt-fig14-rmse-decreases-with-basis", DDPRT, "§6.5, Fig. 13-14",
          "The RMSE of our method w.r.t. the reference (plain) decreases with the number of "
          "basis", "RMSE falls as n grows (plot, no numbers)", "figure ddprt-14",
          rmse_decreases, same_sign()),
    Claim("ddprt-fig14-close-to-projection", DDPRT, "§6.5, Fig. 14",
          "using only a few direct illumination samples as input produces a reconstruction "
          "error close to projecting the complete indirect illumination in the basis",
          "ours ≈ projection (plot); band: within 1.5× for n ≥ 16, direction within 3×",
          "figure ddprt-14", near_projection, in_range(0.0, 1.5, direction=(0.0, 3.0))),
    Claim("ddprt-3.2-indirect-low-dimensional", DDPRT, "§3.2, Fig. 3",
          "We found out that they drop quickly below 1% and only a few dimensions are relevant "
          "for reconstruction.", "relative eigenvalues below 1% after a few (plot); band: "
          "under 1% of the energy outside 16 elements, direction under 10%", "figure ddprt-14",
          low_dimensional, in_range(0.0, 0.01, direction=(0.0, 0.1))),
    Claim("ddprt-fig8-out-of-distribution-departs", DDPRT, "§6.1, Fig. 8",
          "when a different light condition is applied -a directional light- (right), the "
          "result, while being coherent, departs from the reference.",
          "a light outside the dataset's family departs more than a held-out one of it (shown)",
          "figure ddprt-8", out_of_distribution, same_sign(), explain_out_of_distribution),
    Claim("ddprt-fig12-classical-prt-leaks", DDPRT, "§6.4, Fig. 12",
          "because classical PRT restricts the frequency content of the incoming lighting, we "
          "can see that the directional light leaks behind the object",
          "vertex SH PRT lights pixels the sun cannot reach; data-driven does not (shown)",
          "figure ddprt-12", sh_leaks, same_sign()),
    Claim("ddprt-fig12-better-than-classical", DDPRT, "§6.4, Fig. 12",
          "Hence, we can better reproduce such lighting scenario.",
          "closer to the reference than classical PRT (shown)", "figure ddprt-12",
          beats_classical, same_sign(resolution=0.1)),
    Claim("ddprt-6.2-subsurface", DDPRT, "§6.2, Fig. 1, 6, 9",
          "Our method captures the self shadowing and the color saturation due to multiple "
          "scattering within the object.", "subsurface scattering reproduced (shown)",
          not_measurable="neither our radiance model nor the Mitsuba reference has "
                         "participating media or subsurface scattering (DESIGN.md §4)"),
    Claim("ddprt-6.3-hair", DDPRT, "§6.3, Fig. 10-11",
          "We render the interreflection of light in this HAIRBALL asset containing 140k hair "
          "strands.", "indirect light in hair (shown)",
          not_measurable="no hair fibres or fibre BSDF among our scenes and reference"),
)
