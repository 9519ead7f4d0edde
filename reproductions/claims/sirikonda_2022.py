"""Claims of PRTT (Sirikonda, Aakash KT and Narayanan 2022) = thesis chapter 3.

Sections are the paper's, with the thesis's where it renumbers them (§6.4 = thesis §3.3.4,
Table 1 = thesis table 3.1, Table 2 = thesis table 3.2). Measured by table-3.1 (FPS of TP/TPFL
per vertex and per fragment), table-3.2 (memory), table-tessellation, figures 3.4-3.6.
"""

from __future__ import annotations

import math

import numpy as np

from prtbench.bench.claims import Claim, Estimate, Measured, Missing
from reproductions.claims import bases
from reproductions.claims.measures import (
    PSNR,
    cases_text,
    config_of,
    device_text,
    fps,
    is_gpu,
    log_ratio,
    median_ms,
    ops,
    paired_difference,
    ratio_lines,
    records,
    rows_of,
    versus_paper,
)
from reproductions.claims.rules import (
    in_range,
    near_ratio,
    ratio_within,
    same_sign,
    within_tolerance,
)
from reproductions.claims.sources import PRTT
from reproductions.table_3_1 import PAPER_FPS, PAPER_SCENES
from reproductions.table_3_2 import PAPER_MEMORY, SCENE_TABLE, gamma_bytes, tpfl_bytes

#: Shader -> the prefix of its methods (per vertex, per fragment from transfer textures).
SHADER_PREFIX = {"vertex": "vertex", "fragment": "texture"}
PRODUCTS = ("tp", "tpfl")
ALL_SCENES = tuple(s for s, _ in PAPER_SCENES)
#: Paper scenes whose vertex counts exceed their covered pixels (§6.4) and the low-poly ones.
DENSE, LIGHT = ("Dragon", "TRM"), ("Room", "Plants")
FIGURE_COLUMNS = {"vertex TP": 0, "vertex TPFL": 1, "texture TP": 2, "texture TPFL": 3,
                  "vertex TPFL high": 4}


def _ops_ratio(a, b) -> float:
    try:
        return ops(a) / ops(b)
    except Missing:
        return math.nan


def _cell(frame, scene: str, method: str):
    return rows_of(frame, f"{scene} {method}", paper_scene=scene, method=method)


def _ratio_cases(ev, scenes, keys, numerator, denominator, *, name: str) -> Measured:
    """FPS(numerator(key)) / FPS(denominator(key)) per (scene, key), with the ops model's
    prediction of the same ratio (FPS ∝ 1 / ops)."""
    frame, cases, parts, predicted = ev.frame(), [], [], []
    for scene in scenes:
        for key in keys:
            num, den = numerator(key), denominator(key)
            try:
                a, b = _cell(frame, scene, num), _cell(frame, scene, den)
            except Missing:
                continue
            label = f"{scene} {key}"
            cases.append(Estimate(fps(a) / fps(b), label=label))
            parts += [a, b]
            predicted.append((label, _ops_ratio(b, a), PAPER_FPS[(scene, num)]
                              / PAPER_FPS[(scene, den)]))
    if not cases:
        raise Missing(f"no scene with both methods of the {name} ratio")
    return Measured(cases, text=f"{name} FPS: " + cases_text(cases), gpu=all(map(is_gpu, parts)),
                    device=device_text(parts), prediction=f"{name} FPS from ops per frame: "
                    + ratio_lines(predicted))


def _paper_ratios(scenes, keys, numerator, denominator) -> dict[str, float]:
    return {f"{s} {k}": PAPER_FPS[(s, numerator(k))] / PAPER_FPS[(s, denominator(k))]
            for s in scenes for k in keys}


def _texture(product: str) -> str:
    return f"texture-{product.lower()}"


def _vertex(product: str) -> str:
    return f"vertex-{product.lower()}"


def _tpfl(shader: str) -> str:
    return f"{SHADER_PREFIX[shader]}-tpfl"


def _tp(shader: str) -> str:
    return f"{SHADER_PREFIX[shader]}-tp"


def fragment_over_vertex(scenes):
    def measure(ev) -> Measured:
        return _ratio_cases(ev, scenes, ("TP", "TPFL"), _texture, _vertex,
                            name="fragment/vertex")
    return measure


