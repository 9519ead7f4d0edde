"""Belcour et al. 2022, Fig. 12: data-driven PRT against classic (vertex, SH) PRT under a sun.

``lion`` lit by the ``sun`` light (a 1.75° disc, nearly directional), one indirect bounce, from a
view that sees the side turned away from the sun. Classic PRT (our ``vertex`` method, Sloan
2002, with interreflected transfer) band-limits the incident light to 5 SH bands, so light
*leaks* behind the object and shadows blur; it also interpolates per vertex. The data-driven
method draws direct light with shadow maps and reconstructs the indirect light from its
lightmap basis (family: the ``sun`` map turned about +Y). We report masked PSNR against the
Mitsuba reference and the mean radiance over the pixels that the sun does not reach (facing
away or shadowed): the leak.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from methods.data_driven.method import DataDrivenPRT
from prtbench.api.cache import atomic_path
from prtbench.api.method import METHODS, load_or_precompute
from prtbench.api.profiles import get_profile
from prtbench.bench import metrics
from prtbench.bench.reproduction import Figure, Stored, display_panels, provenance_line, write_csv
from prtbench.bench.runner import device_description
from prtbench.io.imageio import display
from prtbench.render.reference import render_reference
from prtbench.scene.registry import get_scene
from prtbench.store import measurements
from prtbench.transport.lights import get_light
from prtbench.transport.raytrace import Tracer, geometry_mask, offset_origins
from reproductions import plots, shared
from scenes.lights import SUN_DIRECTION

SCENE = "lion"
SCENE_PARAMS = {"ground_subdivisions": 48}  # fair to vertex PRT: its ground can hold a shadow
LIGHT = "sun"
#: Measurement table of the figure's numbers (one row per image).
TABLE = "figure-ddprt-12"
SETTINGS = {
    "smoke": {"ours": {"configurations": 6, "paths_per_texel": 4, "basis": 4}, "vertex": {},
              "image": (64, 48)},
    "quick": {"ours": {"configurations": 32, "basis": 16}, "vertex": {}, "image": (320, 240)},
    "paper": {"ours": {"configurations": 128, "basis": 16}, "vertex": {}, "image": (960, 720)},
}


def unlit_mask(scene, view, width: int, height: int, direction: np.ndarray) -> np.ndarray:
    """(H, W) bool: geometry pixels whose surface faces away from ``direction`` or is shadowed."""

    tracer = Tracer.from_scene(scene)
    origins, dirs = view.primary_rays(width, height)
    hits = tracer.first_hit(origins.reshape(-1, 3), dirs.reshape(-1, 3))
    mask = np.zeros(width * height, dtype=bool)
    ok = np.flatnonzero(hits.hit)
    tri = tracer.faces[hits.face[ok]]
    u, v = hits.u[ok, None].astype(float), hits.v[ok, None].astype(float)
    n = tracer.normals.astype(float)
    normal = (1 - u - v) * n[tri[:, 0]] + u * n[tri[:, 1]] + v * n[tri[:, 2]]
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    points = origins.reshape(-1, 3)[ok] + dirs.reshape(-1, 3)[ok] * hits.t[ok, None]
    facing = normal @ direction > 0
    blocked = np.ones(len(ok), dtype=bool)
    idx = np.flatnonzero(facing)
    blocked[idx] = tracer.occluded(offset_origins(points[idx], normal[idx], diagonal=tracer.diagonal),
                                   np.broadcast_to(direction, (len(idx), 3)))
    mask[ok] = blocked
    return mask.reshape(height, width)


class FigureDdprt12(Figure):
    name = "ddprt-12"
    paper = ("Belcour, Deliot, Barbier, Soler: A Data-Driven Paradigm for Precomputed Radiance "
             "Transfer (SIGGRAPH 2022), Fig. 12 (comparison with classical PRT on the LION under "
             "a directional light)")
    title = "Data-driven PRT versus classic vertex PRT under a sun: the SH leak"
    substitutions = (
        "`lion` (CGAL lion head on a plaque, ground split into 48² quads) stands in for the "
        "paper's LION.",
        "The directional light is our `sun` environment light (1.75° disc + 0.02 background), "
        "which the Mitsuba reference renders as a map.",
    )

    def measure(self, *, profile: str, results_path: Path | None, run_id: str,
                progress: bool = True) -> dict[str, dict]:

        settings = SETTINGS.get(profile, SETTINGS["quick"])
        scene = get_scene(SCENE, **SCENE_PARAMS).with_views(1)
        light = get_light(LIGHT)
        view = scene.trajectory.views[0]
        width, height = settings["image"]
        spp = get_profile(profile).reference_spp
        ours_cfg = DataDrivenPRT.make_config({**settings["ours"], "environment": LIGHT},
                                             profile=profile)
        vertex_cls = METHODS.get("vertex")
        vertex_cfg = vertex_cls.make_config({**settings["vertex"], "bounces": ours_cfg.bounces},
                                            profile=profile)
        renders, renderer_names = {}, set()
        for label, cls, cfg in (("data-driven", DataDrivenPRT, ours_cfg),
                                (f"vertex PRT ({vertex_cfg.sh_bands} bands)", vertex_cls, vertex_cfg)):
            cls.validate(scene, cfg)
            artifact = load_or_precompute(cls, scene, cfg, progress=progress)
            renderer = cls.renderer(scene, artifact, cfg, width=width, height=height)
            try:
                renders[label] = renderer.render(view, light)
                renderer_names.add(str(getattr(renderer, "renderer_string", "")))
            finally:
                renderer.release()
        ref = render_reference(scene, light, view, width=width, height=height, spp=spp,
                               bounces=ours_cfg.bounces, progress=progress)
        mask = geometry_mask(scene, view, width, height)
        unlit = unlit_mask(scene, view, width, height, np.asarray(SUN_DIRECTION))
        ref_d = display(ref.image, exposure=scene.exposure)
        ref_unlit = float(ref.image[unlit].mean())
        common = {"width": width, "height": height, "reference_spp": spp,
                  "reference_noise_display": ref.noise_rmse_display, "bounces": ours_cfg.bounces,
                  "unlit_pixels": int(unlit.sum()), "geometry_pixels": int(mask.sum()),
                  "vertex_sh_bands": vertex_cfg.sh_bands,
                  "vertex_rays_per_point": vertex_cfg.rays_per_point,
                  "vertex_bounces": vertex_cfg.bounces}
        rows = [{"image": "Mitsuba reference", "psnr_masked_db": None, "flip_masked": None,
                 "mean_radiance_unlit": ref_unlit, "unlit_vs_reference": 1.0, **common}]
        images = {f"Mitsuba ({spp} spp, {ours_cfg.bounces} bounce)": ref_d}
        errors = {"|error| x4": np.zeros_like(ref_d)}
        for label, image in renders.items():
            d = display(image, exposure=scene.exposure)
            values = metrics.compute_metrics(d, ref_d, mask=mask)
            leak = float(image[unlit].mean())
            rows.append({"image": label, "psnr_masked_db": values["psnr_masked"],
                         "flip_masked": values["flip_masked"], "mean_radiance_unlit": leak,
                         "unlit_vs_reference": leak / ref_unlit, **common})
            images[label] = d
            errors[f"{label}: |error| x4"] = shared.error_image(image, ref.image,
                                                                 scale=4.0 * scene.exposure)
        measurements.record(TABLE, shared.with_load(rows),
                            results_path=results_path, run_id=run_id,
                            profile=profile, renderer=", ".join(sorted(renderer_names - {""})),
                            device=device_description(),
                            images=display_panels({**images, **errors}))
        return {}

    def plot(self, stored: Stored, *, reports_dir: Path) -> list[Path]:
        profile = stored.profile
        settings = SETTINGS.get(profile, SETTINGS["quick"])
        table = stored.table(TABLE)
        records = shared.records(table)
        images = stored.images()
        png = plots.titled_grid(reports_dir / f"figure-{self.name}.png", images,
                                 columns=3)
        header = ["image", "psnr_masked_db", "flip_masked", "mean_radiance_unlit",
                  "unlit_vs_reference"]
        rows = [[r[h] for h in header] for r in records]
        csv_path = write_csv(reports_dir / f"figure-{self.name}.csv", header, rows)
        first = records[0]
        md = reports_dir / f"figure-{self.name}.md"
        lines = [f"# {self.title}", "", f"Source: {self.paper}", "",
                 f"Profile `{profile}`, scene `{SCENE}` {SCENE_PARAMS}, light `{LIGHT}`, view 0, "
                 f"{int(first['width'])}x{int(first['height'])}, direct + {int(first['bounces'])} "
                 f"indirect bounce. Reference kind: `path` (Mitsuba 3, "
                 f"{int(first['reference_spp'])} spp, display noise "
                 f"{first['reference_noise_display']:.4f}). data-driven: "
                 f"{settings['ours'] or 'profile defaults'} (family env-rotations of `{LIGHT}`); "
                 f"vertex: {int(first['vertex_sh_bands'])} SH bands, "
                 f"{int(first['vertex_rays_per_point'])} rays, {int(first['vertex_bounces'])} bounce.",
                 "", provenance_line([table], profile=profile), "",
                 f"'Unlit' pixels ({int(first['unlit_pixels'])} of {int(first['geometry_pixels'])} "
                 "geometry pixels) face away from the sun or are shadowed; their mean linear "
                 "radiance above the reference's is light leaking where the sun cannot reach.", "",
                 "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
        lines += ["| " + " | ".join(f"{v:.4g}" if isinstance(v, float) else str(v) for v in row)
                  + " |" for row in rows]
        lines += ["", "## Scene substitutions", "", *[f"- {s}" for s in self.substitutions]]
        with atomic_path(md) as tmp:
            tmp.write_text("\n".join(lines) + "\n")
        return [png, csv_path, md]


FIGURE = FigureDdprt12()
