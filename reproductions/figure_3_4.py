"""Thesis figure 3.4 (PRTT Fig. 4, with the room of Fig. 1): TP and TPFL per vertex and per
fragment on minimally tessellated grounds, and vertex PRT on a highly tessellated ground.

Rows: our scenes. Columns: ``vertex-tp``, ``vertex-tpfl``, ``texture-tp``, ``texture-tpfl`` on
the scene as built (a two-triangle ground/floor), ``vertex-tpfl`` with the ground/floor
subdivided into 2·64² = 8192 triangles (the paper's "high tessellation" row), and the direct-only
Mitsuba path reference. Every panel carries a wireframe inset (the mesh edges drawn inside a
boxed ground region) and its FPS and masked PSNR, read from the results store after the runner
measured the panel's very image (first view of the trajectory, glossy variant).
"""

from __future__ import annotations

from pathlib import Path

from prtbench.bench.job import Job
from prtbench.bench.reproduction import Figure, display_panels, provenance_line
from prtbench.io import imageio
from prtbench.store import measurements
from reproductions import plots, shared
from reproductions.table_3_1 import ensure_texture_methods, scene_choices

#: Ground (or floor) quads per side of the high-tessellation column: 2·64² = 8192 triangles.
HIGH_SUBDIVISIONS = 64
#: Scene parameter that subdivides each scene's ground.
GROUND_PARAMETER = {"plants": "ground_subdivisions", "dragon": "ground_subdivisions",
                    "dragon-lo": "ground_subdivisions", "trm": "ground_subdivisions",
                    "room": "floor_subdivisions"}
#: Rows per profile (paper: the paper's Fig. 4 scenes and the Fig. 1 room).
SCENES = {"paper": ("plants", "room", "dragon", "trm"),
          "quick": ("plants", "room", "dragon-lo"),
          "smoke": ("plants",)}
#: Columns: (label, method, high tessellation?).
COLUMNS = (("vertex TP", "vertex-tp", False), ("vertex TPFL", "vertex-tpfl", False),
           ("texture TP", "texture-tp", False), ("texture TPFL", "texture-tpfl", False),
           ("vertex TPFL,\nground 8192 tris", "vertex-tpfl", True))
#: Box of the wireframe inset (top, bottom, left, right as panel fractions, first view): ground
#: beside the objects, where their shadows fall and the ground's few edges pass.
CROPS = {"plants": (0.55, 0.92, 0.05, 0.45), "room": (0.60, 0.95, 0.30, 0.70),
         "dragon": (0.50, 0.85, 0.30, 0.75), "dragon-lo": (0.50, 0.85, 0.30, 0.75),
         "trm": (0.55, 0.92, 0.05, 0.45)}
DEFAULT_CROP = (0.55, 0.92, 0.05, 0.45)
VARIANT = "glossy"
#: Measurement table of the rows' scenes (triangle count, substitution); panels as images.
TABLE = "figure-3.4"
#: Supersampling of the wireframe pass (thin antialiased lines).
WIRE_SCALE = 2
CAPTION_HEADER = ("scene", "panel", "method", "tris", "FPS", "frame ms", "PSNR masked (dB)",
                  "SSIM masked", "FLIP masked", "memory MiB", "run id")


