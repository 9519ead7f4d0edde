"""``prtbench stability``: measure the matrix, store it, write the report (and JSON)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from prtbench.api import strict_json
from prtbench.api.cache import atomic_path
from prtbench.api.config import parse_overrides
from prtbench.api.errors import InvalidInputError, UnknownNameError
from prtbench.api.method import METHODS
from prtbench.bench import outputs
from prtbench.stability.case import PROFILES, case_base_scene
from prtbench.stability.cases import method_cases
from prtbench.stability.core import core_case_names
from prtbench.stability.importing import import_csv
from prtbench.stability.matrix import CORE, load_rows, plan, run_matrix, stored_rows, table_name
from prtbench.stability.report import method_summary, write_reports
from prtbench.store.results import default_path


def run(args: argparse.Namespace) -> int:
    """The subcommand; exit status 1 when any case ``failed`` (a bug), else 0.

    Every output location, the profile, the methods and the case names are checked before
    any case runs.
    """

    if args.profile not in PROFILES:

        raise UnknownNameError("stability profile", args.profile, PROFILES)
    if args.timeout is not None and not args.timeout > 0:

        raise InvalidInputError(f"--timeout {args.timeout}; accepted: seconds > 0")

    scene_file, scene_params, label = _scene(args)  # a bad file fails here, before any work
    methods = args.method or ([*METHODS.names()] if scene_file else [*METHODS.names(), CORE])
    results = Path(args.results) if args.results else None
    stem = f"table-stability-{label}" if label else "table-stability"
    outputs.check_folder("--reports", Path(args.reports))
    if args.json:
        outputs.check_file("--json", Path(args.json))
        for option, folder in (("--reports", args.reports), ("--out", args.out)):
            if folder:  # made before the JSON is written
                outputs.check_file_clear_of("--json", args.json, folder_option=option,
                                            folder=folder)
    if args.import_csv:
        _import(args, results, table_name(label))
        if not args.from_store:
            return 0
    if args.from_store:

        every = [*METHODS.names()] if scene_file else [*METHODS.names(), CORE]
        return _write(stored_rows(profile=args.profile, results_path=results,
                                  partial=args.partial, table=table_name(label)), args, None,
                      stem=stem, expected=expected_cases(every, profile=args.profile,
                                                         scene_file=scene_file,
                                                         scene_params=scene_params))
    if args.out:
        outputs.check_folder("--out", Path(args.out))
    outputs.check_results_store("--results", results or default_path())
    outputs.check_cache()
    plan(methods, profile=args.profile, cases=args.case, scene_file=scene_file,
         scene_params=scene_params)  # unknown names fail here
    print(f"[stability] profile={args.profile} methods={','.join(methods)}"
          + (f" scene={label}" if label else ""), file=sys.stderr)
    run_id = run_matrix(methods, profile=args.profile, results_path=results,
                        out_dir=Path(args.out) if args.out else None, cases=args.case,
                        timeout_s=args.timeout, echo=not args.quiet, scene_file=scene_file,
                        scene_params=scene_params)
    return _write(load_rows(run_id, results_path=results, table=table_name(label)), args,
                  run_id, stem=stem, expected=expected_cases(methods, profile=args.profile,
                                                             scene_file=scene_file,
                                                             scene_params=scene_params))


def expected_cases(methods, *, profile: str, scene_file=None, scene_params=None
                   ) -> dict[str, list[str]]:
    """Method -> its catalogue's case names at ``profile`` (the report's "Not measured" list);
    :data:`prtbench.stability.matrix.CORE` -> the SH core's row names."""

    return {m: (core_case_names(profile=profile) if m == CORE else
                [c.name for c in method_cases(METHODS.get(m), profile=profile,
                                              scene_file=scene_file, scene_params=scene_params)])
            for m in methods}


