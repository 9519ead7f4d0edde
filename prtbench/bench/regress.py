"""Golden-metric regression (DESIGN.md §13) gated by trivial images (issue #12).

Every registered method runs in the ``smoke`` profile on its regression case (by default
``plants`` diffuse under ``sky``, one view; a method's ``regression_case`` class attribute
overrides scene, variant and light, and may add ``scene_params`` and config ``overrides``
where the smoke profile alone is too small to beat the trivial images; its
``regression_variants`` add further cases ``method:variant`` with their own config overrides,
e.g. a compressed form of the method's transfer) and

1. its masked metrics must beat every trivial image of the same reference by the margins of
   :mod:`prtbench.bench.trivial` (the flat mean-colour image, the half-bright reference and, for
   methods with a ``visibility`` knob, the method's own unshadowed render), otherwise it FAILs
   whatever its baseline says;
2. its metrics are compared with ``tests/baselines/metrics.json``, which stores each value
   with an explicit tolerance. A method missing from the baselines is a FAIL, not a pass.

Only ``prtbench regress --update`` rewrites the file, and only when every updated method passes
the gate. Runs use a fresh temporary cache unless ``cache`` is given, so a precompute change
without a version bump cannot pass against stale artifacts.

A cases file (:mod:`prtbench.bench.regress_cases`, ``--cases``) replaces the built-in cases by a
team's own (its scene files, its plug-in methods) with a baseline file of its own. Every verdict
is a :class:`~prtbench.bench.regress_report.Check`, printed as it comes and, with ``junit_path``
(``--junit``), written as JUnit XML at the end.
"""

from __future__ import annotations

import json
import math
import os
import sys
import tempfile
import time
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from prtbench.api.cache import atomic_path
from prtbench.api.errors import InvalidInputError, UnknownNameError
from prtbench.api.method import METHODS
from prtbench.bench.cluster import cores, one_line
from prtbench.bench.executors import Lost, make_executor
from prtbench.bench.job import Job
from prtbench.bench.metrics import LDR_METRICS
from prtbench.bench.outputs import check_file
from prtbench.bench.regress_cases import DEFAULT_CASE, PROFILE, RegressionCase, load_cases
from prtbench.bench.regress_report import (BASELINE_TEST, GATE_TEST, Check, error_checks,
                                           failed, metric_check, write_junit)
from prtbench.bench.runner import prepare
from prtbench.bench.submit import run
from prtbench.bench.trivial import GATE_METRICS, gate_failures, trivial_scores, visibility_knob
from prtbench.io.assets import assets_root
from prtbench.render.reference import render_reference
from prtbench.transport.raytrace import geometry_mask

DEFAULT_BASELINES = Path(__file__).resolve().parents[2] / "tests" / "baselines" / "metrics.json"
#: Absolute tolerances per metric: wide enough for Monte-Carlo and rasteriser differences
#: between machines (llvmpipe vs NVIDIA, llvm vs scalar Mitsuba), tight enough to catch a
#: broken shader, transfer or mapping (those move PSNR by several dB).
TOLERANCES = {"psnr_masked": 1.0, "ssim_masked": 0.03, "flip_masked": 0.02, "mae": 0.01}


def regression_case(method_cls, variant: str | None = None) -> dict[str, Any]:
    """The scene/variant/light a method is regressed on.

    ``variant`` names one of the method's ``regression_variants`` (config overrides regressed
    as a case of their own, baseline key ``method:variant``, e.g. a compressed form).
    """
    case = {**DEFAULT_CASE, **method_cls.regression_case}
    if variant is not None:
        extra = method_cls.regression_variants[variant]
        case["overrides"] = {**case.get("overrides", {}), **extra}
    return case


def case_names() -> list[str]:
    """Every regression case: each method's name, then ``method:variant`` for its
    ``regression_variants``."""

    names = []
    for name in METHODS.names():
        names.append(name)
        names += [f"{name}:{v}" for v in METHODS.get(name).regression_variants]
    return names


