"""Thesis figure 3.5 (PRTT Fig. 5): interreflections with transfer textures, 0 versus 1 bounce.

Rows: our stand-ins for the paper's diffuse Monkey (``lion``, diffuse variant) and glossy Roza
(``bust``, glossy variant). Columns: ``texture-tpfl`` with ``bounces=0`` and ``bounces=1`` (an
extra texture of interreflected radiance, light and BRDF baked, PRTT §4.2), then the Mitsuba
path references with direct light only and with one bounce. Each render is a runner cell
(first trajectory view): its FPS and its masked PSNR against its own reference (direct for
0 bounces, one bounce for 1 bounce) are read from the results store. The 0-bounce render's
PSNR against the one-bounce reference is measured from the two runs' display images (same
masked PSNR as the runner) and stored, to show what the missing bounce costs.
"""

from __future__ import annotations

from pathlib import Path

from prtbench.bench import metrics
from prtbench.bench.job import Job
from prtbench.bench.reproduction import Figure, display_panels, provenance_line
from prtbench.io import imageio
from prtbench.store import measurements
from prtbench.transport.raytrace import geometry_mask
from reproductions import plots, shared
from reproductions.table_3_1 import ensure_texture_methods

#: (our scene, variant, the paper scene it stands for).
SCENES = (("lion", "diffuse", "Monkey (diffuse)"), ("bust", "glossy", "Roza (glossy)"))
BOUNCES = (0, 1)
METHOD = "texture-tpfl"
#: Measurement table: each run's masked PSNR against the one-bounce reference.
TABLE = "figure-3.5"
CAPTION_HEADER = ("scene", "variant", "bounces", "FPS", "frame ms",
                  "PSNR masked vs own reference (dB)", "reference bounces",
                  "PSNR masked vs 1-bounce reference (dB)", "SSIM masked", "FLIP masked",
                  "memory MiB", "run id")


class Figure35(Figure):
    name = "3.5"
    paper = ("Sirikonda (2023) thesis, figure 3.5 = PRTT (2022) Fig. 5: zero- and one-bounce "
             "renders with transfer textures (diffuse Monkey, glossy Roza) and their FPS")
    title = "Figure 3.5: transfer textures with 0 and 1 interreflection bounce"

    def cells(self, profile: str) -> list[Job]:
        ensure_texture_methods()
        return [Job(method=METHOD, scene=scene, variant=variant, views=1,
                     overrides={"bounces": b}, label={"scene": scene, "bounces": b})
                for scene, variant, _ in SCENES for b in BOUNCES]

    def measure(self, *, profile: str, results_path: Path | None, run_id: str,
                progress: bool = True) -> dict[str, dict]:

        runs = shared.run_cells(self.cells(profile), profile=profile, results_path=results_path,
                                 progress=progress, tag=f"figure {self.name}")
        by_key = {(r.cell.label["scene"], r.cell.label["bounces"]): r for r in runs}
        images, rows = {}, []
        for scene, variant, paper_scene in SCENES:
            zero, one = by_key[(scene, 0)], by_key[(scene, 1)]
            view = zero.scene.trajectory.views[0]
            h, w = one.reference.shape[:2]
            mask = geometry_mask(zero.scene, view, w, h)
            for run in (zero, one):
                display = imageio.display(run.image, exposure=run.scene.exposure)
                images[f"{scene}/{run.cell.label['bounces']}"] = display
                # What the missing bounce costs: the render against the one-bounce reference.
                rows.append({"cell_run_id": run.run_id, "scene": scene,
                             "bounces": run.cell.label["bounces"],
                             "psnr_masked_vs_one_bounce": metrics.compute_metrics(
                                 display, one.reference, mask=mask, names=["psnr"])["psnr_masked"],
                             "substitution": run.scene.substitution or ""})
            images[f"{scene}/reference-0"] = zero.reference
            images[f"{scene}/reference-1"] = one.reference
        measurements.record(TABLE, rows, results_path=results_path, run_id=run_id,
                            profile=profile, images=display_panels(images))
        return {run.run_id: dict(run.cell.label) for run in runs}

    def plot(self, stored, *, reports_dir: Path) -> list[Path]:
        profile = stored.profile
        frame, images = stored.frame(), stored.images()
        table = stored.table(TABLE)
        extra = {r["cell_run_id"]: r for r in shared.records(table)}
        grid_rows, captions, row_labels, caption_rows = [], [], [], []
        for scene, variant, paper_scene in SCENES:
            texts, panels = [], []
            for bounces in BOUNCES:
                part = frame[(frame["label_scene"] == scene) & (frame["label_bounces"] == bounces)]
                run_id = str(part["run_id"].iloc[0])
                fps = shared.fps(part)
                own = float(part["metric_psnr_masked"].mean())
                vs_one = extra[run_id]["psnr_masked_vs_one_bounce"]
                text = f"{fps:.3g} FPS\nvs 1-bounce ref {vs_one:.1f} dB"
                if bounces == 0:
                    text += f"\nvs direct ref {own:.1f} dB"
                panels.append(images[f"{scene}/{bounces}"])
                texts.append(text)
                caption_rows.append([
                    scene, variant, bounces, fps, float(part["frame_ms"].median()), own,
                    bounces, vs_one, float(part["metric_ssim_masked"].mean()),
                    float(part["metric_flip_masked"].mean()),
                    float(part["memory_bytes"].iloc[0]) / 2**20, run_id])
            panels += [images[f"{scene}/reference-0"], images[f"{scene}/reference-1"]]
            texts += ["direct only", "one bounce"]
            grid_rows.append(panels)
            captions.append(texts)
            row_labels.append(f"{scene}\n({variant})\nfor {paper_scene}")
        spp = int(frame["reference_spp"].iloc[0])
        png = plots.panel_grid(
            reports_dir / f"figure-{self.name}.png", grid_rows, row_labels=row_labels,
            captions=captions, title=self.title + f" ({profile} profile)",
            column_labels=["texture TPFL\n0 bounces", "texture TPFL\n1 bounce",
                           f"Mitsuba path, direct\n{spp} spp", f"Mitsuba path, 1 bounce\n{spp} spp"])
        renderer = ", ".join(sorted(set(frame["renderer"].astype(str))))
        timing = ", ".join(sorted(set(frame["timing_source"].astype(str))))
        subs = sorted({r["substitution"] for r in extra.values() if r["substitution"]})
        lines = [
            f"# {self.title}", "", f"Source: {self.paper}.", "",
            f"![figure {self.name}](figure-{self.name}.png)", "",
            f"Profile `{profile}`: panels {int(frame['width'].iloc[0])}×"
            f"{int(frame['height'].iloc[0])}, first trajectory view, the scene's default light "
            f"(baked into the bounce texture). GL renderer: {renderer}; timing: {timing} (on "
            "llvmpipe FPS are comparable only within this figure).", "",
            provenance_line([frame, table], profile=profile), "",
            "\"PSNR vs own reference\" is the stored runner metric (0 bounces against the "
            "direct-only reference, 1 bounce against the one-bounce reference). \"PSNR vs "
            "1-bounce reference\" is measured after the runs from their images with the same "
            "masked PSNR and stored as measurement table `figure-3.5`. Memory includes the "
            "bounce texture (RGB transferred radiance, ⌈3n²/4⌉ RGBA layers per texture).", "",
            *shared.markdown_table(CAPTION_HEADER, caption_rows),
        ]
        if subs:
            lines += ["", "Scene substitutions:", ""] + [f"- {s}" for s in subs]
        md = shared.write_caption(reports_dir / f"figure-{self.name}.md", lines)
        return [png, md]


FIGURE = Figure35()
