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

from prtbench.reproduction import Cell, Figure

from . import _panels
from .table_3_1 import ensure_texture_methods, scene_choices

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

    def cells(self, profile: str) -> list[Cell]:
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
                cells.append(Cell(method=method, scene=scene, variant=VARIANT, views=1,
                                  scene_params=params,
                                  overrides=choice.overrides(method) if choice else {},
                                  label={"scene": scene, "column": column}))
        return cells

    def make(self, *, profile: str, reports_dir: Path, results_path: Path | None = None,
             progress: bool = True) -> list[Path]:
        from prtbench import imageio

        cells = self.cells(profile)
        runs = _panels.run_cells(cells, profile=profile, results_path=results_path,
                                 progress=progress, tag=f"figure {self.name}")
        by_key = {(r.cell.label["scene"], r.cell.label["column"]): r for r in runs}
        rows, row_labels, caption_rows = [], [], []
        spp = None
        for scene in self.scenes(profile):
            panels = []
            for column, (label, method, high) in enumerate(COLUMNS):
                run = by_key[(scene, column)]
                display = imageio.display(run.image, exposure=run.scene.exposure)
                h, w = display.shape[:2]
                view = run.scene.trajectory.views[0]
                edges, _ = _panels.render_wireframe(run.scene, view, width=WIRE_SCALE * w,
                                                    height=WIRE_SCALE * h)
                panel = _panels.wireframe_overlay(display, edges,
                                                  crop=CROPS.get(scene, DEFAULT_CROP))
                stored = run.rows
                fps = _panels.fps(stored)
                psnr = float(stored["metric_psnr_masked"].mean())
                panel = _panels.caption(panel, f"{fps:.3g} FPS  {psnr:.1f} dB")
                panels.append(panel)
                spp = int(stored["reference_spp"].iloc[0])
                caption_rows.append([
                    scene, label.replace("\n", " "), method, int(stored["scene_triangles"].iloc[0]),
                    fps, float(stored["frame_ms"].median()), psnr,
                    float(stored["metric_ssim_masked"].mean()),
                    float(stored["metric_flip_masked"].mean()),
                    float(stored["memory_bytes"].iloc[0]) / 2**20, run.run_id])
            reference = by_key[(scene, 0)].reference
            panels.append(_panels.caption(reference, "path reference"))
            rows.append(panels)
            first = by_key[(scene, 0)]
            row_labels.append(f"{scene}\n{first.scene.n_triangles} tris")
        image = _panels.grid(rows,
                             column_labels=[c[0] for c in COLUMNS] + [f"Mitsuba path\n{spp} spp"],
                             row_labels=row_labels, title=self.title + f" ({profile} profile)")
        reports_dir = Path(reports_dir)
        reports_dir.mkdir(parents=True, exist_ok=True)
        png = reports_dir / f"figure-{self.name}.png"
        imageio.write_png(png, image)
        md = _panels.write_caption(reports_dir / f"figure-{self.name}.md",
                                   self.caption_lines(runs, caption_rows, profile=profile,
                                                      size=image.shape))
        return [png, md]

    def caption_lines(self, runs, rows, *, profile: str, size) -> list[str]:
        frame = runs[0].rows
        renderer = ", ".join(sorted({str(r.rows["renderer"].iloc[0]) for r in runs}))
        timing = ", ".join(sorted({str(r.rows["timing_source"].iloc[0]) for r in runs}))
        width, height = int(frame["width"].iloc[0]), int(frame["height"].iloc[0])
        subs = sorted({r.scene.substitution for r in runs if r.scene.substitution})
        lines = [f"# {self.title}", "", f"Source: {self.paper}.", "",
                 f"![figure {self.name}](figure-{self.name}.png)", "",
                 f"Profile `{profile}`: panels {width}×{height} (image {size[1]}×{size[0]}), "
                 f"first trajectory view, glossy variants. GL renderer: {renderer}; timing: "
                 f"{timing}. On a CPU rasteriser (llvmpipe) FPS are comparable only within this "
                 "figure.", "",
                 "Columns 1–4 use each scene as built: a two-triangle ground (the room: a "
                 "two-triangle floor). Column 5 subdivides the ground/floor into "
                 f"2·{HIGH_SUBDIVISIONS}² = {2 * HIGH_SUBDIVISIONS**2} triangles and shades per "
                 "vertex (TPFL). Insets: the mesh edges drawn inside the white box "
                 "(ground beside the objects, where their shadows fall). Labels: FPS and masked "
                 "PSNR against the direct-only Mitsuba "
                 "path reference (last column), from the results store.", "",
                 *_panels.markdown_table(CAPTION_HEADER, rows)]
        if subs:
            lines += ["", "Scene substitutions:", ""] + [f"- {s}" for s in subs]
        return lines


FIGURE = Figure34()
