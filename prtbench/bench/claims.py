"""The claims ledger: every checkable claim of the papers, decided from the results store.

DESIGN.md §20. A :class:`Claim` is declarative: its quote and source, the paper's value, the
report (a table or figure) whose newest complete stored run measures it, a ``measure`` function
that reads that run (an :class:`Evidence`) into a :class:`Measured`, and a ``rule`` that decides
the verdict from it. The verdicts:

``reproduced``
    the paper's direction holds beyond the intervals and its magnitude within the rule's band;
``direction only``
    the direction holds, but not beyond the intervals or not within the band;
``contradicted``
    the measured direction is the opposite (beyond the intervals or not: the rule says which);
    it carries an explanation naming a measurement (a report and its number), or says
    "unexplained";
``device-bound``
    a timing claim measured on a CPU rasteriser or CPU torch, which cannot test a GPU's frame
    rates: the verdict shows our timings and the operation-count model's prediction instead;
``not measurable here``
    the claim needs a scene, method or device this project does not have (the reason is given),
    or the store holds no run that answers it: the explanation then starts with
    :data:`NO_DATA` ("not measured in this store") and the command column measures it. Nothing
    is ever filled in for a claim the store cannot answer.

A claim without a report is *computed*: it counts something of our own bases (the tripling
coefficients of SH and Haar), deterministic and independent of the store.

Ledgers are found by name, like tables and figures: a package that registers tables or figures
(entry-point groups ``prtbench.tables`` / ``prtbench.figures``) declares its claims as the tuple
``CLAIMS`` of its ``claims`` module; other distributions add ``module:attr`` tuples under the
entry-point group ``prtbench.claims``.
"""

from __future__ import annotations

import dataclasses
import importlib
import importlib.util
import json
import math
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any

from prtbench.api.errors import PrtbenchError, UnknownNameError
from prtbench.store import measurements
from prtbench.store.results import COLUMNS, PROFILES, ResultsStore

REPRODUCED, DIRECTION, CONTRADICTED = "reproduced", "direction only", "contradicted"
DEVICE_BOUND, NOT_MEASURABLE = "device-bound", "not measurable here"
VERDICTS = (REPRODUCED, DIRECTION, CONTRADICTED, DEVICE_BOUND, NOT_MEASURABLE)
#: How the explanation of a claim the store has no data for starts (its verdict is
#: ``not measurable here``; the command column measures it).
NO_DATA = "not measured in this store"
#: Which complete run a claim reads when no profile is asked for: the most thorough one stored.
PROFILE_PREFERENCE = ("paper", "quick", "smoke")
CLAIMS_GROUP = "prtbench.claims"
REPORT_GROUPS = ("prtbench.tables", "prtbench.figures")
LEDGER_MODULE = "claims"
CSV_COLUMNS = ("id", "source", "section", "claim", "paper", "ours", "interval", "verdict",
               "explanation", "report", "profile", "run_id", "command")


class Missing(PrtbenchError):
    """The stored run lacks the rows a claim needs (the claim is then ``not measurable here``,
    its explanation starting with :data:`NO_DATA`)."""


@dataclass(frozen=True)
class Estimate:
    """One measured number with its 95 % interval (None where the rows carry none).

    ``label`` names the case (a scene, a configuration); ``detail`` is how it was formed.
    """

    value: float
    lo: float | None = None
    hi: float | None = None
    label: str = ""
    detail: str = ""

    def text(self, digits: int = 3) -> str:
        head = f"{self.label}: " if self.label else ""
        return f"{head}{self.value:.{digits}g}" + (f" ({self.detail})" if self.detail else "")

    def interval_text(self, digits: int = 3) -> str:
        if self.lo is None or self.hi is None:
            return ""
        head = f"{self.label}: " if self.label else ""
        return f"{head}[{self.lo:.{digits}g}, {self.hi:.{digits}g}]"


@dataclass
class Measured:
    """What a claim's ``measure`` read from the store.

    Attributes
    ----------
    cases : list of Estimate
        The numbers the rule decides on, one per case (scene, configuration, pair).
    text : str
        Ours, as people read it (with units; the paper's number is never here).
    gpu : bool or None
        For timing claims: whether every timing came from a GPU (None: not a timing).
    device : str
        The renderer(s) and timing source of the timings.
    prediction : str
        The operation-count model's prediction beside the paper's ratio (timing claims).
    facts : dict
        Further numbers an explanation may quote.
    """

    cases: list[Estimate]
    text: str = ""
    gpu: bool | None = None
    device: str = ""
    prediction: str = ""
    facts: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Decision:
    """A rule's verdict on the measured cases and the band it applied, in words."""

    verdict: str
    why: str