def _import(args: argparse.Namespace, results: Path | None, table: str) -> None:
    """``--import-csv``: the CSV's rows into the store, everything checked before the write
    (so that a following ``--from-store`` cannot fail on what was just stored)."""

    measuring = [flag for flag, value in (("--method", args.method), ("--case", args.case),
                                          ("--out", args.out), ("--timeout", args.timeout))
                 if value]
    reporting = [flag for flag, value in (("--json", args.json), ("--note", args.note),
                                          ("--partial", args.partial)) if value]
    if measuring or (reporting and not args.from_store):
        raise InvalidInputError(f"--import-csv with {', '.join(measuring or reporting)}; "
                                "accepted: --import-csv [--from-store [--partial] [--note TEXT] "
                                "[--json FILE]] (an import measures nothing)")
    outputs.check_results_store("--results", results or default_path())
    summary = import_csv(Path(args.import_csv), results_path=results, table=table,
                         profile=args.profile if args.from_store else None,
                         need_complete_run=args.from_store and not args.partial)
    print(f"imported {summary.complete_rows + summary.partial_rows} rows of {summary.source} "
          f"into {results or default_path()} (table {table}, profile {summary.profile}: "
          f"{summary.complete_rows} in complete run {summary.complete_run}, "
          f"{summary.partial_rows} of interrupted runs in {summary.partial_run}; "
          f"{summary.skipped_rows} already stored)", file=sys.stderr)


def _scene(args: argparse.Namespace):
    """``(scene, params, label)`` of ``--scene`` (all None without it), the scene built once so
    that a missing, unreadable or absurd file is a one-line error before anything is written.
    The label is the built scene's name (a file's carries its content hash)."""
    if not args.scene:
        if args.scene_param:

            raise InvalidInputError("--scene-param without --scene; accepted: --scene PATH "
                                    "--scene-param KEY=VALUE")
        return None, None, None

    params = parse_overrides(args.scene_param or [])
    scene = case_base_scene(args.scene, "diffuse", params)
    return args.scene, params, scene.name


def _write(rows, args: argparse.Namespace, run_id: str | None, *,
           stem: str = "table-stability", expected=None) -> int:
    """Reports (and JSON) of ``rows``; 1 when any row failed. ``expected``: method -> case
    names the report lists as not measured when they have no row."""

    for path in write_reports(rows, Path(args.reports), stem=stem, expected=expected,
                              notes=args.note or ()):
        print(f"wrote {path}")
    if args.json:

        with atomic_path(Path(args.json)) as tmp:
            tmp.write_text(strict_json.dumps({"run_id": run_id, "profile": args.profile,
                                              "rows": rows}, indent=2))
        print(f"wrote {args.json}")
    for method in dict.fromkeys(r["method"] for r in rows):
        print(method_summary(method, [r for r in rows if r["method"] == method]))
    failed = [r for r in rows if r["outcome"] == "failed"]
    if failed:
        print(f"prtbench: {len(failed)} stability case(s) failed: "
              f"{', '.join(r['method'] + ' ' + r['case'] for r in failed)}", file=sys.stderr)
        return 1
    return 0


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--method", action="append",
                   help="only these methods, or sh-core (default: every method and sh-core)")
    p.add_argument("--profile", default="quick", help="smoke or quick (default quick)")
    p.add_argument("--case", action="append", help="only these cases (the moderate one always runs)")
    p.add_argument("--scene", default=None,
                   help="an asset file (.glb/.gltf/.obj/.ply/.off/.stl) or scene name as every "
                        "method's base scene; the report is table-stability-<scene name>.*")
    p.add_argument("--scene-param", action="append", metavar="KEY=VALUE",
                   help="import parameter of --scene (files: scale, up, ground)")
    p.add_argument("--json", default=None, help="also write the rows here (strict JSON)")
    p.add_argument("--results", default=None, help="results database (default results/prtbench.sqlite)")
    p.add_argument("--reports", default="reports", help="folder of table-stability.{md,csv}")
    p.add_argument("--out", default=None, help="keep the cases' images here (default: discarded)")
    p.add_argument("--timeout", type=float, default=None,
                   help="seconds per case before it counts as a hang (default: smoke 300, quick 1200)")
    p.add_argument("--quiet", action="store_true", help="no per-case progress lines")
    p.add_argument("--from-store", action="store_true",
                   help="rewrite the report from the newest stored row of each case (no measuring)")
    p.add_argument("--import-csv", default=None, metavar="CSV",
                   help="store the rows of a written table-stability CSV (marked imported, each "
                        "with its own revision and time), e.g. when the store it came from is "
                        "gone; with --from-store, then rewrite the report")
    p.add_argument("--partial", action="store_true",
                   help="with --from-store: runs interrupted before their end count too (marked)")
    p.add_argument("--note", action="append", metavar="TEXT",
                   help="a line the report prints under 'Not measured' (why cases are missing)")
