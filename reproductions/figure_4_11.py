"""Thesis figure 4.11: transfer at two surface points, back-projected onto the sphere.

For two held-out vertices of the main object (never training points), the transfer is shown as
a spherical function on a lat-long canvas (Mitsuba's envmap layout: +Y up at the top row): the
ray-traced cosine-weighted visibility V(ω)·max(n·ω, 0) itself, its SH projection T (ground
truth, the learnt method's band count, many rays), the MLP's regressed T̂, and |T − T̂|. The
thesis shows ROZA with TexturedPRT's transfer as ground truth; ours is the traced transfer the
texture baseline also stores.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from methods.learnt.data import heldout_samples
from methods.learnt.model import LearntModel
from prtbench.api.method import METHODS, load_or_precompute
from prtbench.bench.reproduction import Figure, Stored, provenance_line
from prtbench.bench.runner import device_description
from prtbench.scene.registry import get_scene
from prtbench.store import measurements
from prtbench.transport.latlong import lat_long_directions
from prtbench.transport.raytrace import Tracer, offset_origins
from prtbench.transport.sh import eval_sh
from prtbench.transport.transfer import compute_transfer
from reproductions import plots, shared
from reproductions.table_4_1 import ensure_methods, learnt_overrides

#: Measurement table of the figure's numbers (one row per point; canvases as images).
TABLE = "figure-4.11"
#: Canvas size (lat-long, 2:1) of each spherical panel.
CANVAS = (96, 192)
#: Rays of the ground-truth transfer at the two points.
TRUTH_RAYS = 8192
#: Control points of the colour map (dark blue -> teal -> yellow), value in [0, 1].
COLOURS = np.array([[0.05, 0.03, 0.25], [0.15, 0.35, 0.6], [0.1, 0.65, 0.6], [0.6, 0.85, 0.3],
                    [1.0, 0.95, 0.3]])


def colour_map(values: np.ndarray, *, top: float) -> np.ndarray:
    """(H, W) values in [0, top] -> (H, W, 3) colours; negatives (SH ringing) clip to 0."""
    t = np.clip(values / max(top, 1e-12), 0.0, 1.0) * (len(COLOURS) - 1)
    lo = np.minimum(np.floor(t).astype(int), len(COLOURS) - 2)
    frac = (t - lo)[..., None]
    return (1 - frac) * COLOURS[lo] + frac * COLOURS[lo + 1]


def canvas_directions() -> np.ndarray:
    """(H, W, 3) directions of the canvas texel centres (Mitsuba's lat-long mapping)."""

    h, w = CANVAS
    v, u = np.meshgrid((np.arange(h) + 0.5) / h, (np.arange(w) + 0.5) / w, indexing="ij")
    return lat_long_directions(u, v)


def pick_points(scene, heldout, transfer: np.ndarray) -> list[int]:
    """Two held-out vertices of the object with most vertices, self-shadowed, far apart.

    Normals facing up (n_y > 0.25) keep the ground's horizon from being the occluder, so the
    shadowing comes from the object itself (the thesis picks points in ROZA's hair).
    """

    main = int(np.argmax([o.mesh.n_vertices for o in scene.objects]))
    on_main = np.nonzero(heldout.object_ids == main)[0]
    upward = on_main[heldout.normals[on_main, 1] > 0.25]
    on_main = upward if len(upward) >= 2 else on_main
    fraction = transfer[on_main, 0] * math.sqrt(4 * math.pi) / math.pi  # unoccluded share
    order = on_main[np.argsort(np.abs(fraction - 0.55))]  # most mixed visibility first
    first = int(order[0])
    spread = 0.1 * scene.diagonal()
    far = [int(i) for i in order[1:]
           if np.linalg.norm(heldout.points[i] - heldout.points[first]) > spread]
    return [first, far[0] if far else int(order[1])]


class Figure411(Figure):
    name = "4.11"
    paper = ("Sirikonda (2023) thesis, figure 4.11: transfer at two points of ROZA back-projected "
             "on the sphere, ground truth (TexturedPRT) vs the MLP")
    title = "Figure 4.11: ground-truth vs regressed transfer at two points"
    substitutions = ("ROZA: the scanned `bust` (npm snowden, needs `make assets`).",)

    def __init__(self, *, scene: str = "bust", width: int = 128):
        self.scene_name, self.width = scene, width

    def measure(self, *, profile: str, results_path: Path | None, run_id: str,
                progress: bool = True) -> dict[str, dict]:

        ensure_methods()
        scene = get_scene(self.scene_name)
        cls = METHODS.get("learnt")
        config = cls.make_config(learnt_overrides(128, profile), profile=profile)
        cls.validate(scene, config)
        artifact = load_or_precompute(cls, scene, config, progress=progress)
        model = LearntModel.from_arrays(artifact.arrays)
        heldout = heldout_samples(scene, max_vertices=config.heldout_vertices,
                                  rays_per_point=config.heldout_rays, bands=config.sh_bands,
                                  seed=config.seed + 1, progress=progress)
        picks = pick_points(scene, heldout, heldout.transfer)
        points, normals = heldout.points[picks], heldout.normals[picks]
        truth = compute_transfer(scene, points, normals, bands=config.sh_bands,
                                 rays_per_point=TRUTH_RAYS, seed=11, progress=False,
                                 use_cache=False)
        learnt = model.predict(points, normals, heldout.object_ids[picks])
        dirs = canvas_directions()
        basis = eval_sh(dirs.reshape(-1, 3), config.sh_bands)
        tracer = Tracer.from_scene(scene)
        held = artifact.meta["heldout_vertices"]
        rows, images = [], {}
        for i, name in enumerate(("A", "B")):
            cosine = np.maximum(dirs.reshape(-1, 3) @ normals[i], 0.0)
            origins = offset_origins(np.repeat(points[i:i + 1], len(cosine), 0),
                                     np.repeat(normals[i:i + 1], len(cosine), 0),
                                     diagonal=scene.diagonal())
            visible = ~tracer.occluded(origins.astype(np.float32),
                                       dirs.reshape(-1, 3).astype(np.float32))
            gt = (basis @ truth[i]).reshape(CANVAS)
            mlp = (basis @ learnt[i]).reshape(CANVAS)
            images[f"{name}/raw"] = (visible * cosine).reshape(CANVAS)
            images[f"{name}/truth"], images[f"{name}/mlp"] = gt, mlp
            rows.append({"point": name, "position": points[i].astype(float).tolist(),
                         "normal": normals[i].astype(float).tolist(),
                         "relative_l2": float(np.linalg.norm(learnt[i] - truth[i])
                                              / np.linalg.norm(truth[i])),
                         "max_abs": float(np.abs(gt - mlp).max()),
                         "scene": scene.name, "substitution": scene.substitution or "as built",
                         "sh_bands": config.sh_bands, "hidden": config.hidden,
                         "layers": config.layers, "samples": config.samples,
                         "rays_per_point": config.rays_per_point, "epochs": config.epochs,
                         "heldout_points": held["points"], "heldout_relative_rms": held["relative_rms"],
                         "heldout_dc_relative": held["dc_relative"]})
        measurements.record(TABLE, shared.with_load(rows),
                            results_path=results_path, run_id=run_id,
                            profile=profile, device=device_description(), images=images)
        return {}

    def plot(self, stored: Stored, *, reports_dir: Path) -> list[Path]:
        profile = stored.profile
        table = stored.table(TABLE)
        stats = shared.records(table)
        images = stored.images()
        grid = [[colour_map(images[f"{r['point']}/raw"], top=1.0),
                 colour_map(images[f"{r['point']}/truth"], top=1.0),
                 colour_map(images[f"{r['point']}/mlp"], top=1.0),
                 colour_map(np.abs(images[f"{r['point']}/truth"] - images[f"{r['point']}/mlp"]),
                            top=0.25)] for r in stats]
        c = stats[0]
        labels = ["ray-traced V·cos", f"ground truth ({c['sh_bands']} bands)",
                  f"MLP k={c['hidden']}, l={c['layers']}", "|difference| (x4)"]
        png = plots.panel_grid(reports_dir / f"figure-{self.name}.png", grid,
                                column_labels=labels,
                                row_labels=[f"point {r['point']}" for r in stats],
                                title=self.title)
        lines = [f"# {self.title}", "", f"Source: {self.paper}", "",
                 f"Profile `{profile}`, scene `{c['scene']}` ({c['substitution']}), "
                 f"learnt k={c['hidden']}, l={c['layers']}, {c['sh_bands']} SH bands, "
                 f"{c['samples']} training points x {c['rays_per_point']} rays, "
                 f"{c['epochs']} epochs. Canvases are lat-long (+Y up at the top row), colour "
                 "0 (dark) to 1 (yellow); the difference column is scaled x4.",
                 f"Ground truth: {TRUTH_RAYS} rays per point projected to SH. The points are "
                 "held-out mesh vertices (never training points) of the object with most "
                 "vertices, facing up, chosen where the object shadows about half of the "
                 "cosine-weighted hemisphere.", "", provenance_line([table], profile=profile), ""]
        lines += shared.markdown_table(
            ["point", "position", "normal", "relative L2 error of T",
             "max abs ΔT(ω) on the canvas"],
            [[r["point"], np.round(np.asarray(r["position"]), 3).tolist(),
              np.round(np.asarray(r["normal"]), 3).tolist(), r["relative_l2"], r["max_abs"]]
             for r in stats])
        lines += ["", f"Held-out error of the network on {c['heldout_points']} vertices: relative "
                      f"RMS {c['heldout_relative_rms']:.4f}, DC {c['heldout_dc_relative']:.4f}."]
        if c["scene"] == "bust":
            lines += ["", *(f"Substitution: {s}" for s in self.substitutions)]
        caption = shared.write_caption(reports_dir / f"figure-{self.name}.md", lines)
        return [png, caption]


FIGURE = Figure411()
