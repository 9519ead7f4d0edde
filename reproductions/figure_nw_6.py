"""Raghavan et al. 2023, Fig. 6: wavelet statistics of the lighting and of the transport.

Three panels, from one trained model (table-nw-1's hash grid) and one view (the first far
view, the first held-out light):

1. **Lighting**: the fraction of a light's Haar energy Σ_{top k} ‖L_j‖² / Σ ‖L_j‖² kept by
   the method's selection (its ``selection`` rule) against k, for the held-out lights and three
   training lights, at the model's cubemap resolution.
2. **Transport**: per pixel, the fraction of Σ_j ‖T_j‖² in its k largest transport
   coefficients (sorted by ‖T_j‖, RGB), median over ``pixels`` sampled pixels of the view: the
   learnt T (the network on every wavelet j) against a ground truth computed here.
3. **Rendering**: the relative error of the indirect radiance when only the light's top k
   coefficients are used (Σ_{j ∈ top-k(L)} L_j T_j against all 6N²), for both transports.

**Ground truth (ours, by ray tracing; one bounce, like the model's training data).** At the
pixel's first hit x (the G-buffer the renderer uses) ``gather`` directions ω are drawn half
cosine-weighted about n, half from the Phong lobe about r = reflect(ωo, n) (balance-heuristic
mixture pdf), traced to their first front-face hit q, and the glossy direct transport of q
towards x is the wavelet machinery's (:func:`prtbench.transport.wavelet.transport.compute_wavelet_transport`
with the diffuse and Phong lobes of q as rows, solid angles folded in, exact visibility, in
Haar); then T_j,c(x) = 1/M Σ f_c(x; ω, ωo) max(n·ω, 0) / pdf(ω) · (kd_c(q)/π D_j(q) + ks_c(q)
S_j(q)). Checked against Mitsuba: Σ_j L_j T_j at the sampled pixels beside the Mitsuba
indirect (full − direct, one seed) of the same pixels, reported in the caption.

Entry point: ``"nw-6" = "reproductions.figure_nw_6:FIGURE"``.
"""

from __future__ import annotations

import math
from functools import partial
from pathlib import Path

import numpy as np

from methods.neural_wavelet.data import light_coefficients
from methods.neural_wavelet.gbuffer import GBufferPass, pixel_rows
from methods.neural_wavelet.model import NeuralWaveletModel, PixelInputs
from prtbench.bench.reproduction import Figure, provenance_line, write_csv
from prtbench.bench.runner import device_description
from prtbench.store import measurements
from prtbench.transport.lights import get_light
from prtbench.transport.raytrace import Tracer, offset_origins
from prtbench.transport.wavelet import haar
from prtbench.transport.wavelet.selection import scores
from prtbench.transport.wavelet.transport import compute_wavelet_transport, cosines
from reproductions import plots, shared
from reproductions import table_nw_common as nw

TABLE = "figure-nw-6"
#: Sampled pixels and gather rays per pixel of the ground truth, per profile.
SIZES = {"smoke": (12, 128), "quick": (24, 256), "paper": (256, 2048)}
SEED = 0x4E5736  # "NW6"
#: Gather hits whose dense Haar rows are formed at once (2 × 6N² float64 each).
HITS_PER_CHUNK = 256
#: Pixels whose learnt transport over all wavelets is evaluated at once.
PIXELS_PER_CHUNK = 8


def k_grid(m: int) -> list[int]:
    """Powers of two up to ``m`` with 32, 64, 128 and ``m`` itself."""
    ks = {1 << i for i in range(int(math.log2(m)) + 1)} | {32, 64, 128, m}
    return sorted(k for k in ks if k <= m)


