"""Lecture slides 32-33 (Ramamoorthi, CSE 168; Ng, Ramamoorthi and Hanrahan 2003): linear SH
versus non-linear wavelet lighting at 25, 200, 2,000 and 20,000 terms.

Slide 33 renders one scene under one light with the lighting approximated two ways and the
transport kept: linear spherical harmonics (the first n² terms, the same for every light) and
non-linear Haar wavelets (the k terms that matter most for *this* light). Ours: the method
``wavelet-image`` (per-pixel glossy transport for one fixed view, cubemap 6×64×64 = 24,576
coefficients at the quick profile) renders both rows from one transport: ``lighting='sh'`` with
n = 5, 14, 45 bands (25, 196, 2,025 terms) and the cap of 64 bands (4,096 terms; the light's SH
projection, ``EnvironmentLight.sh``, stops at 64 bands, and the ``vertex`` methods at 8), and
``lighting='wavelet'`` with k = 25, 200, 2,000, 20,000 area-selected terms. Each panel carries
its masked PSNR against the Mitsuba path reference.

Slide 32 plots the lighting error alone against the number of terms: here the relative L2
error over the sphere (texel solid angles as weights) of the cubemap light approximated by SH
(n² terms, n = 1..64) and by its k largest wavelet terms (area-weighted selection, Ng 2003's,
and plain magnitude, the unweighted-L2 optimum), for ``sun``, ``sunset`` and ``city``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from methods.wavelet.image import SH_TEXEL_SAMPLES, WaveletImage
from prtbench.api.cache import atomic_path
from prtbench.api.method import load_or_precompute
from prtbench.api.profiles import get_profile
from prtbench.bench import metrics
from prtbench.bench.reproduction import Figure, Stored, display_panels, provenance_line, write_csv
from prtbench.bench.runner import device_description
from prtbench.io.imageio import display
from prtbench.render.reference import render_reference
from prtbench.scene.registry import get_scene
from prtbench.store import measurements
from prtbench.transport.lights import get_light
from prtbench.transport.raytrace import geometry_mask
from prtbench.transport.sh import eval_sh
from prtbench.transport.wavelet import haar
from prtbench.transport.wavelet.cubemap import (
    light_cubemap,
    subsample_pattern,
    texel_solid_angles,
)
from prtbench.transport.wavelet.selection import approximate
from reproductions import plots, shared

SCENE, VARIANT, LIGHT = "plants", "glossy", "city"
CURVE_LIGHTS = ("sun", "sunset", "city")
TABLE, CURVE = "figure-lecture-33", "figure-lecture-33-lighting"
#: Per profile: image size, cubemap N, the slide's term counts (wavelets; capped at 6N²), the SH
#: bands of the SH row (the cap is 64 bands), the transport kept per pixel row.
SETTINGS = {
    "smoke": {"image": (48, 36), "cubemap": 16, "terms": (25, 200, 1536), "sh_bands": (5, 14),
              "keep": 0.25, "curve_sh_bands": 16},
    "quick": {"image": (160, 120), "cubemap": 64, "terms": (25, 200, 2000, 20000),
              "sh_bands": (5, 14, 45, 64), "keep": 0.25, "curve_sh_bands": 64},
    "paper": {"image": (320, 240), "cubemap": 64, "terms": (25, 200, 2000, 20000),
              "sh_bands": (5, 14, 45, 64), "keep": 0.5, "curve_sh_bands": 64},
}
#: Wavelet term counts of the lighting-only curve (those above 6N² are dropped).
CURVE_TERMS = (1, 2, 5, 10, 25, 50, 100, 200, 500, 1000, 2000, 5000, 10000, 20000, 24576)


def lighting_errors(light, n: int, *, max_bands: int, terms=CURVE_TERMS) -> list[dict]:
    """Relative L2 error of the cubemap light approximated by SH and by k wavelet terms.

    The error is ``sqrt(Σ_t Ω_t |L̃_t − L_t|²) / sqrt(Σ_t Ω_t |L_t|²)`` over the 6N² texels
    (Ω_t the texel solid angles, RGB summed), L the light's texel means. SH at n bands is the
    light's own ``max_bands`` projection truncated to n² terms (orthonormal: the same as an
    n-band projection), evaluated as texel means like ``wavelet-image``'s SH lighting.

    Returns
    -------
    list of dict
        ``light``, ``basis`` ("sh", "wavelet-area", "wavelet-magnitude"), ``terms``, ``rel_l2``.
    """

    cube = light_cubemap(light, n)  # (6, N, N, 3)
    omega = texel_solid_angles(n)[..., None]
    norm = float((omega * cube**2).sum())
    rows = []
    coeffs = haar.forward(np.moveaxis(cube, -1, 0)).reshape(3, -1).T  # (6N², 3)
    support = haar.support_solid_angles(n).reshape(-1)
    for rule in ("area", "magnitude"):
        for k in (t for t in terms if t <= 6 * n * n):
            approx = approximate(coeffs, k, rule=rule, support=support)
            back = np.moveaxis(haar.inverse(approx.T.reshape(3, 6, n, n)), 0, -1)
            rows.append({"light": light.name, "basis": f"wavelet-{rule}", "terms": int(k),
                         "rel_l2": float(np.sqrt((omega * (back - cube) ** 2).sum() / norm))})
    sh = light.sh(max_bands)  # (B², 3)
    dirs, weights = subsample_pattern(n, SH_TEXEL_SAMPLES)
    # Per subsample, texel-major like the directions (the weights are the same on every face).
    w = np.tile((weights / weights.sum(axis=-1, keepdims=True)).reshape(-1), 6)
    flat_dirs, flat_omega = dirs.reshape(-1, 3), np.repeat(omega.reshape(-1), SH_TEXEL_SAMPLES**2)
    target = np.repeat(cube.reshape(-1, 3), SH_TEXEL_SAMPLES**2, axis=0)
    s2 = SH_TEXEL_SAMPLES**2
    err = np.zeros(max_bands)
    chunk = max(s2, ((1 << 23) // (max_bands * max_bands)) // s2 * s2)  # whole texels
    for start in range(0, len(flat_dirs), chunk):
        sl = slice(start, start + chunk)
        y = eval_sh(flat_dirs[sl], max_bands)  # (c, B²)
        # Running sum over bands: the n-band reconstruction for every n in one pass.
        per_band = np.stack([y[:, l * l:(l + 1) ** 2] @ sh[l * l:(l + 1) ** 2]
                             for l in range(max_bands)], axis=1)  # (c, B, 3)
        recon = np.cumsum(per_band, axis=1) * w[sl, None, None]
        means = recon.reshape(-1, s2, max_bands, 3).sum(axis=1)  # texel means (t, B, 3)
        texel_target = target[sl][::s2]
        texel_omega = flat_omega[sl][::s2]
        err += (texel_omega[:, None, None] * (means - texel_target[:, None]) ** 2).sum(axis=(0, 2))
    for b in range(1, max_bands + 1):
        rows.append({"light": light.name, "basis": "sh", "terms": b * b,
                     "rel_l2": float(np.sqrt(err[b - 1] / norm))})
    return rows


class FigureLecture33(Figure):
    name = "lecture-33"
    paper = ("Ramamoorthi, CSE 168 precomputed-rendering lecture, slides 32-33 (after Ng, "
             "Ramamoorthi and Hanrahan 2003, All-Frequency Shadows Using Non-linear Wavelet "
             "Lighting Approximation): linear SH versus non-linear wavelet lighting")
    title = "Linear SH versus non-linear wavelet lighting at 25 to 20,000 terms"
    substitutions = (
        "Our HDRIs stand in for St Peter's Basilica (not one of our assets): `city` (Blender's "
        "studio-light HDRI, CC0) for the rendered panels; `sun`, `sunset` and `city` for the "
        "lighting-error curve.",
        "`plants` (glossy variant: Phong leaves and pot over a diffuse ground) stands in for the "
        "lecture's plant scene; one view, direct light only (no interreflection).",
    )

    def measure(self, *, profile: str, results_path: Path | None, run_id: str,
                progress: bool = True) -> dict[str, dict]:

        settings = SETTINGS.get(profile, SETTINGS["quick"])
        width, height = settings["image"]
        n = settings["cubemap"]
        scene = get_scene(SCENE, variant=VARIANT).with_views(1)
        view, light = scene.trajectory.views[0], get_light(LIGHT)
        base = {"cubemap": n, "width": width, "height": height, "keep": settings["keep"]}
        configs = ([("sh", b * b, WaveletImage.make_config(
            {**base, "lighting": "sh", "sh_bands": b}, profile=profile))
            for b in settings["sh_bands"]]
            + [("wavelet", k, WaveletImage.make_config(
                {**base, "light_terms": k, "selection": "area"}, profile=profile))
               for k in settings["terms"]])
        for _, _, cfg in configs:  # every configuration checked before any work
            WaveletImage.validate(scene, cfg)
        spp = get_profile(profile).reference_spp
        ref = render_reference(scene, light, view, width=width, height=height, spp=spp,
                               bounces=0, progress=progress)
        mask = geometry_mask(scene, view, width, height)
        ref_d = display(ref.image, exposure=scene.exposure)
        images, rows = {f"Mitsuba reference ({spp} spp)": ref_d}, []
        renderer_name = ""
        # One transport for every panel: the render knobs are not part of the artifact.
        artifact = load_or_precompute(WaveletImage, scene, configs[-1][2], progress=progress)
        for basis, terms, cfg in configs:
            renderer = WaveletImage.renderer(scene, artifact, cfg, width=width, height=height)
            image = renderer.render(view, light)
            times = renderer.frame_time(view, light, warmup=1, frames=3)
            renderer_name = renderer.renderer_string
            d = display(image, exposure=scene.exposure)
            values = metrics.compute_metrics(d, ref_d, mask=mask)
            label = (f"SH {cfg.sh_bands} bands ({terms:,} terms)" if basis == "sh"
                     else f"wavelet {terms:,} terms")
            images[label] = d
            rows.append({"panel": label, "basis": basis, "terms": int(terms),
                         "sh_bands": cfg.sh_bands if basis == "sh" else None,
                         "psnr_masked_db": values["psnr_masked"],
                         "flip_masked": values["flip_masked"], "frame_ms": times.median_ms,
                         "precompute_s": artifact.precompute_s,
                         "stored_bytes": artifact.meta["stored_bytes"],
                         "dense_float32_bytes": artifact.meta["dense_float32_bytes"],
                         "pixels": artifact.meta["pixels"], "lobes": artifact.meta["lobes"],
                         "cubemap": n, "keep": cfg.keep, "width": width, "height": height,
                         "reference_spp": spp,
                         "reference_noise_display": ref.noise_rmse_display,
                         "scene": SCENE, "variant": VARIANT, "light": LIGHT})
        measurements.record(TABLE, shared.with_load(rows),
                            results_path=results_path, run_id=run_id,
                            profile=profile, renderer=renderer_name,
                            device=device_description(), images=display_panels(images))
        curve = [row for name in CURVE_LIGHTS for row in
                 lighting_errors(get_light(name), n, max_bands=settings["curve_sh_bands"])]
        measurements.record(CURVE, shared.with_load(curve),
                            results_path=results_path, run_id=run_id,
                            profile=profile, device=device_description())
        return {}

    def plot(self, stored: Stored, *, reports_dir: Path) -> list[Path]:
        table, curve = stored.table(TABLE), stored.table(CURVE)
        records = shared.records(table)
        images = stored.images()
        ref_key = next(k for k in images if k.startswith("Mitsuba"))
        sh = [r for r in records if r["basis"] == "sh"]
        wav = [r for r in records if r["basis"] == "wavelet"]
        columns = max(len(sh), len(wav))

        def caption(r):
            return f"{r['psnr_masked_db']:.2f} dB"

        panels = [[images[r["panel"]] for r in sh] + [None] * (columns - len(sh)) + [images[ref_key]],
                  [images[r["panel"]] for r in wav] + [None] * (columns - len(wav)) + [None]]
        titles = [[r["panel"] for r in sh] + [""] * (columns - len(sh)) + [ref_key],
                  [r["panel"] for r in wav] + [""] * (columns - len(wav)) + [""]]
        captions = [[caption(r) for r in sh] + [""] * (columns - len(sh) + 1),
                    [caption(r) for r in wav] + [""] * (columns - len(wav) + 1)]
        png = plots.panel_grid(reports_dir / f"figure-{self.name}.png", panels, titles=titles,
                                captions=captions, row_labels=["linear SH", "non-linear\nwavelet"],
                                title=f"{SCENE} ({VARIANT}) under {LIGHT}: masked PSNR vs path")
        curve_png = self._plot_curve(curve, reports_dir / f"figure-{self.name}-lighting.png")
        header = ["panel", "basis", "terms", "sh_bands", "psnr_masked_db", "flip_masked",
                  "frame_ms"]
        rows = [[r[h] for h in header] for r in records]
        curve_rows = shared.records(curve)
        csv_path = write_csv(reports_dir / f"figure-{self.name}.csv",
                             ["kind", *header, "light", "rel_l2"],
                             [["panel", *row, LIGHT, None] for row in rows]
                             + [["lighting", None, c["basis"], c["terms"], None, None, None,
                                 None, c["light"], c["rel_l2"]] for c in curve_rows])
        md = reports_dir / f"figure-{self.name}.md"
        with atomic_path(md) as tmp:
            tmp.write_text(self._markdown(records, curve_rows, stored, table, curve))
        return [png, curve_png, csv_path, md]

    def _plot_curve(self, curve, path: Path) -> Path:
        plt = plots._pyplot()
        lights = list(dict.fromkeys(curve["light"]))
        fig, axes = plt.subplots(1, len(lights), figsize=(4.2 * len(lights), 3.6), sharey=True)
        styles = {"sh": ("linear SH (n² terms)", "-", "o"),
                  "wavelet-area": ("wavelets, area-weighted (Ng 2003)", "-", "s"),
                  "wavelet-magnitude": ("wavelets, largest magnitude", "--", "^")}
        for ax, name in zip(np.atleast_1d(axes), lights):
            for basis, (label, line, marker) in styles.items():
                part = curve[(curve["light"] == name) & (curve["basis"] == basis)].sort_values("terms")
                ax.plot(part["terms"], part["rel_l2"], line, marker=marker, markersize=3,
                        label=label)
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_title(f"lighting error: {name}")
            ax.set_xlabel("terms")
            ax.grid(True, which="both", alpha=0.3)
        np.atleast_1d(axes)[0].set_ylabel("relative L2 error (solid-angle weighted)")
        np.atleast_1d(axes)[-1].legend(loc="lower left", fontsize=7)
        fig.tight_layout()
        return plots.save(fig, path)

    def _markdown(self, records, curve_rows, stored, table, curve) -> str:
        first = records[0]
        lines = [f"# {self.title}", "", f"Source: {self.paper}", "",
                 f"Profile `{stored.profile}`: scene `{SCENE}` ({VARIANT}), light `{LIGHT}`, view "
                 f"0, {int(first['width'])}x{int(first['height'])}, direct light only, method "
                 f"`wavelet-image` (cubemap 6x{int(first['cubemap'])}x{int(first['cubemap'])} = "
                 f"{6 * int(first['cubemap'])**2:,} coefficients, transport keep "
                 f"{first['keep']:g} per pixel row, {int(first['lobes'])} lobes, "
                 f"{int(first['pixels'])} pixels; stored {first['stored_bytes'] / 2**20:.1f} MiB "
                 f"vs {first['dense_float32_bytes'] / 2**20:.1f} MiB dense float32; precompute "
                 f"{first['precompute_s']:.1f} s). Reference kind: `path` (Mitsuba 3, "
                 f"{int(first['reference_spp'])} spp, display noise "
                 f"{first['reference_noise_display']:.4f}).", "",
                 provenance_line([table, curve], profile=stored.profile), "",
                 "![panels](figure-lecture-33.png)", "",
                 "![lighting error](figure-lecture-33-lighting.png)", "",
                 "| panel | terms | masked PSNR (dB) | masked FLIP | frame (ms, CPU) |",
                 "|---|---|---|---|---|"]
        lines += [f"| {r['panel']} | {r['terms']:,} | {r['psnr_masked_db']:.2f} | "
                  f"{r['flip_masked']:.4f} | {r['frame_ms']:.2f} |" for r in records]
        lines += ["", "Lighting-only error (relative L2, solid-angle weighted) at the slide's "
                  "term counts:", "", "| light | basis | terms | rel. L2 |", "|---|---|---|---|"]
        marks = {25, 200, 2000, 20000, 64, 196, 2025, 4096}
        lines += [f"| {c['light']} | {c['basis']} | {c['terms']:,} | {c['rel_l2']:.4f} |"
                  for c in curve_rows if c["terms"] in marks]
        lines += ["", "## Notes", "",
                  "- SH stops at 64 bands (4,096 terms): `EnvironmentLight.sh` projects at most "
                  "64 bands (and the `vertex`/`texture` methods' `sh_bands` knob stops at 8, 64 "
                  "terms), so the SH row has no 20,000-term panel; its last panel is the 64-band "
                  "cap. 196 and 2,025 SH terms (14 and 45 bands) stand for the slide's 200 and "
                  "2,000.",
                  "- Both rows share one per-pixel transport, truncated to the same kept "
                  "coefficients per pixel, so the rows differ only in the lighting "
                  "approximation, as on the slide. The SH panels use every wavelet term of the "
                  "SH-approximated light (their frame time is that full product, not an SH "
                  "renderer's).",
                  "- Frame times are the host clock around the CPU sparse product (no GL), on "
                  "the machine named above.",
                  "", "## Scene substitutions", "", *[f"- {s}" for s in self.substitutions]]
        return "\n".join(lines) + "\n"


FIGURE = FigureLecture33()