@dataclass(frozen=True)
class Claim:
    """One checkable claim of a source.

    Attributes
    ----------
    id : str
        Unique, e.g. ``prtt-3.1-fragment-faster``.
    source, section : str
        The paper and where in it.
    quote : str
        Short, from the paper's text.
    paper : str
        The paper's value or relation, in words and numbers.
    report : str or None
        ``"table NAME"`` or ``"figure NAME"``; None for a computed claim.
    measure : callable or None
        ``measure(evidence) -> Measured`` (``Evidence`` is None for a computed claim).
    rule : callable or None
        ``rule(measured) -> Decision``.
    explain : callable or None
        ``explain(evidence, measured) -> str or None``: for a contradiction, the measurement
        that explains it (None: unexplained).
    timing : bool
        A frame-time claim: measured on a CPU it is ``device-bound``.
    not_measurable : str
        Why this claim cannot be measured here (the verdict is then fixed).
    """

    id: str
    source: str
    section: str
    quote: str
    paper: str
    report: str | None = None
    measure: Callable[[Any], Measured] | None = None
    rule: Callable[[Measured], Decision] | None = None
    explain: Callable[[Any, Measured], str | None] | None = None
    timing: bool = False
    not_measurable: str = ""

    @property
    def kind_and_name(self) -> tuple[str, str]:
        kind, _, name = (self.report or "").partition(" ")
        return kind, name


# --- the store ------------------------------------------------------------------------------

class Evidence:
    """One complete report run, read from the store only (what a claim's ``measure`` sees).

    Parameters
    ----------
    report : prtbench.store.measurements.ReportRun
    store : _Store
        The shared reader (one load of the result rows for every claim).
    """

    def __init__(self, report, store: _Store):
        self.report, self._store = report, store
        self.kind, self.name = report.kind, report.name
        self.profile, self.run_id = report.profile, report.run_id
        self._frame = None
        self._tables: dict[str, Any] = {}
        #: Other report runs read through :meth:`other` (their provenance counts too).
        self.consulted: list[Evidence] = []

    def frame(self):
        """The result rows of the run's members, with ``label_<key>`` columns (a DataFrame)."""
        if self._frame is None:
            members = self.report.members
            rows = self._store.rows()
            frame = rows[rows["run_id"].isin(list(members))].copy() if len(rows) else rows.copy()
            for key in sorted({k for label in members.values() for k in label}):
                frame[f"label_{key}"] = [members.get(r, {}).get(key) for r in frame["run_id"]]
            self._frame = frame
        return self._frame

    def table(self, name: str):
        """Measurement table ``name`` of this run."""
        if name not in self._tables:
            self._tables[name] = measurements.load(name, run_ids=[self.run_id],
                                                   results_path=self._store.path)
        return self._tables[name]

    def merged(self, name: str):
        """The result rows joined with measurement table ``name`` on its ``cell_run_id``."""
        table, frame = self.table(name), self.frame()
        if not len(table) or not len(frame):
            return frame
        keep = [c for c in table.columns if c not in frame.columns or c == "cell_run_id"]
        return frame.merge(table[keep], how="left", left_on="run_id", right_on="cell_run_id")

    def images(self) -> dict:
        """The panels stored with this run, key -> ndarray (as stored)."""
        return measurements.load_images(self.run_id, results_path=self._store.path)

    def other(self, report: str) -> Evidence | None:
        """The newest complete run of another report (``"table NAME"``), this run's profile first."""
        found = self._store.evidence(report, prefer=self.profile)
        if found is not None and found not in self.consulted:
            self.consulted.append(found)
        return found

    def provenance_frames(self) -> list:
        """The frames read from this run (result rows, measurement tables, the report run's own
        commit): what :func:`provenance_text` summarises."""
        import pandas as pd

        frames = [pd.DataFrame({"git_sha": [self.report.git_sha]})]
        if self._frame is not None:
            frames.append(self._frame)
        return frames + list(self._tables.values())