def split_case(name: str) -> tuple[str, str | None]:
    """(method, variant or None) of a case name; unknown names are UnknownNameErrors."""

    method, sep, variant = name.partition(":")
    METHODS.check(method)
    if sep and variant not in METHODS.get(method).regression_variants:
        raise UnknownNameError("regression case", name, case_names())
    return method, (variant if sep else None)


def _case_of(name: str) -> dict[str, Any]:
    method, variant = split_case(name)
    return regression_case(METHODS.get(method), variant)


@dataclass
class Measurement:
    """One method's regression run.

    Attributes
    ----------
    case : dict
        Scene, variant and light.
    metrics : dict of str to float
        Mean over views of the method's metrics.
    trivial : dict of str to dict of str to float
        Mean metrics of each trivial image (``flat``, ``half``, ``unshadowed`` where the
        method has a visibility knob).
    skipped : dict of str to str
        Trivial images not computed, with the reason.
    """

    case: dict[str, Any]
    metrics: dict[str, float]
    trivial: dict[str, dict[str, float]] = field(default_factory=dict)
    skipped: dict[str, str] = field(default_factory=dict)

    def gate_failures(self) -> list[str]:
        """Lines naming each trivial image the method does not beat (empty: it passes)."""
        return gate_failures(self.metrics, self.trivial)


def _mean(rows: Sequence[Mapping[str, float]]) -> dict[str, float]:
    return {k: float(sum(r[k] for r in rows) / len(rows)) for k in rows[0]}


def case_job(method: str, *, overrides: Mapping[str, Any] | None = None) -> Job:
    """The :class:`~prtbench.bench.job.Job` of ``method``'s regression case (smoke profile).

    The case's own ``overrides`` (config knobs a method needs for a meaningful smoke case,
    e.g. a longer training) come first, then ``overrides`` (``--set``).
    """
    case = _case_of(method)  # a ``method:variant`` case runs the method with its overrides
    method = split_case(method)[0]
    return Job(method=method, scene=case["scene"], variant=case["variant"], light=case["light"],
               profile=PROFILE, overrides={**case.get("overrides", {}), **(overrides or {})},
               scene_params=dict(case.get("scene_params", {})))


def trivial_metrics(job: Job) -> dict[str, dict[str, float]]:
    """Mean (over the job's views) metrics of the flat and half-bright images.

    The reference and mask are those a run of ``job`` measures against (same profile,
    resolution, spp and bounces; the reference comes from the same cache).
    """
    prepared = prepare(job, store=False)
    scene = prepared.scene
    per_view = []
    for view in scene.trajectory.views:
        ref = render_reference(scene, prepared.light, view, width=prepared.width,
                               height=prepared.height, spp=prepared.profile.reference_spp,
                               bounces=int(getattr(prepared.config, "bounces", 0)))
        mask = geometry_mask(scene, view, prepared.width, prepared.height)
        per_view.append(trivial_scores(ref.image, mask, exposure=scene.exposure))
    return {name: _mean([v[name] for v in per_view]) for name in per_view[0]}


def trivial_results(job: Job) -> tuple[dict[str, dict[str, float]], dict[str, str]]:
    """(metrics of every trivial image of ``job``, skipped images with their reason).

    Adds the ``unshadowed`` render (the same job with ``visibility=False``) where the method
    has a visibility knob.
    """
    trivial, skipped = trivial_metrics(job), {}
    reason = visibility_knob(METHODS.get(job.method))
    if reason is None:
        unshadowed = replace(job, overrides={**job.overrides, "visibility": False})
        trivial["unshadowed"] = run(unshadowed, store=False, progress=False,
                                    echo=False).summary.mean_metrics()
    else:
        skipped["unshadowed"] = reason
    return trivial, skipped


def gate(job: Job, metrics: Mapping[str, float]) -> list[str]:
    """Lines naming each trivial image of ``job`` that ``metrics`` do not beat.

    For smoke tests: ``assert not gate(job, summary.mean_metrics())``.
    """
    trivial, _ = trivial_results(job)
    return gate_failures(metrics, trivial)