def tpfl_over_tp(ev) -> Measured:
    return _ratio_cases(ev, ALL_SCENES, SHADER_PREFIX, _tpfl, _tp, name="TPFL/TP")


def fragment_cost_bounded(ev) -> Measured:
    """Spread of FPS over the scenes, vertex over fragment, per product."""
    frame, cases, parts, predicted = ev.frame(), [], [], []
    for product in PRODUCTS:
        spreads, model = {}, {}
        for shader in ("vertex", "texture"):
            method = f"{shader}-{product}"
            cells = [c for c in (_try_cell(frame, s, method) for s in ALL_SCENES) if c is not None]
            if len(cells) < 2:
                raise Missing(f"fewer than two scenes of {method}")
            rates = [fps(c) for c in cells]
            spreads[shader] = max(rates) / min(rates)
            counts = [o for o in (_try_ops(c) for c in cells) if not math.isnan(o)]
            model[shader] = max(counts) / min(counts) if len(counts) >= 2 else math.nan
            parts += cells
        paper = _paper_spread(f"vertex-{product}") / _paper_spread(f"texture-{product}")
        cases.append(Estimate(spreads["vertex"] / spreads["texture"], label=product.upper(),
                              detail=f"vertex {spreads['vertex']:.3g}×, fragment "
                                     f"{spreads['texture']:.3g}×"))
        predicted.append((product.upper(), model["vertex"] / model["texture"], paper))
    return Measured(cases, text="FPS spread over the scenes, vertex / fragment: "
                    + cases_text(cases), gpu=all(map(is_gpu, parts)), device=device_text(parts),
                    prediction="ops spread, vertex / fragment: " + ratio_lines(predicted))


def _try_cell(frame, scene, method):
    try:
        return _cell(frame, scene, method)
    except Missing:
        return None


def _try_ops(part) -> float:
    try:
        return ops(part)
    except Missing:
        return math.nan


def _paper_spread(method: str) -> float:
    rates = [PAPER_FPS[(s, method)] for s, _ in PAPER_SCENES]
    return max(rates) / min(rates)


def texture_real_time(ev) -> Measured:
    frame, cases, parts = ev.frame(), [], []
    for scene, _ in PAPER_SCENES:
        part = _try_cell(frame, scene, "texture-tpfl")
        if part is not None:
            cases.append(log_ratio(fps(part), 30.0, label=scene))
            parts.append(part)
    if not cases:
        raise Missing("no texture-tpfl rows")
    return Measured(cases, text="texture-tpfl FPS: " + ", ".join(
        f"{c.label} {30 * math.exp(c.value):.3g}" for c in cases), gpu=all(map(is_gpu, parts)),
        device=device_text(parts))


def tpfl_same_quality(ev) -> Measured:
    frame, cases = ev.frame(), []
    for scene, _ in PAPER_SCENES:
        a, b = _try_cell(frame, scene, "texture-tpfl"), _try_cell(frame, scene, "texture-tp")
        if a is not None and b is not None:
            cases.append(paired_difference(a, b, label=scene))
    if not cases:
        raise Missing("no scene with both texture methods")
    return Measured(cases, text="masked PSNR texture-tpfl − texture-tp (dB): " + cases_text(cases))


# --- figure 3.4 and the tessellation table ------------------------------------------------------

def _column(frame, scene: str, name: str):
    return rows_of(frame, f"{scene} {name}", scene=scene, column=FIGURE_COLUMNS[name])


def texture_shadows(ev) -> Measured:
    frame, cases = ev.frame(), []
    for scene in dict.fromkeys(frame["label_scene"]) if len(frame) else []:
        for product in ("TP", "TPFL"):
            cases.append(paired_difference(_column(frame, scene, f"texture {product}"),
                                           _column(frame, scene, f"vertex {product}"),
                                           label=f"{scene} {product}"))
    if not cases:
        raise Missing("no panels stored")
    return Measured(cases, text="masked PSNR texture − vertex, 2-triangle ground (dB): "
                    + cases_text(cases))


