"""Thesis figure 3.5 (PRTT Fig. 5): interreflections with transfer textures, 0 versus 1 bounce.

Rows: our stand-ins for the paper's diffuse Monkey (``lion``, diffuse variant) and glossy Roza
(``bust``, glossy variant). Columns: ``texture-tpfl`` with ``bounces=0`` and ``bounces=1`` (an
extra texture of interreflected radiance, light and BRDF baked, PRTT §4.2), then the Mitsuba
path references with direct light only and with one bounce. Each render is a runner cell
(first trajectory view): its FPS and its masked PSNR against its own reference (direct for
0 bounces, one bounce for 1 bounce) are read from the results store. The 0-bounce render's
PSNR against the one-bounce reference is computed by the figure from the two stored runs'
display images (same masked PSNR as the runner), to show what the missing bounce costs.
"""

from __future__ import annotations

from pathlib import Path

from prtbench.reproduction import Cell, Figure

from . import _panels
from .table_3_1 import ensure_texture_methods

#: (our scene, variant, the paper scene it stands for).
SCENES = (("lion", "diffuse", "Monkey (diffuse)"), ("bust", "glossy", "Roza (glossy)"))
BOUNCES = (0, 1)
METHOD = "texture-tpfl"
CAPTION_HEADER = ("scene", "variant", "bounces", "FPS", "frame ms",
                  "PSNR masked vs own reference (dB)", "reference bounces",
                  "PSNR masked vs 1-bounce reference (dB)", "SSIM masked", "FLIP masked",
                  "memory MiB", "run id")


class Figure35(Figure):
    name = "3.5"
    paper = ("Sirikonda (2023) thesis, figure 3.5 = PRTT (2022) Fig. 5: zero- and one-bounce "
             "renders with transfer textures (diffuse Monkey, glossy Roza) and their FPS")
    title = "Figure 3.5: transfer textures with 0 and 1 interreflection bounce"

    def cells(self, profile: str) -> list[Cell]:
        ensure_texture_methods()
        return [Cell(method=METHOD, scene=scene, variant=variant, views=1,
                     overrides={"bounces": b}, label={"scene": scene, "bounces": b})
                for scene, variant, _ in SCENES for b in BOUNCES]

    def make(self, *, profile: str, reports_dir: Path, results_path: Path | None = None,
             progress: bool = True) -> list[Path]:
        from prtbench import imageio, metrics
        from prtbench.runner import geometry_mask

        runs = _panels.run_cells(self.cells(profile), profile=profile, results_path=results_path,
                                 progress=progress, tag=f"figure {self.name}")
        by_key = {(r.cell.label["scene"], r.cell.label["bounces"]): r for r in runs}
        grid_rows, row_labels, caption_rows = [], [], []
        for scene, variant, paper_scene in SCENES:
            zero, one = by_key[(scene, 0)], by_key[(scene, 1)]
            one_bounce_reference = one.reference
            view = zero.scene.trajectory.views[0]
            h, w = one_bounce_reference.shape[:2]
            mask = geometry_mask(zero.scene, view, w, h)
            panels = []
            for run in (zero, one):
                display = imageio.display(run.image, exposure=run.scene.exposure)
                stored = run.rows
                fps = _panels.fps(stored)
                own = float(stored["metric_psnr_masked"].mean())
                vs_one = metrics.compute_metrics(display, one_bounce_reference, mask=mask,
                                                 names=["psnr"])["psnr_masked"]
                bounces = run.cell.label["bounces"]
                text = f"{fps:.3g} FPS\nvs 1-bounce ref {vs_one:.1f} dB"
                if bounces == 0:
                    text += f"\nvs direct ref {own:.1f} dB"
                panels.append(_panels.caption(display, text))
                caption_rows.append([
                    scene, variant, bounces, fps, float(stored["frame_ms"].median()), own,
                    bounces, vs_one, float(stored["metric_ssim_masked"].mean()),
                    float(stored["metric_flip_masked"].mean()),
                    float(stored["memory_bytes"].iloc[0]) / 2**20, run.run_id])
            panels.append(_panels.caption(zero.reference, "direct only"))
            panels.append(_panels.caption(one_bounce_reference, "one bounce"))
            grid_rows.append(panels)
            row_labels.append(f"{scene}\n({variant})\nfor {paper_scene}")
        spp = int(runs[0].rows["reference_spp"].iloc[0])
        image = _panels.grid(
            grid_rows, row_labels=row_labels, title=self.title + f" ({profile} profile)",
            column_labels=["texture TPFL\n0 bounces", "texture TPFL\n1 bounce",
                           f"Mitsuba path, direct\n{spp} spp", f"Mitsuba path, 1 bounce\n{spp} spp"])
        reports_dir = Path(reports_dir)
        reports_dir.mkdir(parents=True, exist_ok=True)
        png = reports_dir / f"figure-{self.name}.png"
        imageio.write_png(png, image)
        first = runs[0].rows
        renderer = ", ".join(sorted({str(r.rows["renderer"].iloc[0]) for r in runs}))
        timing = ", ".join(sorted({str(r.rows["timing_source"].iloc[0]) for r in runs}))
        subs = sorted({r.scene.substitution for r in runs if r.scene.substitution})
        lines = [
            f"# {self.title}", "", f"Source: {self.paper}.", "",
            f"![figure {self.name}](figure-{self.name}.png)", "",
            f"Profile `{profile}`: panels {int(first['width'].iloc[0])}×"
            f"{int(first['height'].iloc[0])}, first trajectory view, the scene's default light "
            f"(baked into the bounce texture). GL renderer: {renderer}; timing: {timing} (on "
            "llvmpipe FPS are comparable only within this figure).", "",
            "\"PSNR vs own reference\" is the stored runner metric (0 bounces against the "
            "direct-only reference, 1 bounce against the one-bounce reference). \"PSNR vs "
            "1-bounce reference\" is computed here from the stored runs' images with the same "
            "masked PSNR. Memory includes the bounce texture (RGB transferred radiance, "
            "⌈3n²/4⌉ RGBA layers per texture).", "",
            *_panels.markdown_table(CAPTION_HEADER, caption_rows),
        ]
        if subs:
            lines += ["", "Scene substitutions:", ""] + [f"- {s}" for s in subs]
        md = _panels.write_caption(reports_dir / f"figure-{self.name}.md", lines)
        return [png, md]


FIGURE = Figure35()
