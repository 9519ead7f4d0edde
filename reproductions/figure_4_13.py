"""Thesis figure 4.13: the learnt transfer without and with positional encoding.

PLANTS with albedo disabled (every object a white diffuse kd = 0.8, so shadows read clearly, as
in the thesis) under the scene's light, rendered by the GLSL path with two networks that differ
only in ``pe_frequencies`` (0 = raw (p, n) inputs). A third panel shades the transfer traced at
every visible pixel with the same SH bands (the best any network can do: isolates the learning
error), a fourth is the Mitsuba path reference. Masked PSNRs against both are printed.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from methods.learnt.torch_renderer import shade_torch
from prtbench.api.config import with_overrides
from prtbench.api.method import METHODS, load_or_precompute
from prtbench.api.profiles import get_profile
from prtbench.bench import metrics
from prtbench.bench.reproduction import Figure, Stored, display_panels, provenance_line
from prtbench.bench.runner import device_description
from prtbench.io import imageio
from prtbench.render.prt_shading import tpfl_matrix_rgb
from prtbench.render.reference import render_reference
from prtbench.scene.model import Material, SceneObject
from prtbench.scene.registry import get_scene
from prtbench.store import measurements
from prtbench.transport.lights import get_light
from prtbench.transport.raytrace import geometry_mask
from prtbench.transport.transfer import compute_transfer
from reproductions import plots, shared
from reproductions.table_4_1 import ensure_methods, learnt_overrides

#: Width of the networks compared (the thesis does not state it; table 4.1's smaller one).
WIDTH = 64
#: Measurement table of the figure's numbers (one row per network; panels as images).
TABLE = "figure-4.13"
ALBEDO = (0.8, 0.8, 0.8)
ORACLE_RAYS = 1024


def white_scene(scene):
    """``scene`` with every material replaced by a white diffuse one ("albedo disabled")."""

    objects = [SceneObject(o.name, o.mesh, Material(kd=ALBEDO, name="white"))
               for o in scene.objects]
    return dataclasses.replace(scene, name=f"{scene.name}-white", objects=objects,
                               substitution=scene.substitution)


def traced_transfer_image(renderer, scene, view, light, *, bands: int) -> np.ndarray:
    """Shade the transfer traced at each covered pixel of the torch renderer's G-buffer."""
    import torch

    renderer.render(view, light)  # fills the G-buffers
    g = [renderer.target.read(i) for i in range(4)]
    covered = g[0][..., 3] > 0
    p, n = g[0][covered][:, :3], g[1][covered][:, :3]
    transfer = compute_transfer(scene, p, n, bands=bands, rays_per_point=ORACLE_RAYS, seed=5,
                                progress=False, use_cache=False)
    wo = np.asarray(view.eye, np.float32) - p
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    t = lambda a: torch.as_tensor(np.ascontiguousarray(a, np.float32))  # noqa: E731
    radiance = shade_torch(torch, t(transfer), t(tpfl_matrix_rgb(light.sh(bands), bands)),
                           t(g[2][covered][:, :3]), t(g[3][covered][:, :3]),
                           t(g[2][covered][:, 3]), t(n), t(wo), bands).numpy()
    image = np.zeros(covered.shape + (3,), np.float32)
    image[covered] = radiance
    return image


