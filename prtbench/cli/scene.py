"""``prtbench scene``: inspect an asset file (or a built-in scene) as a prtbench scene."""

from __future__ import annotations

import argparse

import numpy as np

from prtbench.api.config import parse_overrides
from prtbench.scene.files import is_scene_path, read_scene_file
from prtbench.scene.registry import get_scene


def add_arguments(p: argparse.ArgumentParser) -> None:
    scene_sub = p.add_subparsers(dest="scene_command", required=True)
    p = scene_sub.add_parser("info", help="counts, bounds, mapped materials and repairs of a file")
    p.add_argument("path", help=".glb/.gltf/.obj/.ply/.off/.stl file, or a built-in scene's name")
    p.add_argument("--variant", default="diffuse", help="material variant: diffuse or glossy")
    p.add_argument("--scene-param", action="append", metavar="KEY=VALUE",
                   help="import parameter: scale=<float>, up=y|z, ground=true|false")


def run(args: argparse.Namespace) -> int:
    params = parse_overrides(args.scene_param or [])
    if is_scene_path(args.path):
        scene, report = read_scene_file(args.path, variant=args.variant, **params)
    else:  # a built-in scene's name: the same summary, without the import's repairs
        scene, report = get_scene(args.path, variant=args.variant, **params), None
    lo, hi = scene.world_bounds()  # the user's units (rendered in the canonical frame)

    def value(v) -> str:
        return v.name if hasattr(v, "image") else (
            f"{v:g}" if isinstance(v, float) else "(" + ", ".join(f"{c:.3f}" for c in v) + ")")

    source = (f"from {report.path}, sha256 {report.sha256[:16]}"
              + (f" (+ {len(report.sidecars)} sidecar files)" if report.sidecars else "")
              if report else "built in")
    print(f"scene {scene.name} ({scene.variant}) {source}")
    print(f"  {len(scene.objects)} objects, {scene.n_triangles} triangles, "
          f"{scene.n_vertices} vertices")
    print(f"  bounds ({', '.join(f'{c:.4g}' for c in lo)}) .. ({', '.join(f'{c:.4g}' for c in hi)})"
          f", diagonal {float(np.linalg.norm(hi - lo)):.4g}")
    frame = scene.world_from_canonical
    if not frame.is_identity:
        print(f"  rendered in the canonical frame: world = {frame.scale:.6g} · p + "
              f"({', '.join(f'{c:.6g}' for c in frame.offset)})")
    views = (f"{report.cameras} from the file" if report and report.cameras
             else f"{len(scene.trajectory)} views")
    print(f"  views: {views}; default light {scene.default_light}")
    if report:
        print(f"  repaired: {report.degenerate_faces} degenerate and {report.duplicate_faces} "
              f"duplicate faces removed, normals computed for {report.normals_computed} objects; "
              f"{report.non_manifold_edges} non-manifold edges (kept)")
    for o in scene.objects:
        m = o.material
        print(f"  object {o.name}: {o.mesh.n_triangles} tris, material {m.name}: kd {value(m.kd)}"
              f" ks {value(m.ks)} s {value(m.shininess)}"
              f"{f' normal map {m.normal_map.name}' if m.normal_map is not None else ''}")
    for line in (report.skipped if report else []):
        print(f"  skipped: {line}")
    for line in (report.warnings if report else []):
        print(f"  warning: {line}")
    return 0