def tessellation_closes_gap(ev) -> Measured:
    frame, cases = ev.frame(), []
    for scene in dict.fromkeys(frame["label_scene"]) if len(frame) else []:
        low, texture, high = (float(_column(frame, scene, n)[PSNR].mean())
                              for n in ("vertex TPFL", "texture TPFL", "vertex TPFL high"))
        if texture - low > 0.25:  # a gap to close
            cases.append(Estimate((high - low) / (texture - low), label=scene,
                                  detail=f"{low:.1f} → {high:.1f} dB, texture {texture:.1f}"))
    if not cases:
        raise Missing("no scene where the texture beats the vertex render")
    return Measured(cases, text="fraction of the vertex–texture PSNR gap closed by an 8192-"
                    "triangle ground: " + cases_text(cases))


def _ground_extremes(ev):
    frame = ev.frame()
    tris = sorted(set(frame["label_ground_tris"])) if len(frame) else []
    if len(tris) < 2:
        raise Missing("fewer than two ground tessellations stored")
    return (rows_of(frame, "coarsest ground", ground_tris=tris[0]),
            rows_of(frame, "finest ground", ground_tris=tris[-1]), tris[0], tris[-1])


def tessellation_needed(ev) -> Measured:
    coarse, fine, t0, t1 = _ground_extremes(ev)
    case = paired_difference(fine, coarse, label=f"{t0} → {t1} ground triangles")
    return Measured([case], text=f"masked PSNR gain of vertex PRT: {case.value:.3g} dB "
                    f"({t0} → {t1} ground triangles)")


def tessellation_costs(ev) -> Measured:
    coarse, fine, t0, t1 = _ground_extremes(ev)
    case = log_ratio(median_ms(fine), median_ms(coarse), label=f"{t0} → {t1} ground triangles")
    memory = float(fine["memory_bytes"].iloc[0]) / float(coarse["memory_bytes"].iloc[0])
    return Measured([case], text=f"frame time ×{math.exp(case.value):.3g}, memory ×{memory:.3g}",
                    gpu=is_gpu(fine) and is_gpu(coarse), device=device_text([coarse, fine]),
                    prediction=f"ops per frame ×{_ops_ratio(fine, coarse):.3g}")


# --- table 3.2 ----------------------------------------------------------------------------------

def _mib_of(text: str) -> float:
    value = float(text.rstrip("GMB"))
    return value * 1024.0 if text.endswith("GB") else value


def _scheme(ev, scheme: str):
    frame = ev.merged(SCENE_TABLE)
    return rows_of(frame, f"{scheme} rows", scheme=scheme)


def _per_texel(part) -> list[tuple[str, float]]:
    """(paper scene, resident bytes per texel of the transfer textures, TPFL matrix excluded)."""
    out = []
    for _, row in part.iterrows():
        config = config_of(part[part["run_id"] == row["run_id"]])
        sets = int(row["scene_objects"]) if config.get("texture_sets") else 1
        texels = sets * int(config["texture_resolution"]) ** 2
        out.append((row["label_paper_scene"], (float(row["memory_bytes"])
                                               - tpfl_bytes(int(config["sh_bands"]))) / texels))
    return out


def texture_memory_constant(ev) -> Measured:
    per = dict(_per_texel(_scheme(ev, "ours")))
    if len(per) < 2:
        raise Missing("fewer than two scenes with transfer textures")
    spread = max(per.values()) / min(per.values())
    return Measured([Estimate(math.log(spread), label="max/min bytes per texel",
                              detail=f"×{spread:.4f}")],
                    text="bytes per texel: " + ", ".join(f"{s} {v:.4g}" for s, v in per.items()))


def vertex_memory_linear(ev) -> Measured:
    part = _scheme(ev, "ng")
    points = []
    for _, row in part.iterrows():
        bands = int(config_of(part[part["run_id"] == row["run_id"]])["sh_bands"])
        points.append((int(row["scene_vertices"]), float(row["memory_bytes"]) - gamma_bytes(bands)))
    if len({v for v, _ in points}) < 2:
        raise Missing("fewer than two vertex counts")
    slope = bases.loglog_slope(points)
    return Measured([Estimate(slope, label="exponent of bytes in V")],
                    text=f"transfer bytes ∝ V^{slope:.3f} over " + ", ".join(
                        f"{v} vertices {b / 2**20:.3g} MiB" for v, b in points))


def mckenzie_bytes(ev) -> Measured:
    bands = int(config_of(_scheme(ev, "ours"))["sh_bands"])
    mib = 1024**2 * bands**4 * 4 / 2**20
    return Measured([versus_paper(mib, _mib_of(PAPER_MEMORY["Room"]["mckenzie"]))],
                    text=f"closed form 1024²·n⁴·4 at the stored n = {bands}: {mib:.0f} MiB (never "
                         "materialised)")


