"""``prtbench claims``: every checkable claim of the papers, decided from the results store.

Reads the store only (never runs anything): each claim's report run, its rule, its verdict
(:mod:`prtbench.bench.claims`); writes ``claims.md`` (provenance and verdict counts at the top,
one row per claim) and ``claims.csv`` into ``--reports``, each atomically. A claim whose report
has no run in the store is ``not measurable here`` with "not measured in this store" and the
command that measures it. A missing store, a bad folder or an unknown source is one line
(``prtbench: error: ...``, exit status 2) and writes nothing.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from prtbench.api.errors import InvalidInputError
from prtbench.bench import claims, claims_page, outputs
from prtbench.store.results import PROFILES, ResultsStore, default_path

EPILOG = """\
Verdicts:
  reproduced           the paper's direction beyond our 95 % intervals, its magnitude in
                       the claim's band
  direction only       the direction holds, not beyond the intervals or not in the band
  contradicted         the other way; the explanation names the measurement that explains
                       it, or says "unexplained"
  device-bound         a GPU timing claim timed on a CPU: our timings beside the
                       operation-count model's prediction
  not measurable here  the reason; "not measured in this store" when the store has no run
                       that answers it (the command column measures it)

Examples:
  prtbench claims                                  # the default store, into reports/
  prtbench claims --results results/reports-0123abcd.sqlite --reports out/claims
  prtbench claims --source nw --source prtt        # only these sources' claims
"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.formatter_class = argparse.RawDescriptionHelpFormatter
    p.epilog = EPILOG
    p.add_argument("--results", default=None, metavar="FILE",
                   help="the results store to read (default: $PRTBENCH_RESULTS, else "
                        "results/prtbench.sqlite); it must exist and is never written")
    p.add_argument("--reports", default="reports", metavar="FOLDER",
                   help="folder for claims.md and claims.csv (default: reports)")
    p.add_argument("--profile", default=None, choices=PROFILES,
                   help="read only this profile's runs (default: per report the most "
                        "thorough profile stored: paper, then quick, then smoke)")
    p.add_argument("--source", action="append", default=None, metavar="NAME",
                   help="only the claims of this source, repeatable: prtt, thesis, ddprt, nw, "
                        "lecture (or a full source name); default: all five")


def run(args: argparse.Namespace) -> int:
    results = Path(args.results) if args.results else default_path()
    reports = Path(args.reports)
    shown = claims_page.display_path(results)
    # Every input before any work: a bad one writes nothing.
    if results.is_dir():
        raise InvalidInputError(f"--results '{shown}' is a folder; accepted: a results store "
                                "file (see `prtbench results --help`)")
    if not results.exists():
        raise InvalidInputError(f"--results '{shown}' does not exist; accepted: a results store "
                                "written by `prtbench run`, `table`, `figure` or `make reports` "
                                "(default $PRTBENCH_RESULTS, else results/prtbench.sqlite)")
    ResultsStore(results).check()  # an SQLite store of ours; opened read-only
    everything = claims.all_claims()
    chosen = claims.select(everything, args.source)
    outputs.check_folder("--reports", reports)
    assessments = claims.evaluate(chosen, results_path=results, profile=args.profile)
    note = (f"Only the claims of {', '.join(args.source)} were asked for: {len(chosen)} of the "
            f"ledger's {len(everything)}." if args.source else "")
    paths = claims_page.write_reports(assessments, reports_dir=reports, results_path=results,
                                 note=note)
    print(claims_page.counts_text(assessments))
    unexplained = [a.claim.id for a in assessments
                   if a.verdict == claims.CONTRADICTED and "unexplained" in a.explanation]
    if unexplained:  # a contradiction no report explains is a defect of the reproduction
        print(f"prtbench: warning: {len(unexplained)} contradicted claim(s) name no explaining "
              f"measurement: {', '.join(unexplained)}", file=sys.stderr)
    for path in paths:
        print(f"wrote {path}")
    return 0