class _Store:
    """Reads report runs and result rows of one results store, each once."""

    def __init__(self, path: Path, *, profile: str | None):
        self.path, self.profile = Path(path), profile
        self._rows = None
        self._cache: dict[tuple[str, str | None], Evidence | None] = {}

    def rows(self):
        """Every result row as a DataFrame, read only (JSON fields as text, ``metric_<name>``
        columns), like :func:`prtbench.store.results.load` but never migrating the file."""
        if self._rows is None:
            import pandas as pd

            records = []
            for row in ResultsStore(self.path, readonly=True).query():
                record = dataclasses.asdict(row)
                for name in ("config", "view_json", "metrics", "scene_params",
                             "frame_components", "memory_breakdown"):
                    record[name] = json.dumps(record[name], sort_keys=True)
                record.update({f"metric_{k}": math.nan if v is None else float(v)
                               for k, v in row.metrics.items()})
                records.append(record)
            self._rows = pd.DataFrame.from_records(records, columns=None if records
                                                   else list(COLUMNS))
        return self._rows

    def profiles(self, prefer: str | None = None) -> list[str]:
        if self.profile is not None:
            return [self.profile]
        return ([prefer] if prefer else []) + [p for p in PROFILE_PREFERENCE if p != prefer]

    def evidence(self, report: str, *, prefer: str | None = None) -> Evidence | None:
        key = (report, prefer)
        if key not in self._cache:
            kind, _, name = report.partition(" ")
            found = None
            for profile in self.profiles(prefer):
                run = measurements.latest_report(kind, name, profile=profile,
                                                 results_path=self.path)
                if run is not None:
                    found = Evidence(run, self)
                    break
            self._cache[key] = found
        return self._cache[key]

    def candidates(self, report: str) -> list[Evidence]:
        """The newest run of ``report`` for every profile allowed, most thorough first."""
        kind, _, name = report.partition(" ")
        runs = [measurements.latest_report(kind, name, profile=p, results_path=self.path)
                for p in self.profiles()]
        return [Evidence(r, self) for r in runs if r is not None]


# --- evaluation -----------------------------------------------------------------------------

@dataclass(frozen=True)
class Assessment:
    """A claim's verdict on one store, with what decided it."""

    claim: Claim
    verdict: str
    ours: str = ""
    interval: str = ""
    explanation: str = ""
    profile: str = ""
    run_id: str = ""
    command: str = ""
    #: The report runs the verdict read (the chosen run and those its explanation consulted).
    runs: tuple = ()

    @property
    def no_data(self) -> bool:
        """The store could not answer the claim (not a limit of the project)."""
        return self.explanation.startswith(NO_DATA)

    def row(self) -> list[str]:
        c = self.claim
        return [c.id, c.source, c.section, c.quote, c.paper, self.ours, self.interval,
                self.verdict, self.explanation, c.report or "computed (no store)", self.profile,
                self.run_id, self.command]


def _command(claim: Claim, profile: str) -> str:
    kind, name = claim.kind_and_name
    return f"prtbench {kind} {name} --profile {profile}" if claim.report else "prtbench claims"


def _intervals(measured: Measured) -> str:
    return "; ".join(t for t in (c.interval_text() for c in measured.cases) if t)


def assess(claim: Claim, store: _Store) -> Assessment:
    """The verdict of one claim on ``store``."""
    if claim.measure is None:  # nothing of ours to show: the reason is the verdict
        return Assessment(claim, NOT_MEASURABLE, explanation=claim.not_measurable)
    if claim.report is None:  # computed from our own bases, not from the store
        return _decide(claim, None, claim.measure(None), command=_command(claim, ""))
    candidates = store.candidates(claim.report)
    fallback = candidates[0].profile if candidates else (store.profile or "quick")
    chosen, measured, missing = None, None, ""
    for evidence in candidates:  # a GPU run answers a timing claim, else the most thorough
        try:
            result = claim.measure(evidence)
        except Missing as exc:
            missing = missing or str(exc)
            continue
        if chosen is None or (claim.timing and result.gpu and not measured.gpu):
            chosen, measured = evidence, result
    if measured is None:
        why = (f"{NO_DATA}: the stored {candidates[0].profile} run of {claim.report} cannot "
               f"answer it ({missing}); the command measures it again" if candidates else
               f"{NO_DATA}: no complete run of {claim.report}; the command measures it")
        return Assessment(claim, NOT_MEASURABLE,
                          explanation=claim.not_measurable or why, profile=fallback,
                          run_id=candidates[0].run_id if candidates else "",
                          command=_command(claim, fallback),
                          runs=(candidates[0],) if candidates else ())
    assessment = _decide(claim, chosen, measured, profile=chosen.profile, run_id=chosen.run_id,
                         command=_command(claim, chosen.profile))
    return dataclasses.replace(assessment, runs=(chosen, *chosen.consulted))