class Figure34(Figure):
    name = "3.4"
    paper = ("Sirikonda (2023) thesis, figure 3.4 = PRTT (2022) Fig. 4 (and Fig. 1): TP/TPFL on "
             "the vertex vs fragment shader on minimally tessellated grounds, and vertex PRT on a "
             "highly tessellated ground")
    title = "Figure 3.4: vertex vs transfer-texture PRT on low-tessellation grounds"

    def scenes(self, profile: str) -> tuple[str, ...]:
        return SCENES.get(profile, SCENES["quick"])

    def cells(self, profile: str) -> list[Job]:
        """One cell per panel except the reference column, one view each."""
        ensure_texture_methods()
        choices = {c.scene: c for c in scene_choices(profile)}
        cells = []
        for scene in self.scenes(profile):
            # Same scene parameters and texture settings as table 3.1 (e.g. TRM's texture sets).
            choice = choices.get(scene)
            for column, (label, method, high) in enumerate(COLUMNS):
                params = dict(choice.scene_params) if choice else {}
                if high:
                    params[GROUND_PARAMETER[scene]] = HIGH_SUBDIVISIONS
                cells.append(Job(method=method, scene=scene, variant=VARIANT, views=1,
                                  scene_params=params,
                                  overrides=choice.overrides(method) if choice else {},
                                  label={"scene": scene, "column": column}))
        return cells

    def measure(self, *, profile: str, results_path: Path | None, run_id: str,
                progress: bool = True) -> dict[str, dict]:

        runs = shared.run_cells(self.cells(profile), profile=profile, results_path=results_path,
                                 progress=progress, tag=f"figure {self.name}")
        images, scenes = {}, {}
        for run in runs:
            scene, column = run.cell.label["scene"], run.cell.label["column"]
            display = imageio.display(run.image, exposure=run.scene.exposure)
            h, w = display.shape[:2]
            edges, _ = shared.render_wireframe(run.scene, run.scene.trajectory.views[0],
                                                width=WIRE_SCALE * w, height=WIRE_SCALE * h)
            images[f"{scene}/{column}/display"] = display
            images[f"{scene}/{column}/edges"] = edges
            if column == 0:
                images[f"{scene}/reference"] = run.reference
                scenes[scene] = {"scene": scene, "n_triangles": run.scene.n_triangles,
                                 "substitution": run.scene.substitution or ""}
        measurements.record(TABLE, list(scenes.values()), results_path=results_path,
                            run_id=run_id, profile=profile, images=display_panels(images))
        return {run.run_id: dict(run.cell.label) for run in runs}

    def plot(self, stored, *, reports_dir: Path) -> list[Path]:
        profile = stored.profile
        frame, images = stored.frame(), stored.images()
        table = stored.table(TABLE)
        scenes = shared.records(table)
        rows, captions, row_labels, caption_rows = [], [], [], []
        for info in scenes:
            scene = info["scene"]
            panels, texts = [], []
            for column, (label, method, high) in enumerate(COLUMNS):
                part = frame[(frame["label_scene"] == scene) & (frame["label_column"] == column)]
                panels.append(shared.wireframe_overlay(
                    images[f"{scene}/{column}/display"], images[f"{scene}/{column}/edges"],
                    crop=CROPS.get(scene, DEFAULT_CROP)))
                fps = shared.fps(part)
                psnr = float(part["metric_psnr_masked"].mean())
                texts.append(f"{fps:.3g} FPS  {psnr:.1f} dB")
                caption_rows.append([
                    scene, label.replace("\n", " "), method, int(part["scene_triangles"].iloc[0]),
                    fps, float(part["frame_ms"].median()), psnr,
                    float(part["metric_ssim_masked"].mean()),
                    float(part["metric_flip_masked"].mean()),
                    float(part["memory_bytes"].iloc[0]) / 2**20, str(part["run_id"].iloc[0])])
            panels.append(images[f"{scene}/reference"])
            texts.append("path reference")
            rows.append(panels)
            captions.append(texts)
            row_labels.append(f"{scene}\n{info['n_triangles']} tris")
        spp = int(frame["reference_spp"].iloc[0])
        png = plots.panel_grid(reports_dir / f"figure-{self.name}.png", rows,
                                column_labels=[c[0] for c in COLUMNS] + [f"Mitsuba path\n{spp} spp"],
                                row_labels=row_labels, captions=captions,
                                title=self.title + f" ({profile} profile)")
        md = shared.write_caption(reports_dir / f"figure-{self.name}.md",
                                   self.caption_lines(frame, table, caption_rows, profile=profile))
        return [png, md]

    def caption_lines(self, frame, table, rows, *, profile: str) -> list[str]:
        scenes = shared.records(table)
        renderer = ", ".join(sorted(set(frame["renderer"].astype(str))))
        timing = ", ".join(sorted(set(frame["timing_source"].astype(str))))
        width, height = int(frame["width"].iloc[0]), int(frame["height"].iloc[0])
        subs = sorted({s["substitution"] for s in scenes if s["substitution"]})
        lines = [f"# {self.title}", "", f"Source: {self.paper}.", "",
                 f"![figure {self.name}](figure-{self.name}.png)", "",
                 f"Profile `{profile}`: panels {width}×{height}, "
                 f"first trajectory view, glossy variants. GL renderer: {renderer}; timing: "
                 f"{timing}. On a CPU rasteriser (llvmpipe) FPS are comparable only within this "
                 "figure.", "", provenance_line([frame, table], profile=profile), "",
                 "Columns 1–4 use each scene as built: a two-triangle ground (the room: a "
                 "two-triangle floor). Column 5 subdivides the ground/floor into "
                 f"2·{HIGH_SUBDIVISIONS}² = {2 * HIGH_SUBDIVISIONS**2} triangles and shades per "
                 "vertex (TPFL). Insets: the mesh edges drawn inside the white box "
                 "(ground beside the objects, where their shadows fall). Labels: FPS and masked "
                 "PSNR against the direct-only Mitsuba "
                 "path reference (last column), from the results store.", "",
                 *shared.markdown_table(CAPTION_HEADER, rows)]
        if subs:
            lines += ["", "Scene substitutions:", ""] + [f"- {s}" for s in subs]
        return lines


FIGURE = Figure34()