def texture_bytes_1024(ev) -> Measured:
    per = _per_texel(_scheme(ev, "ours"))
    mib = float(np.median([v for _, v in per])) * 1024**2 / 2**20
    return Measured([versus_paper(mib, _mib_of(PAPER_MEMORY["Room"]["ours"]))],
                    text=f"{mib:.1f} MiB at 1024² texels (measured bytes per texel × 1024²)")


def sloan_over_ng(ev) -> Measured:
    frame, cases = ev.frame(), []
    for scene, _ in PAPER_SCENES:
        try:
            sloan = rows_of(frame, "sloan", paper_scene=scene, scheme="sloan")
            ng = rows_of(frame, "ng", paper_scene=scene, scheme="ng")
        except Missing:
            continue
        cases.append(Estimate(float(sloan["memory_bytes"].iloc[0]) / float(ng["memory_bytes"].iloc[0]),
                              label=scene))
    if not cases:
        raise Missing("no scene with both vertex schemes measured")
    return Measured(cases, text="Sloan / Ng et al. measured bytes: " + cases_text(cases))


PAPER_SLOAN_OVER_NG = {s: _mib_of(m["sloan"]) / _mib_of(m["ng"]) for s, m in PAPER_MEMORY.items()}


# --- figures 3.5 and 3.6 -------------------------------------------------------------------------

def _bounce_rows(ev):
    frame = ev.frame()
    scenes = list(dict.fromkeys(frame["label_scene"])) if len(frame) else []
    if not scenes:
        raise Missing("no figure-3.5 rows")
    return frame, scenes


def bounce_slower(ev) -> Measured:
    frame, scenes = _bounce_rows(ev)
    cases, parts, predicted = [], [], []
    for scene in scenes:
        zero = rows_of(frame, f"{scene} 0 bounces", scene=scene, bounces=0)
        one = rows_of(frame, f"{scene} 1 bounce", scene=scene, bounces=1)
        cases.append(log_ratio(fps(zero), fps(one), label=scene))
        parts += [zero, one]
        predicted.append((scene, _ops_ratio(one, zero), None))
    return Measured(cases, text="FPS 0 / 1 bounce: " + ", ".join(
        f"{c.label} {math.exp(c.value):.3g}" for c in cases), gpu=all(map(is_gpu, parts)),
        device=device_text(parts), prediction="ops 1 / 0 bounce: " + ratio_lines(predicted))


def bounce_adds_light(ev) -> Measured:
    frame, scenes = _bounce_rows(ev)
    extra = {r["cell_run_id"]: r for r in records(ev.table("figure-3.5"), "figure 3.5")}
    cases = []
    for scene in scenes:
        vs = [extra[str(rows_of(frame, scene, scene=scene, bounces=b)["run_id"].iloc[0])]
              ["psnr_masked_vs_one_bounce"] for b in (0, 1)]
        cases.append(Estimate(vs[1] - vs[0], label=scene, detail=f"{vs[0]:.1f} → {vs[1]:.1f} dB"))
    return Measured(cases, text="masked PSNR against the one-bounce reference, 1 − 0 bounces "
                    "(dB): " + cases_text(cases))


def normal_map_effect(ev) -> Measured:
    images = ev.images()
    if "with" not in images or "without" not in images:
        raise Missing("figure-3.6 panels are not stored")
    changed = float(np.mean(np.abs(images["with"].astype(np.int16)
                                   - images["without"].astype(np.int16)).max(axis=-1) > 1))
    mapped = records(ev.table("figure-3.6"), "figure 3.6")[0]
    plain = ev.frame()
    return Measured([Estimate(changed, label="pixels changed")],
                    text=f"the normal map changes {100 * changed:.1f} % of the pixels at "
                         f"{int(mapped['n_triangles'])} triangles (without it: "
                         f"{int(plain['scene_triangles'].iloc[0]) if len(plain) else '?'})")