def _decide(claim: Claim, evidence: Evidence | None, measured: Measured,
            **base: str) -> Assessment:
    ours, interval = measured.text, _intervals(measured)
    if claim.not_measurable:
        return Assessment(claim, NOT_MEASURABLE, ours, interval, claim.not_measurable, **base)
    if claim.timing and not measured.gpu:
        text = (f"timed on {measured.device or 'a CPU'}: a CPU cannot test a GPU's frame-time "
                "ratios" + (f"; operation-count model: {measured.prediction}"
                            if measured.prediction else "; no operation-count analogue"))
        return Assessment(claim, DEVICE_BOUND, ours, interval, text, **base)
    try:
        decision = claim.rule(measured)
    except Missing as exc:
        return Assessment(claim, NOT_MEASURABLE, ours, interval,
                          f"{NO_DATA}: the stored run cannot answer it ({exc}); the command "
                          "measures it again", **base)
    explanation = decision.why
    if decision.verdict == CONTRADICTED:
        named = claim.explain(evidence, measured) if claim.explain else None
        explanation = (f"{decision.why}. Explained by: {named}" if named else
                       f"{decision.why}. unexplained: no stored measurement names the cause")
    return Assessment(claim, decision.verdict, ours, interval, explanation, **base)


def evaluate(claims: Sequence[Claim], *, results_path: str | Path,
             profile: str | None = None) -> list[Assessment]:
    """Every claim's verdict on the results store at ``results_path`` (read only).

    ``profile`` pins the runs read (default: per report the most thorough profile stored).
    """
    if profile is not None and profile not in PROFILES:
        raise PrtbenchError(f"unknown profile '{profile}'; accepted: {', '.join(PROFILES)}")
    store = _Store(Path(results_path), profile=profile)
    return [assess(claim, store) for claim in claims]


# --- discovery ------------------------------------------------------------------------------

def ledger_targets() -> list[str]:
    """``module:attr`` of every ledger: the ``claims`` module of each package registering tables
    or figures (where it has one), and the entry points of ``prtbench.claims``."""
    packages = sorted({ep.value.partition(":")[0].split(".")[0]
                       for group in REPORT_GROUPS for ep in metadata.entry_points(group=group)})
    targets = [f"{p}.{LEDGER_MODULE}:CLAIMS" for p in packages
               if importlib.util.find_spec(f"{p}.{LEDGER_MODULE}") is not None]
    return sorted(set(targets) | {ep.value for ep in metadata.entry_points(group=CLAIMS_GROUP)})


def all_claims() -> tuple[Claim, ...]:
    """Every registered claim, ledger by ledger; ids must be unique."""
    found: list[Claim] = []
    for target in ledger_targets():
        module, _, attr = target.partition(":")
        found += list(getattr(importlib.import_module(module), attr or "CLAIMS"))
    repeated = [i for i, n in Counter(c.id for c in found).items() if n > 1]
    if repeated:
        raise PrtbenchError(f"claim ids declared twice: {', '.join(sorted(repeated))}")
    return tuple(found)


# --- choosing claims ------------------------------------------------------------------------

def source_key(claim: Claim) -> str:
    """The short name of a claim's source: its id's first word (``prtt``, ``thesis``, ...)."""
    return claim.id.partition("-")[0]


def select(claims_: Sequence[Claim], sources: Sequence[str] | None) -> list[Claim]:
    """The claims of ``sources`` (short names as :func:`source_key`, or full source names, any
    case); every claim for None or empty. An unknown one is a :class:`UnknownNameError`."""
    if not sources:
        return list(claims_)
    known = {source_key(c) for c in claims_} | {c.source for c in claims_}
    lowered = {k.lower(): k for k in known}
    wanted = set()
    for name in sources:
        if name.lower() not in lowered:
            raise UnknownNameError("source", name, sorted({source_key(c) for c in claims_}))
        wanted.add(lowered[name.lower()])
    return [c for c in claims_ if source_key(c) in wanted or c.source in wanted]
