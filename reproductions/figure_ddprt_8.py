"""Belcour et al. 2022, Fig. 8: relighting inside versus outside the dataset's lighting family.

The basis and transfer matrix are learnt from random spot lights (``spot`` family) in ``room``
(our stand-in for the VIKING room). We relight with a held-out spot light (in distribution)
and with a directional light (out of distribution) and compare with Mitsuba: total images
(direct + indirect) and indirect-only images, with the indirect RMSE of ours and of the
projection of the path-traced lightmap onto the basis (what the basis could represent).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from methods.data_driven.evaluation import held_out, image_study
from methods.data_driven.lights import DirectionalLight
from methods.data_driven.method import DataDrivenPRT
from prtbench.api.cache import atomic_path
from prtbench.api.profiles import get_profile
from prtbench.bench.reproduction import Figure, Stored, display_panels, provenance_line, write_csv
from prtbench.bench.runner import device_description
from prtbench.io.imageio import display
from prtbench.render import gl
from prtbench.scene.registry import get_scene
from prtbench.store import measurements
from reproductions import plots, shared

SCENE = "room"
#: Measurement table of the figure's numbers (one row per light).
TABLE = "figure-ddprt-8"
SETTINGS = {
    "smoke": {"overrides": {"configurations": 6, "paths_per_texel": 4, "basis": 4,
                            "lightmap_resolution": 256}, "image": (64, 48)},
    "quick": {"overrides": {"configurations": 64, "basis": 16}, "image": (320, 240)},
    "paper": {"overrides": {"configurations": 128, "basis": 16}, "image": (960, 540)},
}
#: The out-of-distribution light: a sun-like directional light from the front right, above.
DIRECTIONAL = {"to_light": (0.45, 0.75, 0.5), "irradiance": (2.0, 2.0, 2.0)}


class FigureDdprt8(Figure):
    name = "ddprt-8"
    paper = ("Belcour, Deliot, Barbier, Soler: A Data-Driven Paradigm for Precomputed Radiance "
             "Transfer (SIGGRAPH 2022), Fig. 8 (spot light in the dataset's family vs another "
             "light type)")
    title = "Data-driven PRT: in-distribution (spot) versus out-of-distribution (directional) light"
    substitutions = (
        "`room` (procedural room with table, chairs and rug) stands in for the VIKING room.",
        "Out of distribution: a directional light, as the issue asks (the paper moved point "
        "lights close to the surface).",
    )

    def measure(self, *, profile: str, results_path: Path | None, run_id: str,
                progress: bool = True) -> dict[str, dict]:

        settings = SETTINGS.get(profile, SETTINGS["quick"])
        scene = get_scene(SCENE)
        config = DataDrivenPRT.make_config({**settings["overrides"], "light_family": "spot"},
                                           profile=profile)
        DataDrivenPRT.validate(scene, config)
        width, height = settings["image"]
        spp = get_profile(profile).reference_spp
        view = scene.trajectory.views[0]
        cases = [("in distribution: held-out spot", held_out(scene, config, 1)[0]),
                 ("out of distribution: directional", DirectionalLight(**DIRECTIONAL, name="sun"))]
        rows, images = [], {}
        exposure = scene.exposure
        for title, light in cases:
            study = image_study(scene, config, light, view=view, width=width, height=height,
                                spp=spp, with_direct=True, progress=progress)
            ours_total = study.direct_ours + study.ours
            ref_total = study.direct_reference + study.reference
            ref_rms = float(np.sqrt(np.mean(study.reference[study.mask] ** 2)))
            total_rmse = float(np.sqrt(np.mean((ours_total - ref_total)[study.mask] ** 2)))
            rows.append({"case": title, "light": light.name, "indirect_rmse": study.ours_rmse,
                         "indirect_rmse_relative": study.ours_rmse / ref_rms,
                         "projection_rmse": study.projection_rmse,
                         "projection_rmse_relative": study.projection_rmse / ref_rms,
                         "total_rmse": total_rmse,
                         "reference_noise_rmse": study.reference_noise_rmse,
                         "width": width, "height": height, "reference_spp": spp,
                         "bounces": config.bounces})
            gain = exposure * 4.0
            short = "spot" if "spot" in title else "directional"
            images.update({
                f"{short}: ours": display(ours_total, exposure=exposure),
                f"{short}: Mitsuba": display(ref_total, exposure=exposure),
                f"{short}: ours indirect x4": display(study.ours, exposure=gain),
                f"{short}: Mitsuba indirect x4": display(study.reference, exposure=gain),
                f"{short}: |indirect error| x4": shared.error_image(study.ours, study.reference,
                                                                     scale=gain)})
        measurements.record(TABLE, shared.with_load(rows),
                            results_path=results_path, run_id=run_id,
                            profile=profile, renderer=gl.renderer_string(),  # image_study's GL
                            device=device_description(), images=display_panels(images))
        return {}

    def plot(self, stored: Stored, *, reports_dir: Path) -> list[Path]:
        profile = stored.profile
        settings = SETTINGS.get(profile, SETTINGS["quick"])
        table = stored.table(TABLE)
        records = shared.records(table)
        images = stored.images()
        png = plots.titled_grid(reports_dir / f"figure-{self.name}.png", images,
                                 columns=5)
        header = ["case", "light", "indirect_rmse", "indirect_rmse_relative", "projection_rmse",
                  "projection_rmse_relative", "total_rmse", "reference_noise_rmse"]
        rows = [[r[h] for h in header] for r in records]
        csv_path = write_csv(reports_dir / f"figure-{self.name}.csv", header, rows)
        first = records[0]
        width, height, spp = int(first["width"]), int(first["height"]), int(first["reference_spp"])
        md = reports_dir / f"figure-{self.name}.md"
        lines = [f"# {self.title}", "", f"Source: {self.paper}", "",
                 f"Profile `{profile}`, scene `{SCENE}` view 0, {width}x{height}; dataset: "
                 f"`spot` family, overrides {settings['overrides']}. Reference kind: `path` "
                 f"(Mitsuba 3, {spp} spp; indirect = max_depth {int(first['bounces']) + 2} minus "
                 "max_depth 2 with shared seeds). RMSE on linear radiance over geometry pixels; "
                 "'relative' divides by the reference indirect's RMS. The projection row is the "
                 "path-traced lightmap projected onto the same basis and drawn by the same shader.",
                 "", provenance_line([table], profile=profile),
                 "", "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
        lines += ["| " + " | ".join(f"{v:.4g}" if isinstance(v, float) else str(v) for v in row)
                  + " |" for row in rows]
        lines += ["", "Panels per row: ours (direct + indirect), Mitsuba, ours indirect ×4, "
                  "Mitsuba indirect ×4, |indirect error| ×4 (grey).", "",
                  "## Scene substitutions", "", *[f"- {s}" for s in self.substitutions]]
        with atomic_path(md) as tmp:
            tmp.write_text("\n".join(lines) + "\n")
        return [png, csv_path, md]


FIGURE = FigureDdprt8()