class Figure413(Figure):
    name = "4.13"
    paper = ("Sirikonda (2023) thesis, figure 4.13: MLP without (left) and with (right) "
             "positional encoding; albedo disabled so shadows show")
    title = "Figure 4.13: without vs with positional encoding (plants, albedo disabled)"
    substitutions = ("PLANTS: our procedural potted plants (`plants`), all materials white "
                     "diffuse kd = 0.8.",)

    def __init__(self, *, scene: str = "plants"):
        self.scene_name = scene

    def measure(self, *, profile: str, results_path: Path | None, run_id: str,
                progress: bool = True) -> dict[str, dict]:

        ensure_methods()
        prof = get_profile(profile)
        scene = white_scene(get_scene(self.scene_name)).with_views(1)
        view, light = scene.trajectory.views[0], get_light(scene.default_light)
        width, height = prof.width, prof.height
        cls = METHODS.get("learnt")
        base = cls.make_config(learnt_overrides(WIDTH, profile), profile=profile)
        images, facts, renderers = {}, {}, set()
        for label, frequencies in (("no PE", 0), ("PE", base.pe_frequencies)):
            config = with_overrides(base, {"pe_frequencies": frequencies})
            artifact = load_or_precompute(cls, scene, config, progress=progress)
            renderer = cls.renderer(scene, artifact, config, width=width, height=height)
            try:
                images[label] = renderer.render(view, light)
                renderers.add(str(getattr(renderer, "renderer_string", "")))
            finally:
                renderer.release()
            facts[label] = (frequencies, artifact.meta["heldout_vertices"],
                            artifact.meta["heldout_surface"])
        torch_config = with_overrides(base, {"renderer": "torch"})
        renderer = cls.renderer(scene, load_or_precompute(cls, scene, torch_config,
                                                          progress=progress),
                                torch_config, width=width, height=height)
        try:
            oracle = traced_transfer_image(renderer, scene, view, light, bands=base.sh_bands)
        finally:
            renderer.release()
        reference = render_reference(scene, light, view, width=width, height=height,
                                     spp=prof.reference_spp, bounces=0, progress=progress).image
        mask = geometry_mask(scene, view, width, height)
        shown = {k: imageio.display(v, exposure=scene.exposure) for k, v in
                 [*images.items(), ("traced", oracle), ("path", reference)]}
        rows = []
        for k in images:
            rows.append({
                "network": k, "pe_frequencies": facts[k][0],
                "psnr_masked_vs_traced": metrics.compute_metrics(
                    shown[k], shown["traced"], mask=mask)["psnr_masked"],
                "psnr_masked_vs_path": metrics.compute_metrics(
                    shown[k], shown["path"], mask=mask)["psnr_masked"],
                "heldout_vertex_relative_rms": facts[k][1]["relative_rms"],
                "heldout_surface_relative_rms": facts[k][2]["relative_rms"],
                "width": width, "height": height, "light": light.name, "hidden": WIDTH,
                "layers": base.layers, "sh_bands": base.sh_bands, "samples": base.samples,
                "rays_per_point": base.rays_per_point, "epochs": base.epochs,
                "reference_spp": prof.reference_spp})
        measurements.record(TABLE, shared.with_load(rows),
                            results_path=results_path, run_id=run_id,
                            profile=profile, renderer=", ".join(sorted(renderers - {""})),
                            device=device_description(), images=display_panels(shown))
        return {}

    def plot(self, stored: Stored, *, reports_dir: Path) -> list[Path]:
        profile = stored.profile
        table = stored.table(TABLE)
        rows = shared.records(table)
        shown = stored.images()
        c = rows[0]
        pe = next(r["pe_frequencies"] for r in rows if r["network"] == "PE")
        panels = [shown[r["network"]] for r in rows] + [shown["traced"], shown["path"]]
        captions = [f"{r['psnr_masked_vs_traced']:.1f} dB vs traced" for r in rows] + ["", ""]
        labels = [f"no positional encoding\n(k={c['hidden']})",
                  f"positional encoding F={pe}\n(k={c['hidden']})",
                  f"traced transfer per pixel\n({c['sh_bands']} SH bands)", "path reference"]
        png = plots.panel_grid(reports_dir / f"figure-{self.name}.png", [panels],
                                column_labels=labels, captions=[captions], title=self.title)
        lines = [f"# {self.title}", "", f"Source: {self.paper}", "",
                 f"Profile `{profile}`, {int(c['width'])}x{int(c['height'])}, first trajectory "
                 f"view, light `{c['light']}`; learnt k={c['hidden']}, l={c['layers']}, "
                 f"{c['sh_bands']} SH bands, {c['samples']} points x {c['rays_per_point']} rays, "
                 f"{c['epochs']} epochs, GLSL "
                 "path. 'traced transfer per pixel' shades transfer ray-traced at each visible "
                 f"pixel ({ORACLE_RAYS} rays) with the same bands and shading: the target the "
                 "networks learn, so PSNR against it is the learning error alone. The path "
                 "reference adds SH truncation.", "", provenance_line([table], profile=profile), ""]
        lines += shared.markdown_table(
            ["network", "PE frequencies", "PSNR masked vs traced (dB)",
             "PSNR masked vs path (dB)", "held-out vertex rel. RMS", "held-out surface rel. RMS"],
            [[r["network"], r["pe_frequencies"], r["psnr_masked_vs_traced"],
              r["psnr_masked_vs_path"], r["heldout_vertex_relative_rms"],
              r["heldout_surface_relative_rms"]] for r in rows])
        for s in self.substitutions:
            lines.append(f"\nSubstitution: {s}")
        caption = shared.write_caption(reports_dir / f"figure-{self.name}.md", lines)
        return [png, caption]


FIGURE = Figure413()
