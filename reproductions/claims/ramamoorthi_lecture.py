"""Claims of Ramamoorthi's CSE 168 lecture on precomputed rendering (after Sloan 2002-2003 and
Ng, Ramamoorthi and Hanrahan 2003-2004).

Measured by figure-lecture-33 (linear SH against non-linear wavelet lighting), table-ng03
(wavelet and SH PRT under a sun and a broad sky), table-cpca (global PCA against clustered PCA);
the tripling-coefficient counts of slide 48 are computed from our own bases.
"""

from __future__ import annotations

import math

import numpy as np

from prtbench.bench.claims import Claim, Estimate, Measured, Missing
from reproductions.claims import bases
from reproductions.claims.measures import (
    cases_text,
    difference,
    log_ratio,
    mean_estimate,
    paired_difference,
    records,
    rows_of,
)
from reproductions.claims.rules import in_range, same_sign
from reproductions.claims.sources import LECTURE

#: Slide 31: the non-linear approximation keeps 0.1 % - 1 % of 6·64² = 24,576 wavelets.
KEEP_SHARE = 0.01
#: table-ng03: the wavelet and SH configurations compared at equal vertex sampling.
WAVELET, SH = "wavelet-vertex k=200", "vertex 5 bands"


def _panels(ev) -> dict[tuple[str, int], dict]:
    rows = records(ev.table("figure-lecture-33"), "figure lecture-33")
    return {(str(r["basis"]), int(r["terms"])): r for r in rows}


def wavelet_beats_sh_images(ev) -> Measured:
    panels, cases = _panels(ev), []
    sh_terms = sorted(t for b, t in panels if b == "sh")
    for (basis, terms), row in sorted(panels.items(), key=lambda kv: kv[0][1]):
        if basis == "sh" or not sh_terms:
            continue
        nearest = min(sh_terms, key=lambda t: abs(math.log(t / terms)))
        if abs(math.log(nearest / terms)) > math.log(1.25):
            continue  # no SH panel with about as many terms (SH stops at 64 bands)
        sh = panels[("sh", nearest)]
        cases.append(Estimate(row["psnr_masked_db"] - sh["psnr_masked_db"],
                              label=f"{terms} vs {nearest} terms",
                              detail=f"{row['psnr_masked_db']:.2f} vs {sh['psnr_masked_db']:.2f} dB"))
    if not cases:
        raise Missing("no wavelet and SH panels with matching term counts")
    return Measured(cases, text="masked PSNR, wavelet − SH at about equal terms (dB): "
                    + cases_text(cases))


def _curve(ev) -> list[dict]:
    return records(ev.table("figure-lecture-33-lighting"), "figure lecture-33 lighting curve")


def _budget(ev) -> int:
    panels = records(ev.table("figure-lecture-33"), "figure lecture-33")
    n = int(panels[0]["cubemap"])
    return int(KEEP_SHARE * 6 * n * n)


def wavelet_lighting_few_terms(ev) -> Measured:
    curve, budget, cases = _curve(ev), _budget(ev), []
    for light in sorted({r["light"] for r in curve}):
        rows = [r for r in curve if r["light"] == light and r["basis"] == "wavelet-area"
                and r["terms"] <= budget]
        if rows:
            best = max(rows, key=lambda r: r["terms"])
            cases.append(Estimate(float(best["rel_l2"]), label=f"{light} {best['terms']} terms"))
    if not cases:
        raise Missing("no area-weighted wavelet curve within 1 % of the basis")
    return Measured(cases, text=f"relative L2 of the light with at most {budget} wavelets (1 %): "
                    + cases_text(cases))


def sh_misses_high_frequency(ev) -> Measured:
    curve, budget, cases = _curve(ev), _budget(ev), []
    for light in sorted({r["light"] for r in curve}):
        sh = [r for r in curve if r["light"] == light and r["basis"] == "sh" and r["terms"] <= budget]
        wl = [r for r in curve if r["light"] == light and r["basis"] == "wavelet-area"
              and r["terms"] <= budget]
        if sh and wl:
            s, w = max(sh, key=lambda r: r["terms"]), max(wl, key=lambda r: r["terms"])
            cases.append(log_ratio(s["rel_l2"], w["rel_l2"], floor=1e-6,
                                   label=f"{light}: SH {s['terms']} / wavelet {w['terms']} terms"))
    if not cases:
        raise Missing("no SH and wavelet curve points within the budget")
    return Measured(cases, text="lighting error, SH over wavelets at about equal terms: " + ", ".join(
        f"{c.label} ×{math.exp(c.value):.3g}" for c in cases))


