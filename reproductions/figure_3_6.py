"""Thesis figure 3.6 (PRTT Fig. 6): normal maps with transfer textures.

The room (glossy) with its two-triangle floor, rendered by ``texture-tpfl`` without and with the
floor's tangent-space normal map (``normal_mapped_floor=True``): the precompute traces transfer
at the shading normal of every texel, so the tiles' bevels appear without a single extra
vertex (PRTT §6.2). Panels: without, with (wireframe inset of the floor), the mesh's wireframe,
and the difference the normal map makes.

No path metric for the normal-mapped render: our Mitsuba reference does not apply normal maps,
so comparing against it would measure the normal map itself as error. That render is therefore
*not* a runner cell (no result row claims an error for it): the figure renders it directly from
the cached artifact, times it with the profile's warm-up and frame counts and stores the timing
as measurement table ``figure-3.6``. The render
without a normal map is an ordinary runner cell, so its PSNR against the path reference is in
the results store.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from prtbench.api import config as config_mod
from prtbench.api.method import METHODS, load_or_precompute
from prtbench.api.profiles import get_profile
from prtbench.bench.job import Job
from prtbench.bench.reproduction import Figure, display_panels, provenance_line
from prtbench.bench.runner import device_description
from prtbench.io import imageio
from prtbench.scene.registry import get_scene
from prtbench.store import measurements
from prtbench.transport.lights import get_light
from reproductions import plots, shared
from reproductions.table_3_1 import ensure_texture_methods

SCENE = "room"
VARIANT = "glossy"
METHOD = "texture-tpfl"
#: Box of the wireframe inset: the floor in front of the table (first view).
CROP = (0.60, 0.98, 0.55, 0.98)
WIRE_SCALE = 2
#: Measurement table of the normal-mapped render's timing; panels as images.
TABLE = "figure-3.6"
#: Gain of the difference panel (display-space |with − without|).
DIFFERENCE_GAIN = 4.0


def render_direct(*, method: str, scene, profile: str, width: int, height: int,
                  progress: bool = True) -> dict:
    """Render and time ``method`` on ``scene``'s first view outside the runner.

    Returns
    -------
    dict
        ``image`` (H, W, 3) linear float32, ``frame_ms``, ``frame_ms_p95``, ``memory_bytes``,
        ``renderer``, ``timing_source``, ``config`` (dict).
    """

    cls = METHODS.get(method)
    config = cls.make_config(profile=profile)
    cls.validate(scene, config)
    light = get_light(scene.default_light)
    artifact = load_or_precompute(cls, scene, config, progress=progress)
    renderer = cls.renderer(scene, artifact, config, width=width, height=height)
    prof = get_profile(profile)
    view = scene.trajectory.views[0]
    try:
        image = renderer.render(view, light)
        times = renderer.frame_time(view, light, warmup=prof.timing_warmup,
                                    frames=prof.timing_frames)
        memory = renderer.memory_bytes()
    finally:
        renderer.release()
    return {"image": image, "frame_ms": times.median_ms, "frame_ms_p95": times.p95_ms,
            "memory_bytes": memory, "renderer": renderer.renderer_string, "timing_source": times.source,
            "config": config_mod.to_dict(config)}


class Figure36(Figure):
    name = "3.6"
    paper = ("Sirikonda (2023) thesis, figure 3.6 = PRTT (2022) Fig. 6: a minimally tessellated "
             "floor with a normal map, rendered with TPFL and transfer textures")
    title = "Figure 3.6: normal maps with transfer textures (room floor, texture TPFL)"

    def cells(self, profile: str) -> list[Job]:
        """The runner cell: the room without normal map (the normal-mapped render is direct)."""
        ensure_texture_methods()
        return [Job(method=METHOD, scene=SCENE, variant=VARIANT, views=1,
                     scene_params={"normal_mapped_floor": False},
                     label={"normal_map": False})]

    def measure(self, *, profile: str, results_path: Path | None, run_id: str,
                progress: bool = True) -> dict[str, dict]:

        cells = self.cells(profile)
        mapped_scene = get_scene(SCENE, variant=VARIANT, normal_mapped_floor=True).with_views(1)
        ensure_texture_methods()
        plain = shared.run_cells(cells, profile=profile, results_path=results_path,
                                  progress=progress, tag=f"figure {self.name}")[0]
        h, w = plain.image.shape[:2]
        print(f"[figure {self.name}] normal-mapped floor (direct render, no path metric)",
              flush=True)
        mapped = render_direct(method=METHOD, scene=mapped_scene, profile=profile, width=w,
                               height=h, progress=progress)
        exposure = plain.scene.exposure
        view = mapped_scene.trajectory.views[0]
        edges, _ = shared.render_wireframe(mapped_scene, view, width=WIRE_SCALE * w,
                                            height=WIRE_SCALE * h)
        images = {"without": imageio.display(plain.image, exposure=exposure),
                  "with": imageio.display(mapped["image"], exposure=exposure), "edges": edges}
        # The normal-mapped render is a timing outside the runner: stored with its renderer.
        row = {"render": "with normal map", "frame_ms": mapped["frame_ms"],
               "frame_ms_p95": mapped["frame_ms_p95"], "memory_bytes": mapped["memory_bytes"],
               "timing_source": mapped["timing_source"],
               "texture_resolution": mapped["config"]["texture_resolution"],
               "n_triangles": mapped_scene.n_triangles,
               "substitution": plain.scene.substitution or ""}
        measurements.record(TABLE, [row], results_path=results_path, run_id=run_id,
                            profile=profile, renderer=mapped["renderer"],
                            device=device_description(), images=display_panels(images))
        return {plain.run_id: dict(plain.cell.label)}

    def plot(self, stored, *, reports_dir: Path) -> list[Path]:
        profile = stored.profile
        stored_rows, images = stored.frame(), stored.images()
        table = stored.table(TABLE)
        mapped = shared.records(table)[0]
        without, with_map, edges = images["without"], images["with"], images["edges"]
        h, w = without.shape[:2]
        edges_1x = edges.reshape(h, WIRE_SCALE, w, WIRE_SCALE).mean(axis=(1, 3))
        plain_fps = shared.fps(stored_rows)
        mapped_fps = 1000.0 / mapped["frame_ms"]
        psnr = float(stored_rows["metric_psnr_masked"].mean())
        difference = np.clip(DIFFERENCE_GAIN * np.abs(with_map - without), 0, 1)
        wire = without * 0.45 + 0.55 * edges_1x[..., None] * np.asarray(shared.WIRE, np.float32)
        panels = [without, shared.wireframe_overlay(with_map, edges, crop=CROP),
                  wire.astype(np.float32), difference.astype(np.float32)]
        captions = [f"{plain_fps:.3g} FPS\npath PSNR {psnr:.1f} dB",
                    f"{mapped_fps:.3g} FPS\nno path metric", f"{int(mapped['n_triangles'])} tris",
                    f"|difference| x{DIFFERENCE_GAIN:g}"]
        png = plots.panel_grid(reports_dir / f"figure-{self.name}.png", [panels],
                                captions=[captions], title=self.title + f" ({profile} profile)",
                                column_labels=["without normal map", "with normal map",
                                               "wireframe (2-triangle floor)",
                                               "effect of the normal map"])
        floor_mask = np.abs(with_map - without).max(axis=-1) > 1.0 / 255
        header = ("render", "source", "FPS", "frame ms", "PSNR masked vs path (dB)",
                  "memory MiB", "timing", "GL renderer")
        run_id = str(stored_rows["run_id"].iloc[0])
        rows = [
            ["without normal map", f"results store, run {run_id}", plain_fps,
             float(stored_rows["frame_ms"].median()), psnr,
             float(stored_rows["memory_bytes"].iloc[0]) / 2**20,
             str(stored_rows["timing_source"].iloc[0]), str(stored_rows["renderer"].iloc[0])],
            ["with normal map", f"measurement table `{TABLE}`, run {stored.run_id}", mapped_fps,
             mapped["frame_ms"], "no path metric", mapped["memory_bytes"] / 2**20,
             mapped["timing_source"], str(table["renderer"].iloc[0])],
        ]
        lines = [
            f"# {self.title}", "", f"Source: {self.paper}.", "",
            f"![figure {self.name}](figure-{self.name}.png)", "",
            f"Profile `{profile}`: panels {w}×{h}, first trajectory view of `{SCENE}` "
            f"({VARIANT}), texture resolution {int(mapped['texture_resolution'])}², "
            f"{int(mapped['n_triangles'])} triangles with or without the normal map (the floor "
            "stays two triangles).", "", provenance_line([stored_rows, table], profile=profile), "",
            "**No path metric for the normal-mapped render:** our Mitsuba reference does not "
            "apply normal maps, so it is not compared with it, and the figure renders and times "
            "it outside the runner (a measurement row without error metrics). The render without "
            "the normal map is a runner cell; its masked PSNR against the direct-only path "
            "reference is stored.", "",
            f"The normal map changes {100 * floor_mask.mean():.1f} % of the pixels by more "
            "than one display level (last panel, |with − without| × "
            f"{DIFFERENCE_GAIN:g}).", "",
            *shared.markdown_table(header, rows),
            "", f"Scene substitution: {mapped['substitution']}.",
        ]
        md = shared.write_caption(reports_dir / f"figure-{self.name}.md", lines)
        return [png, md]


FIGURE = Figure36()