def measure(case: str | RegressionCase) -> Measurement:
    """Run a regression case (smoke profile), with its trivial images.

    ``case``: a method's name or a ``method:variant`` case, or a case of a cases file.
    """
    if isinstance(case, RegressionCase):
        job, record = case.job, dict(case.record)
    else:
        job, record = case_job(case), _case_of(case)
    summary = run(job, store=False, progress=False, echo=False).summary
    trivial, skipped = trivial_results(job)
    return Measurement(record, summary.mean_metrics(), trivial, skipped)


def _measure_safely(case: str | RegressionCase) -> tuple[Measurement | None, str, float]:
    """(measurement or None, the one-line error of a case that could not run, seconds)."""
    start = time.perf_counter()
    try:
        return measure(case), "", time.perf_counter() - start
    except Exception as exc:  # noqa: BLE001 - a broken method fails its case, not the run
        return None, one_line(exc), time.perf_counter() - start


@contextmanager
def _cache_dir(cache: Path | None) -> Iterator[Path]:
    """``$PRTBENCH_CACHE`` pointed at ``cache``, or at a fresh temporary folder, meanwhile.

    Fetched assets (pinned, checksummed downloads, not artifacts of our code) stay where they
    were: ``$PRTBENCH_ASSETS`` is pointed at the previous assets folder meanwhile.
    """

    saved = {k: os.environ.get(k) for k in ("PRTBENCH_CACHE", "PRTBENCH_ASSETS")}
    assets = assets_root()
    with tempfile.TemporaryDirectory(prefix="prtbench-regress-") as fresh:
        root = Path(cache) if cache is not None else Path(fresh)
        os.environ["PRTBENCH_CACHE"] = str(root)
        os.environ["PRTBENCH_ASSETS"] = str(assets)
        try:
            yield root
        finally:
            for key, value in saved.items():
                if value is None:
                    os.environ.pop(key, None)
                else:
                    os.environ[key] = value


def load_baselines(path: Path, *, required: bool) -> dict[str, Any]:
    """The baseline file as a dict of method -> entry; a bad file is an InvalidInputError.

    ``required``: a missing file is an error (comparing) rather than an empty dict (updating).
    Entries are checked one by one in :func:`_entry_metrics`, so that one bad entry fails its
    method, not the whole run.
    """
    path = Path(path)
    if not path.exists():
        if required:
            raise InvalidInputError(f"baseline file '{path}' does not exist; accepted: a JSON file "
                                    "written by `prtbench regress --update`")
        return {}
    if path.is_dir():
        raise InvalidInputError(f"baseline file '{path}' is a directory; accepted: a JSON file")
    try:
        data = json.loads(path.read_text())
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InvalidInputError(f"baseline file '{path}' is not valid JSON ({exc}); "
                                "accepted: the output of `prtbench regress --update`") from None
    if not isinstance(data, dict):
        raise InvalidInputError(f"baseline file '{path}' holds a JSON {type(data).__name__}; "
                                "accepted: an object of method name -> entry")
    return data