def _frame(normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit tangents (P, 3) completing each unit normal to an orthonormal frame."""
    helper = np.where(np.abs(normals[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t = np.cross(normals, helper)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    return t, np.cross(normals, t)


def _around(axis: np.ndarray, cos_a: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Directions (P, M, 3) at polar cosine ``cos_a`` and azimuth ``phi`` about ``axis`` (P, 3)."""
    t, b = _frame(axis)
    sin_a = np.sqrt(np.maximum(1.0 - cos_a**2, 0.0))
    return (sin_a * np.cos(phi))[..., None] * t[:, None] + (sin_a * np.sin(phi))[..., None] \
        * b[:, None] + cos_a[..., None] * axis[:, None]


def gather_directions(n, r, s, glossy, m: int, rng):
    """(P, M, 3) directions, half cosine about n and half Phong(s) about r where ``glossy``,
    and the mixture pdf (P, M) of each (cosine alone on diffuse pixels)."""
    p = len(n)
    u1, u2 = rng.random((p, m)), rng.random((p, m))
    cos_dirs = _around(n, np.sqrt(1.0 - u1), 2 * math.pi * u2)
    lobe = _around(r, u1 ** (1.0 / (s[:, None] + 1.0)), 2 * math.pi * u2)
    half = np.arange(m) % 2 == 1
    use_lobe = glossy[:, None] & half[None]
    dirs = np.where(use_lobe[..., None], lobe, cos_dirs)
    pdf_cos = np.maximum(np.einsum("pmj,pj->pm", dirs, n), 0.0) / math.pi
    pdf_lobe = (s[:, None] + 1.0) / (2 * math.pi) * np.maximum(
        np.einsum("pmj,pj->pm", dirs, r), 0.0) ** s[:, None]
    pdf = np.where(glossy[:, None], 0.5 * (pdf_cos + pdf_lobe), pdf_cos)
    return dirs, pdf


def ground_truth_transport(scene, rows: dict, *, n: int, gather: int, seed: int,
                           progress: bool = False) -> np.ndarray:
    """One-bounce Haar transport (P, 6N², 3) of the G-buffer ``rows`` (module docstring)."""

    tracer = Tracer.from_scene(scene)
    positions, vnormals, faces, object_of_face = scene.merged()
    corners = positions.astype(np.float64)[faces]
    face_n = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    kd = np.array([o.material.kd for o in scene.objects], np.float64)
    ks = np.array([o.material.ks for o in scene.objects], np.float64)
    shin = np.array([o.material.shininess for o in scene.objects], np.float64)
    x = rows["positions"].astype(np.float64)
    nx = rows["normals"].astype(np.float64)
    nx /= np.linalg.norm(nx, axis=1, keepdims=True)
    wo = rows["wo"].astype(np.float64)
    rx = 2.0 * np.sum(nx * wo, axis=1, keepdims=True) * nx - wo
    sx, ksx, kdx = rows["shininess"].astype(np.float64), rows["ks"].astype(np.float64), \
        rows["kd"].astype(np.float64)
    rng = np.random.default_rng(seed)
    dirs, pdf = gather_directions(nx, rx, sx, ksx.max(axis=1) > 0, gather, rng)
    m = 6 * n * n
    out = np.zeros((len(x), m, 3))
    for p in range(len(x)):
        d = dirs[p]
        cos = d @ nx[p]
        origin = offset_origins(x[p:p + 1], nx[p:p + 1], diagonal=tracer.diagonal)
        hits = tracer.first_hit(np.repeat(origin, gather, axis=0).astype(np.float32),
                                d.astype(np.float32))
        ok = (hits.face >= 0) & (cos > 0) & (pdf[p] > 0)
        ok[ok] = np.einsum("hj,hj->h", d[ok], face_n[hits.face[ok]]) < 0  # front faces only
        idx = np.flatnonzero(ok)
        if not len(idx):
            continue
        face = hits.face[idx]
        u, v = hits.u[idx].astype(np.float64), hits.v[idx].astype(np.float64)
        bary = np.stack([1.0 - u - v, u, v], axis=1)
        q = np.einsum("hk,hkj->hj", bary, positions.astype(np.float64)[faces[face]])
        nq = np.einsum("hk,hkj->hj", bary, vnormals.astype(np.float64)[faces[face]])
        nq /= np.linalg.norm(nq, axis=1, keepdims=True)
        wq = -d[idx]
        rq = (2.0 * np.sum(nq * wq, axis=1, keepdims=True) * nq - wq).astype(np.float32)
        obj = object_of_face[face]
        sq = shin[obj]

        def lobes(sl, dirs_t, rq=rq, sq=sq, offset=0):
            sl = slice(sl.start + offset, sl.stop + offset)  # points of this chunk of hits
            dot = np.maximum(cosines(rq[sl], dirs_t), 0.0)
            s = sq[sl, None]
            spec = (s + 1.0) / (2.0 * math.pi) * np.power(dot, s)
            return np.stack([np.ones_like(spec), spec], axis=1).astype(np.float32)

        dot = np.maximum(d[idx] @ rx[p], 0.0)
        f = kdx[p][None] / math.pi + ksx[p][None] * ((sx[p] + 1.0) / (2 * math.pi)
                                                     * dot ** sx[p])[:, None]  # (H, 3)
        weight = f * (cos[idx] / pdf[p][idx])[:, None] / gather
        for start in range(0, len(idx), HITS_PER_CHUNK):  # bounds the dense rows' memory
            sl = slice(start, start + HITS_PER_CHUNK)
            transport, _ = compute_wavelet_transport(
                scene, q[sl], nq[sl], n=n, keep=1.0, lobes=partial(lobes, offset=start),
                n_lobes=2, tracer=tracer, progress=progress)
            dense = transport.dense().reshape(-1, 2, m)  # (h, lobe, M)
            # (h, M, 3): radiance of each hit towards x per unit of each wavelet
            shade = kd[obj[sl]][:, None, :] / math.pi * dense[:, 0, :, None] \
                + ks[obj[sl]][:, None, :] * dense[:, 1, :, None]
            out[p] += np.einsum("hc,hmc->mc", weight[sl], shade)
    return out


def energy_captured(values: np.ndarray, ks) -> np.ndarray:
    """Fraction of Σ‖v_j‖² in the k largest ‖v_j‖ (rows of ``values`` (M, 3)), per k."""
    e = np.sort((np.asarray(values, np.float64) ** 2).sum(axis=1))[::-1]
    total = e.sum()
    cum = np.cumsum(e)
    return np.array([cum[k - 1] / total if total > 0 else math.nan for k in ks])


class FigureNw6(Figure):
    name = "nw-6"
    paper = ("Raghavan, Wang, Ramamoorthi et al. 2023, Neural Free-Viewpoint Relighting for "
             "Glossy Indirect Illumination, Fig. 6 (wavelet statistics of one view)")
    title = "Neural wavelet PRT: wavelet statistics of lighting and transport"
    substitutions = ("`four-animals` (first far view) stands in for the paper's view; smoke: "
                     "glossy `sphere-over-plane`.",)

    def measure(self, *, profile: str, results_path: Path | None, run_id: str,
                progress: bool = True) -> dict[str, dict]:
        import torch

        st = nw.setup(profile)
        config = nw.nw_config(profile)
        artifact, _ = nw.train(config, st, progress=progress)
        n, m = config.cubemap, 6 * config.cubemap ** 2
        ks = k_grid(m)
        rule = {"support": haar.support_solid_angles(n).reshape(-1)} \
            if config.selection == "area" else {}
        records = []

        def light_order(coeffs):
            return np.argsort(-scores(coeffs, rule=config.selection, **rule), kind="stable")

        lights = [*st.lights, *config.train_lights[:3]]
        for name in lights:
            coeffs = light_coefficients(get_light(name), n)
            order = light_order(coeffs)
            e = (coeffs.astype(np.float64) ** 2).sum(axis=1)
            cum = np.cumsum(e[order]) / e.sum()
            kind = "held-out" if name in st.lights else "training"
            records += [{"panel": "light", "series": f"{name} ({kind})", "k": k,
                         "value": float(cum[k - 1])} for k in ks]
        scene = st.scenes["far"].with_views(1)
        view, light = scene.trajectory.views[0], get_light(st.lights[0])
        gpass = GBufferPass(scene, width=st.width, height=st.height)
        try:
            rows = pixel_rows(gpass.read(view), view.eye)
            renderer_string = gpass.renderer_string
        finally:
            gpass.release()
        count, gather = SIZES[profile]
        pick = np.sort(np.random.default_rng(SEED).choice(len(rows["pixel"]),
                                                          size=min(count, len(rows["pixel"])),
                                                          replace=False))
        rows = {k: v[pick] for k, v in rows.items()}
        nw.log("nw6", f"ground-truth transport of {len(pick)} pixels x {gather} gather rays, "
                      f"6x{n}x{n} wavelets")
        gt = ground_truth_transport(scene, rows, n=n, gather=gather, seed=SEED)

        model = NeuralWaveletModel.from_arrays(artifact.arrays)
        inputs = PixelInputs(*(torch.as_tensor(rows[k]) for k in
                               ("positions", "normals", "wo", "kd", "ks", "shininess")),
                             torch.as_tensor(rows["triangles"], dtype=torch.int64))
        with torch.no_grad():
            learnt = np.concatenate([
                (model.transport(inputs.rows(slice(i, i + PIXELS_PER_CHUNK)), np.arange(m))
                 * model.target_scale).double().numpy()
                for i in range(0, len(pick), PIXELS_PER_CHUNK)])
        coeffs = light_coefficients(light, n).astype(np.float64)
        order = light_order(coeffs)
        for series, t in (("ground truth", gt), ("learnt", learnt)):
            fractions = np.array([energy_captured(t[p], ks) for p in range(len(t))])
            records += [{"panel": "transport", "series": series, "k": k,
                         "value": float(np.nanmedian(fractions[:, i]))} for i, k in enumerate(ks)]
            full = np.einsum("pmc,mc->pc", t, coeffs)
            for k in ks:
                part = np.einsum("pmc,mc->pc", t[:, order[:k]], coeffs[order[:k]])
                err = np.linalg.norm(part - full) / max(np.linalg.norm(full), 1e-30)
                records.append({"panel": "rendering", "series": series, "k": k,
                                "value": float(err)})
        # The check uses a smooth training light (the transport does not depend on the light):
        # a sharp held-out light lights too few of the sampled pixels indirectly to compare.
        check_light = get_light(config.train_lights[0])
        check = light_coefficients(check_light, n).astype(np.float64)
        refs = nw.References(st, bounces=config.bounces, direct_spp=config.direct_spp)
        _, ref_indirect, _ = refs.get(scene, check_light, view)
        mitsuba = ref_indirect.reshape(-1, 3)[rows["pixel"]].astype(np.float64)
        for p in range(len(pick)):
            records.append({"panel": "check", "series": f"pixel {int(rows['pixel'][p])}",
                            "k": m, "value": math.nan, "light": check_light.name,
                            "ground_truth": float(np.einsum("mc,mc->", gt[p], check)),
                            "learnt": float(np.einsum("mc,mc->", learnt[p], check)),
                            "mitsuba": float(mitsuba[p].sum()),
                            "ks": float(rows["ks"][p].mean()),
                            "shininess": float(rows["shininess"][p])})
        facts = {"panel": "facts", "series": "setup", "k": m, "value": math.nan,
                 "scene": scene.name, "light": light.name, "view": 0, "pixels": int(len(pick)),
                 "gather": int(gather), "cubemap": int(n), "selection": config.selection,
                 "width": st.width, "height": st.height, "reference_spp": st.reference_spp}
        measurements.record(TABLE, shared.with_load([*records, facts]),
                            results_path=results_path, run_id=run_id,
                            profile=profile, renderer=renderer_string,
                            device=device_description())
        return {}

    def plot(self, stored, *, reports_dir: Path) -> list[Path]:
        table = stored.table(TABLE)
        recs = shared.records(table)
        facts = next(r for r in recs if r["panel"] == "facts")
        plt = plots._pyplot()
        fig, axes = plt.subplots(1, 3, figsize=(15.0, 4.6))
        titles = {"light": ("Lighting: energy in the top-k coefficients", "energy fraction"),
                  "transport": ("Transport: energy in its k largest (median pixel)",
                                "energy fraction"),
                  "rendering": ("Indirect with the light's top k: relative error",
                                "relative error")}
        for ax, (panel, (title, ylabel)) in zip(axes, titles.items()):
            part = [r for r in recs if r["panel"] == panel]
            for series in dict.fromkeys(r["series"] for r in part):
                pts = [(r["k"], r["value"]) for r in part if r["series"] == series]
                ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", markersize=3,
                        label=series)
            ax.set_xscale("log", base=2)
            if panel == "rendering":
                ax.set_yscale("log")
            for k in (32, 64, 128):
                ax.axvline(k, color="grey", linewidth=0.6, alpha=0.5)
            ax.set_title(title)
            ax.set_xlabel("k")
            ax.set_ylabel(ylabel)
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize="small")
        fig.suptitle(f"{self.title} ({stored.profile} profile)")
        fig.tight_layout()
        png = plots.save(fig, reports_dir / f"figure-{self.name}.png")
        header = ["panel", "series", "k", "value"]
        rows = [[r["panel"], r["series"], int(r["k"]), r["value"]] for r in recs
                if r["panel"] in titles]
        csv_path = write_csv(reports_dir / f"figure-{self.name}.csv", header, rows)
        checks = [r for r in recs if r["panel"] == "check"]
        mits = np.array([r["mitsuba"] for r in checks])
        gt = np.array([r["ground_truth"] for r in checks])
        le = np.array([r["learnt"] for r in checks])

        def rel(a):
            return float(np.linalg.norm(a - mits) / max(np.linalg.norm(mits), 1e-30))

        def at(panel, series, k):
            return next((r["value"] for r in recs if r["panel"] == panel
                         and r["series"] == series and r["k"] == k), math.nan)

        lines = [
            f"# {self.title}", "", f"Source: {self.paper}.", "",
            f"![figure {self.name}](figure-{self.name}.png)", "",
            f"Profile `{stored.profile}`: scene `{facts['scene']}`, first far view, held-out "
            f"light `{facts['light']}`, {facts['width']}×{facts['height']}; cubemap 6×"
            f"{facts['cubemap']}² = {6 * facts['cubemap'] ** 2} Haar wavelets, selection "
            f"`{facts['selection']}`; {facts['pixels']} sampled pixels, {facts['gather']} "
            "gather rays each for the ground truth.", "",
            provenance_line([table], profile=stored.profile), "",
            "Ground truth: one bounce by our ray tracing and the wavelet transport machinery "
            "(module docstring of `reproductions/figure_nw_6.py`), not Mitsuba; checked against "
            "Mitsuba's indirect (full − direct, one seed, "
            f"{facts['reference_spp']} spp) at the same pixels under the training light "
            f"`{checks[0]['light']}` (RGB sums of Σ_j L_j T_j): "
            f"relative L2 difference ground truth vs Mitsuba {rel(gt):.3f}, learnt vs Mitsuba "
            f"{rel(le):.3f} over the {len(checks)} pixels.", "",
            f"At k = 64: the held-out light keeps {at('light', recs[0]['series'], 64):.3f} of "
            f"its energy; the median pixel's transport keeps "
            f"{at('transport', 'ground truth', 64):.3f} (ground truth) / "
            f"{at('transport', 'learnt', 64):.3f} (learnt) in its 64 largest coefficients; the "
            f"indirect radiance from the light's top 64 is off by "
            f"{at('rendering', 'ground truth', 64):.3f} (ground truth) / "
            f"{at('rendering', 'learnt', 64):.3f} (learnt) relative to all wavelets.", "",
            "The paper's figure is a picture (no numbers survive in our copy): it says the "
            "learnt distribution differs in shape from the ground truth while most energy sits "
            "in few entries; compare with the middle panel.", "",
            *shared.markdown_table(header, rows), "",
            "## Scene substitutions", "", *[f"- {s}" for s in self.substitutions],
        ]
        md = shared.write_caption(reports_dir / f"figure-{self.name}.md", lines)
        return [png, csv_path, md]


FIGURE = FigureNw6()