def _ng03(frame, scene: str, light: str, config: str):
    return rows_of(frame, f"{scene} {light} {config}", scene=scene, light=light, config=config)


def sh_fine_for_broad_light(ev) -> Measured:
    frame, cases = ev.frame(), []
    scenes = sorted(set(frame["label_scene"])) if len(frame) else []
    for scene in scenes:
        try:
            gain = {light: difference(mean_estimate(_ng03(frame, scene, light, WAVELET),
                                                    "metric_psnr_masked"),
                                      mean_estimate(_ng03(frame, scene, light, SH),
                                                    "metric_psnr_masked"))
                    for light in ("sun", "sunset")}
        except Missing:
            continue
        case = difference(gain["sun"], gain["sunset"], label=scene)
        cases.append(Estimate(case.value, case.lo, case.hi, scene,
                              f"wavelet − SH: sun {gain['sun'].value:+.2f}, sunset "
                              f"{gain['sunset'].value:+.2f} dB"))
    if not cases:
        raise Missing("no scene under both the sun and the sunset")
    return Measured(cases, text="wavelet advantage over 5-band SH, sun minus sunset (dB): "
                    + cases_text(cases))


def clustered_pca(ev) -> Measured:
    frame = ev.merged("table-cpca-form")
    if not len(frame) or "transfer_rmse" not in frame.columns:
        raise Missing("no compressed forms stored")
    cases = []
    for case in dict.fromkeys(frame["label_case"]):
        part = frame[frame["label_case"] == case]
        clustered_k = max(int(k) for k in part["label_K"])
        for n in sorted({int(v) for v in part["label_n"] if int(v) > 0}):
            pca = part[(part["label_K"] == 1) & (part["label_n"] == n)]
            cpca = part[(part["label_K"] == clustered_k) & (part["label_n"] == n)]
            if len(pca) and len(cpca) and clustered_k > 1:
                cases.append(log_ratio(float(pca["transfer_rmse"].iloc[0]),
                                       float(cpca["transfer_rmse"].iloc[0]),
                                       label=f"{case} n′={n}"))
    if not cases:
        raise Missing("no global-PCA and CPCA form with the same n′")
    return Measured(cases, text="transfer RMSE, global PCA / CPCA at equal per-vertex cost: "
                    + ", ".join(f"{c.label} ×{math.exp(c.value):.3g}" for c in cases))


def factored_loses_with_gloss(ev) -> Measured:
    """Masked PSNR of factored-brdf at the broadest lobe minus at the sharpest, per J, paired
    over the views; the gap to the unfactored matrix at the sharpest lobe in the text."""
    frame, cases, gaps = ev.frame(), [], []
    shininess = sorted({int(s) for s in frame.get("label_shininess", [])})
    if len(shininess) < 2:
        raise Missing("fewer than two Phong exponents stored")
    low, high = shininess[0], shininess[-1]
    for setup in sorted({str(s) for s in frame["label_setup"]} - {"sloan-matrix"}):
        broad = rows_of(frame, f"{setup} s={low}", setup=setup, shininess=low)
        sharp = rows_of(frame, f"{setup} s={high}", setup=setup, shininess=high)
        cases.append(paired_difference(broad, sharp, label=f"{setup}: s={low} − s={high}"))
        matrix = frame[(frame["label_setup"] == "sloan-matrix")
                       & (frame["label_shininess"] == high)]
        if len(matrix):
            gaps.append(f"{setup} {paired_difference(sharp, matrix).value:+.2f} dB")
    if not cases:
        raise Missing("no factored-brdf rows stored")
    return Measured(cases, text="masked PSNR, broadest − sharpest lobe (dB): "
                    + cases_text(cases) + (f"; against the unfactored matrix at s={high}: "
                                           + ", ".join(gaps) if gaps else ""))


def cost_linear_in_terms(ev) -> Measured:
    panels = _panels(ev)
    points = sorted((t, float(r["frame_ms"])) for (b, t), r in panels.items() if b == "wavelet")
    if len(points) < 2:
        raise Missing("fewer than two wavelet panels")
    slope = float(np.polyfit(np.log([t for t, _ in points]), np.log([m for _, m in points]), 1)[0])
    return Measured([Estimate(slope, label="exponent of frame time in terms")],
                    text=f"CPU frame time ∝ terms^{slope:.2f} over " + ", ".join(
                        f"{t} terms {m:.3g} ms" for t, m in points))