def _number(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def _known_metric(key: str) -> bool:
    return (key[:-len("_masked")] if key.endswith("_masked") else key) in LDR_METRICS


def check_entry(entry: Any, case: Mapping[str, Any]) -> tuple[dict[str, tuple[float, float]],
                                                               list[str]]:
    """(metric -> (value, tolerance), problems) of one baseline entry, before any work.

    Problems (each a FAIL line): not an object, a case other than ``case``, no or empty
    ``metrics``, a value or tolerance that is not a finite number (tolerance >= 0), a metric
    name the runner never produces.
    """
    if not isinstance(entry, dict):
        return {}, [f"baseline entry is {json.dumps(entry)}; accepted: an object with 'case' "
                    "and 'metrics'"]
    if entry.get("case") != dict(case):
        return {}, [f"baseline recorded on case {json.dumps(entry.get('case'))}, but the "
                    f"method's regression case is {json.dumps(dict(case))}; update it"]
    specs = entry.get("metrics")
    if not isinstance(specs, dict) or not specs:
        return {}, [f"baseline entry has metrics={json.dumps(specs)}; accepted: a non-empty "
                    "object of metric -> {value, tolerance}"]
    out, problems = {}, []
    for metric, spec in specs.items():
        value = _number(spec.get("value")) if isinstance(spec, dict) else None
        tol = _number(spec.get("tolerance")) if isinstance(spec, dict) else None
        if not _known_metric(metric):
            problems.append(f"baseline metric '{metric}' is not produced by a run; accepted: "
                            f"{', '.join(TOLERANCES)} or another metric of prtbench.bench.metrics")
        elif value is None or tol is None or tol < 0:
            problems.append(f"baseline {metric} = {json.dumps(spec)}; accepted: "
                            "{\"value\": finite number, \"tolerance\": finite number >= 0}")
        else:
            out[metric] = (value, tol)
    return out, problems


def _fmt(values: Mapping[str, float]) -> str:
    return ", ".join(f"{m}={values[m]:.4f}" for m in GATE_METRICS if m in values)


def gate_check(name: str, result: Measurement, seconds: float) -> Check:
    """The gate of a measured case: its scores and each trivial image's as notes, a FAIL line per
    trivial image it does not beat (or one ``gate ok`` line)."""
    notes = [f"{_fmt(result.metrics)} on {json.dumps(result.case)} "
             f"({seconds:.1f} s with its trivial images)"]
    notes += [f"trivial {label}: {_fmt(scores)}" for label, scores in result.trivial.items()]
    notes += [f"trivial {label}: skipped ({reason})" for label, reason in result.skipped.items()]
    failures = result.gate_failures()
    if failures:
        return Check(name, GATE_TEST, "fail", "; ".join(failures),
                     lines=tuple(f"FAIL {line}" for line in failures), notes=tuple(notes),
                     seconds=seconds)
    verdict = f"{_fmt(result.metrics)} beats {', '.join(result.trivial)}"
    return Check(name, GATE_TEST, "ok", verdict, lines=(f"gate ok ({verdict})",),
                 notes=tuple(notes), seconds=seconds)


def compare_checks(name: str, specs: Mapping[str, tuple[float, float]],
                   result: Measurement) -> list[Check]:
    """One check per baseline metric of ``name``: within its tolerance, or a FAIL."""
    checks = []
    for metric, (want, tol) in specs.items():
        if metric not in result.metrics:
            message = (f"baseline metric '{metric}' is not produced; produced: "
                       f"{', '.join(sorted(result.metrics))}")
            checks.append(Check(name, metric, "fail", message, lines=(f"FAIL {message}",),
                                baseline=want, tolerance=tol))
        else:
            checks.append(metric_check(name, metric, float(result.metrics[metric]), want, tol))
    return checks


def _check_names(names: Sequence[str], cases: Mapping[str, RegressionCase] | None) -> None:
    for name in names:
        if cases is None:
            split_case(name)
        elif name not in cases:
            raise UnknownNameError("regression case", name, list(cases))


def regress(*, update: bool = False, methods: Sequence[str] | None = None,
            baseline_path: Path | None = None, cache: Path | None = None,
            workers: int | None = 0, cases_path: Path | None = None,
            junit_path: Path | None = None) -> bool:
    """Gate and compare (or with ``update``, rewrite) baselines; prints a report.

    Parameters
    ----------
    update : bool
        Rewrite the baselines of ``methods`` (all by default) from this run; refused, writing
        nothing, if any of them fails the trivial-image gate.
    methods : sequence of str, optional
        Method names or ``method:variant`` cases (default: every case, :func:`case_names`);
        with ``cases_path``, names of that file's cases (default: all of them).
    baseline_path : Path, optional
        Default :data:`DEFAULT_BASELINES`; required with ``cases_path``.
    cache : Path, optional
        Artifact cache to use; default a fresh temporary one, removed afterwards.
    workers : int, optional
        Cases measured at once on Dask workers (0: one after another in this process; None:
        one per core, at most one per case). The gate and the baselines compare image metrics
        only, never times, so parallel cases give the same verdicts.
    cases_path : Path, optional
        A cases file (:mod:`prtbench.bench.regress_cases`) whose cases replace the built-in ones.
    junit_path : Path, optional
        Write every check as JUnit XML here at the end (also when cases fail); checked before
        any work.

    Returns
    -------
    bool
        True if every case passes the gate and (when comparing) its baseline.
    """
    started, clock = datetime.now(timezone.utc), time.perf_counter()
    if junit_path is not None:
        check_file("--junit", junit_path)
    if cases_path is not None and baseline_path is None:
        raise InvalidInputError(f"--cases '{cases_path}' needs --baselines FILE; accepted: the "
                                "cases' own baseline file (tests/baselines/metrics.json holds "
                                "the built-in cases)")
    cases = {c.name: c for c in load_cases(cases_path)} if cases_path is not None else None
    path = Path(baseline_path or DEFAULT_BASELINES)
    baselines = load_baselines(path, required=not update)
    if cache is not None and Path(cache).exists() and not Path(cache).is_dir():
        raise InvalidInputError(f"--cache '{cache}' is a file; accepted: a folder (created if "
                                "missing)")
    names = list(methods) if methods else (list(cases) if cases is not None else case_names())
    _check_names(names, cases)
    items = [cases[name] for name in names] if cases is not None else names
    records = {name: dict(cases[name].record) if cases is not None else _case_of(name)
               for name in names}
    if workers is None:
        workers = min(cores(), len(names)) if len(names) > 1 else 0
    refused: list[str] = []
    checks: list[Check] = []

    def emit(check: Check) -> None:
        for line in check.printed():
            print(line)
        checks.append(check)

    specs_of: dict[str, dict[str, tuple[float, float]]] = {}
    if not update:  # baseline problems are reported before any work
        for name in names:
            if name not in baselines:
                how = (f"prtbench regress --update --cases {cases_path} --baselines {path} "
                       f"--method {name}" if cases is not None else
                       f"prtbench regress --update --method {name}")
                emit(Check(name, BASELINE_TEST, "fail", f"no baseline in '{path}'",
                           lines=(f"FAIL no baseline (run `{how}`)",)))
                continue
            specs, problems = check_entry(baselines[name], records[name])
            if problems:
                emit(Check(name, BASELINE_TEST, "fail", "; ".join(problems),
                           lines=tuple(f"FAIL {line}" for line in problems)))
            specs_of[name] = specs
    with _cache_dir(cache), make_executor(workers=workers) as executor:
        for index, outcome in executor.map(_measure_safely, items):
            name = names[index]
            result, error, seconds = (None, outcome.error, outcome.seconds) if isinstance(
                outcome, Lost) else outcome
            if result is None:
                for check in error_checks(name, error, [GATE_TEST, *specs_of.get(name, {})],
                                          seconds=seconds):
                    emit(check)
                refused.append(name)
                continue
            gate = gate_check(name, result, seconds)
            emit(gate)
            if update:
                if not gate.passed:
                    refused.append(name)
                    continue
                baselines[name] = {"case": result.case, "metrics": {
                    m: {"value": round(float(result.metrics[m]), 5), "tolerance": tol}
                    for m, tol in TOLERANCES.items()}}
                line = "baseline updated " + ", ".join(f"{m}={result.metrics[m]:.4f}"
                                                        for m in TOLERANCES)
                emit(Check(name, BASELINE_TEST, "ok", f"{line} (in '{path}')", lines=(line,)))
                continue
            for check in compare_checks(name, specs_of.get(name, {}), result):
                emit(check)
    if update:
        if refused:
            print(f"refused to update the baselines: {', '.join(refused)} "
                  "do not beat the trivial images (see the FAIL lines); nothing written",
                  file=sys.stderr)
            checks = [replace(c, message=f"{c.message}: not written, as {', '.join(refused)} "
                                         "failed") if c.test == BASELINE_TEST and c.passed else c
                      for c in checks]
        else:
            with atomic_path(path) as tmp:
                tmp.write_text(json.dumps(baselines, indent=2, sort_keys=True) + "\n")
            print(f"wrote {path}", file=sys.stderr)
    if junit_path is not None:
        write_junit(junit_path, checks, seconds=time.perf_counter() - clock, started=started,
                    properties={"mode": "update" if update else "compare", "profile": PROFILE,
                                "baselines": str(path),
                                "cases": str(cases_path) if cases_path is not None else "built-in"})
        print(f"wrote {junit_path}", file=sys.stderr)
    return not failed(checks) and not refused