def tp_cost_exponent(_) -> Measured:
    counts = bases.sh_tripling_counts(range(2, 9))
    ratio = [(k, c / k**2) for k, c in counts]  # TP madds per point over TPFL's k²
    slope = bases.last_slope(ratio)
    k, nonzero = counts[-1]
    return Measured([Estimate(slope, label="exponent of TP/TPFL work in k")],
                    text=f"TP multiply-adds per point (non-zero Γ) {nonzero} at k = {k}, TPFL's "
                         f"k² = {k * k}; TP/TPFL grows as k^{slope:.2f} (k = 49 → 64)")


CLAIMS = (
    Claim("prtt-6.1-texture-shadows-low-tessellation", PRTT, "§6.1, Fig. 4 (thesis fig. 3.4)",
          "For minimal tessellations, our method accurately renders shadows whereas previous "
          "methods are unable due to insufficient sampling of transfer.",
          "texture (fragment) PRT closer to the reference than vertex PRT on a 2-triangle "
          "ground, TP and TPFL (shown, no number)", "figure 3.4", texture_shadows, same_sign()),
    Claim("prtt-6.1-high-tessellation-approaches", PRTT, "§6.1, Fig. 4 third row",
          "the TP/TPFL methods on vertex shader approach the render quality of our transfer "
          "textures with a highly tessellated ground plane",
          "vertex PRT on a finely tessellated ground approaches the texture quality (shown); "
          "band: at least half the PSNR gap closed", "figure 3.4", tessellation_closes_gap,
          same_sign(band=(0.5, None), what="fraction of the gap closed")),
    Claim("prtt-1-vertex-needs-dense-tessellation", PRTT, "§1",
          "This necessitates a reasonably dense mesh tessellation (high mesh resolution) for "
          "high-quality renders.", "vertex PRT improves as the ground is tessellated (no number)",
          "table tessellation", tessellation_needed, same_sign()),
    Claim("prtt-6.1-redundant-vertices-cost", PRTT, "§6.1",
          "all previous PRT methods on vertex shaders require the addition of avoidable "
          "vertices to store the transfer on leading to drop in performance",
          "frame time grows with the ground's vertices (no number)", "table tessellation",
          tessellation_costs, same_sign(), timing=True),
    Claim("prtt-6.1-tpfl-similar-quality", PRTT, "§6.1",
          "The TPFL method with transfer textures also achieves a similar render quality at a "
          "higher FPS.", "TPFL renders as TP does (band: within 0.5 dB masked PSNR)",
          "table 3.1", tpfl_same_quality, within_tolerance(0.5)),
    Claim("prtt-3.1-tpfl-faster-than-tp", PRTT, "Table 1 (thesis table 3.1), §3",
          "The compute efficiency can be further improved to O(k²) by fixing the light",
          "TPFL/TP FPS: vertex 7-11×, fragment 7-29× (Table 1)", "table 3.1", tpfl_over_tp,
          ratio_within(_paper_ratios(ALL_SCENES, SHADER_PREFIX, _tpfl, _tp), factor=2.0),
          timing=True),
    Claim("prtt-3.1-fragment-faster-dragon-trm", PRTT, "§6.4 (thesis §3.3.4), Table 1",
          "Here, the FPS is lower for vertex based approach as compared to fragment based "
          "approach with transfer texture, in both TP and TPFL.",
          "fragment/vertex FPS: Dragon 1.44 (TP), 3.67 (TPFL); TRM 1.49, 1.75",
          "table 3.1", fragment_over_vertex(DENSE),
          ratio_within(_paper_ratios(DENSE, ("TP", "TPFL"), _texture, _vertex), factor=2.0),
          timing=True),
    Claim("prtt-3.1-vertex-faster-low-poly", PRTT, "Table 1 (thesis table 3.1)",
          "Room (21K tris) and Plants (18K): vertex TP 352/363 FPS, fragment TP 83.6/6.7",
          "fragment/vertex FPS: Room 0.24 / 0.23, Plants 0.018 / 0.065 (TP / TPFL)",
          "table 3.1", fragment_over_vertex(LIGHT),
          ratio_within(_paper_ratios(LIGHT, ("TP", "TPFL"), _texture, _vertex), factor=2.0),
          timing=True),
    Claim("prtt-6.4-fragment-cost-bounded", PRTT, "§6.4 (thesis §3.3.4)",
          "The computation is roughly the same for each fragment ... This is in contrast to "
          "vertex based approaches, where run-time depends on the number of vertices",
          "FPS spread over the four scenes: vertex 63× (TPFL), 100× (TP); fragment 3.8×, 16× "
          "(ratios 16.8, 6.2)", "table 3.1", fragment_cost_bounded,
          ratio_within({p.upper(): _paper_spread(f"vertex-{p}") / _paper_spread(f"texture-{p}")
                        for p in PRODUCTS}, factor=3.0), timing=True),
    Claim("prtt-3.1-real-time-all-scenes", PRTT, "Table 1 (thesis table 3.1)",
          "Our approach achieves real-time framerates on all scenes.",
          "fragment TPFL at 151-568 FPS (RTX 3090, 1920×1080); band: at least 30 FPS",
          "table 3.1", texture_real_time, same_sign(), timing=True),
    Claim("prtt-6.3-texture-memory-constant", PRTT, "§6.3 (thesis §3.3.3), Table 2",
          "The former's memory requirements depend on the scene complexity whereas it is "
          "constant for textures.", "100MB for every scene's 1024² texture",
          "table 3.2", texture_memory_constant, within_tolerance(math.log(1.05))),
    Claim("prtt-6.3-vertex-memory-grows", PRTT, "§6.3 (thesis §3.3.3), Table 2",
          "The former's memory requirements depend on the scene complexity",
          "Ng et al. at vertices: 2.5MB (21K tris) to 215.8MB (1.3M tris), ∝ vertices",
          "table 3.2", vertex_memory_linear, in_range(0.9, 1.1, direction=(0.3, 3.0))),
    Claim("prtt-6.3-mckenzie-infeasible", PRTT, "§6.3 (thesis §3.3.3), Table 2",
          "a direct extension of Sloan's method to textures is infeasible, as shown in the "
          "fifth column (2.5 GB per texture)", "2.5GB per 1024² texture (ratio band ×4/3)",
          "table 3.2", mckenzie_bytes, near_ratio(4 / 3)),
    Claim("prtt-6.3-texture-100mb", PRTT, "Table 2 (thesis table 3.2)",
          "Ours: 100MB", "100MB per 1024² transfer texture, 5 bands (band ×4/3)", "table 3.2",
          texture_bytes_1024, near_ratio(4 / 3)),
    Claim("prtt-6.3-sloan-matrices-k-times-vectors", PRTT, "§6.3, Table 2",
          "This amounts to storing a k × k matrix per texel which quickly becomes intractable",
          "Sloan/Ng et al. bytes: Room 25.6, Dragon 24.1, TRM 16.5, Plants 25.6 (band ×4/3)",
          "table 3.2", sloan_over_ng, ratio_within(PAPER_SLOAN_OVER_NG, factor=4 / 3)),
    Claim("prtt-6.1-interreflections-slightly-slower", PRTT, "§6.1, Fig. 5 (thesis fig. 3.5)",
          "Because of extra texture fetch, convolution and evaluation operations the FPS with "
          "inter-reflections is slightly lower, albeit still real-time.",
          "one bounce slightly slower than zero (FPS in the figure, lost in our copy); band: "
          "slower by less than 2×", "figure 3.5", bounce_slower,
          same_sign(band=(0.0, math.log(2.0)), what="ln(FPS 0 / FPS 1)"), timing=True),
    Claim("prtt-4.2-interreflections-add-light", PRTT, "§4.2, Fig. 5",
          "We further demonstrate glossy interreflections by precomputing additional textures.",
          "the one-bounce render adds the interreflected light (shown, no number)",
          "figure 3.5", bounce_adds_light, same_sign(resolution=0.1)),
    Claim("prtt-6.2-normal-maps-preserved", PRTT, "§6.2, Fig. 6 (thesis fig. 3.6)",
          "All normal map details are preserved.", "normal-map detail without extra vertices "
          "(shown)", "figure 3.6", normal_map_effect,
          not_measurable="our Mitsuba reference does not apply normal maps, so whether the "
                         "detail is right cannot be scored; ours shows only that it appears "
                         "at an unchanged triangle count"),
    Claim("prtt-3-tp-vs-tpfl-complexity", PRTT, "§1, §3",
          "it retains a compute complexity of O(k²) as opposed to O(k^{5/2}) of traditional "
          "triple products", "TP/TPFL work ∝ k^{1/2}; band: exponent 0.35-0.65",
          None, tp_cost_exponent, in_range(0.35, 0.65, direction=(0.0, 1.0))),
)