def haar_tripling(_) -> Measured:
    counts = bases.haar_tripling_counts((2, 4, 8))
    slope = bases.last_slope_n_log_n(counts)
    return Measured([Estimate(slope, label="exponent in N log N, N = 96 → 384")],
                    text="non-zero Haar C_ijk (6 faces): " + ", ".join(
                        f"N={n} {c}" for n, c in counts) + f"; grows as (N log N)^{slope:.2f}, "
                        f"N^{bases.last_slope(counts):.2f}")


def sh_tripling(_) -> Measured:
    counts = bases.sh_tripling_counts(range(2, 9))
    slope = bases.last_slope(counts)
    return Measured([Estimate(slope, label="local exponent, N = 49 → 64")],
                    text="non-zero SH Γ_ijk: " + ", ".join(f"N={n} {c}" for n, c in counts)
                         + f"; grows as N^{slope:.2f}")


CLAIMS = (
    Claim("lecture-48-haar-tripling-n-log-n", LECTURE, "slide 48",
          "Number Non-Zero C_ijk ... Haar Wavelets O(N log N)",
          "O(N log N): count ∝ (N log N)^1 (band: exponent 0.9-1.25, direction below 2)", None,
          haar_tripling, in_range(0.9, 1.25, direction=(0.5, 2.0))),
    Claim("lecture-48-sh-tripling-n-5-2", LECTURE, "slide 48",
          "Number Non-Zero C_ijk ... Sph. Harmonics O(N^{5/2})",
          "O(N^{5/2}): exponent 2.5 (band 2.3-2.7, direction 2-3)", None, sh_tripling,
          in_range(2.3, 2.7, direction=(2.0, 3.0))),
    Claim("lecture-34-wavelet-images-beat-linear-sh", LECTURE, "slides 33-34",
          "Top: Linear Spherical Harmonic Approximation; Bottom: Non-linear Wavelet "
          "Approximation (25, 200, 2,000, 20,000 terms)",
          "at equal terms the wavelet render is closer to the reference (images)",
          "figure lecture-33", wavelet_beats_sh_images, same_sign(resolution=0.1)),
    Claim("lecture-31-retain-one-percent", LECTURE, "slides 30-32",
          "Non-linear Approximation: Retain 0.1% – 1% terms",
          "1 % of the wavelets approximate the light (band: relative L2 ≤ 0.1, direction ≤ 0.5)",
          "figure lecture-33", wavelet_lighting_few_terms,
          in_range(0.0, 0.1, direction=(0.0, 0.5))),
    Claim("lecture-33-linear-sh-misses-detail", LECTURE, "slides 30, 33",
          "By contrast, linear approx. uses fixed set of basis functions (like 25 lowest "
          "frequency spherical harmonics)", "SH lighting error far above the wavelets' at "
          "equal terms (plot)", "figure lecture-33", sh_misses_high_frequency, same_sign()),
    Claim("lecture-21-sh-for-broad-lighting", LECTURE, "slide 21",
          "Good technique (common in games, movies) but useful only for broad low-frequency "
          "lighting", "the wavelets' advantage over SH is larger under a small sun than under a "
          "broad sky (no number)", "table ng03", sh_fine_for_broad_light,
          same_sign(resolution=0.1)),
    Claim("lecture-25-clustered-pca", LECTURE, "slides 25, 39",
          "Idea: light transport is locally low-dimensional. Why? Even though globally complex",
          "clustered PCA beats global PCA at equal per-vertex cost (Sloan 2003)", "table cpca",
          clustered_pca, same_sign()),
    Claim("lecture-50-linear-in-retained-terms", LECTURE, "slide 50",
          "Final complexity linear in number of retained basis coefficients",
          "frame cost ∝ retained terms; band: exponent 0.8-1.25", "figure lecture-33",
          cost_linear_in_terms, in_range(0.8, 1.25, direction=(0.5, 2.0))),
    Claim("lecture-41-factored-brdf-low-gloss", LECTURE, "slide 41",
          "Problem: Non-optimal factorization, few terms - Can only handle less glossy "
          "materials", "factored BRDFs lose accuracy as the gloss rises (no number)",
          "table factored-gloss", factored_loses_with_gloss, same_sign()),
)
