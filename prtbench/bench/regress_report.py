"""What ``prtbench regress`` found, as data: one :class:`Check` per verdict, printed as it comes
and written at the end as JUnit XML (``prtbench regress --junit FILE``).

A check is one JUnit test case: per regression case (a method's name, ``method:variant`` or a
cases file's name) one per metric of its baseline entry (value, baseline and tolerance), one
``trivial-images`` for the gate against the trivial images (:mod:`prtbench.bench.trivial`), and
``baseline`` where the entry is missing or malformed, or (``--update``) was rewritten. A case
that could not run is an ``<error>`` on each test case it would have had, so a CI history keeps
the same test names whether a case runs, fails or breaks.

JUnit is the format Jenkins, GitLab and GitHub test-report actions read::

    <testsuites name="prtbench regress" tests="…" failures="…" errors="…" time="…">
      <testsuite name="prtbench regress" tests="…" failures="…" errors="…" skipped="0" time="…">
        <testcase classname="prtbench.regress.vertex" name="psnr_masked" time="0.000">
          <properties><property name="value" value="20.9"/>…</properties>
          <failure type="regression" message="psnr_masked = 20.9000 …">value: 20.9 …</failure>
        </testcase>
        <testcase classname="prtbench.regress.vertex" name="trivial-images" time="3.214">
          <system-out>the case's scores, the trivial images' scores, the verdict</system-out>
        </testcase>

The run time of a case (its render, reference and trivial images) is the ``trivial-images``
test case's time; comparing a metric with its baseline takes none.
"""

from __future__ import annotations

import re
import socket
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import KW_ONLY, dataclass
from datetime import datetime, timezone
from pathlib import Path

from prtbench.api.cache import atomic_path

#: The test case of the gate against the trivial images.
GATE_TEST = "trivial-images"
#: The test case of a baseline entry's own problems (missing, malformed) and of its update.
BASELINE_TEST = "baseline"
#: JUnit suite name and classname prefix.
SUITE = "prtbench regress"
CLASS_PREFIX = "prtbench.regress."
#: Check statuses, from best to worst.
STATUSES = ("ok", "fail", "error")
#: Characters XML 1.0 cannot hold (control characters, e.g. a worker's ANSI colour escape in
#: an error message, and unpaired surrogates): ElementTree would write them unescaped.
_NOT_XML = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\ud800-\udfff\ufffe\uffff]")


@dataclass(frozen=True)
class Check:
    """One verdict of a regression case: the lines ``regress`` prints and one JUnit test case.

    Attributes
    ----------
    case : str
        The regression case (a method's name, ``method:variant``, a cases file's ``name``).
    test : str
        What was checked: a metric name, :data:`GATE_TEST` or :data:`BASELINE_TEST`.
    status : {"ok", "fail", "error"}
        ``error``: the case could not run, so nothing was checked.
    message : str
        One line for JUnit's ``message``: a metric's value, baseline and tolerance, the trivial
        images not beaten, or why the case could not run.
    lines : tuple of str
        Printed, each after ``"<case>: "``; empty where another check of the case printed the
        reason (the error checks of a case that could not run print one line between them).
    notes : tuple of str
        Printed before ``lines``, and the test case's ``system-out`` (with ``message`` when it
        passed): the case's mean metrics and each trivial image's scores.
    value, baseline, tolerance : float, optional
        A metric's measured value, its baseline value and the accepted absolute difference.
    seconds : float
        The test case's time.
    """

    case: str
    test: str
    status: str
    message: str
    _: KW_ONLY
    lines: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()
    value: float | None = None
    baseline: float | None = None
    tolerance: float | None = None
    seconds: float = 0.0

    def __post_init__(self) -> None:
        if self.status not in STATUSES:
            raise ValueError(f"check status '{self.status}'; accepted: {', '.join(STATUSES)}")

    @property
    def passed(self) -> bool:
        return self.status == "ok"

    def printed(self) -> list[str]:
        """The lines ``regress`` prints for this check: notes, then verdict lines."""
        return [f"{self.case}: {line}" for line in (*self.notes, *self.lines)]


def metric_check(case: str, metric: str, value: float, baseline: float,
                 tolerance: float) -> Check:
    """The comparison of one measured metric with its baseline ``value ± tolerance``.

    NaN compares False: a NaN value fails.
    """
    passed = abs(value - baseline) <= tolerance
    line = (f"{metric} = {value:.4f} (baseline {baseline:.4f} ± {tolerance}) "
            f"{'ok' if passed else 'FAIL'}")
    message = (f"{metric} = {value:.4f}, baseline {baseline:.4f} ± {tolerance}: "
               f"{'within' if passed else 'outside'} the tolerance "
               f"(difference {value - baseline:+.4f})")
    return Check(case, metric, "ok" if passed else "fail", message, lines=(line,), value=value,
                 baseline=baseline, tolerance=tolerance)


def error_checks(case: str, error: str, tests: Sequence[str], *, seconds: float) -> list[Check]:
    """A case that could not run: an error on each of its ``tests`` (the gate first), one line
    printed."""
    message = f"the case could not run: {error}"
    return [Check(case, test, "error", message, lines=(f"FAIL {message}",) if i == 0 else (),
                  seconds=seconds if i == 0 else 0.0)
            for i, test in enumerate(tests)]


def failed(checks: Sequence[Check]) -> bool:
    """Whether any check did not pass."""
    return any(not c.passed for c in checks)


def _xml(text: object) -> str:
    return _NOT_XML.sub("\N{REPLACEMENT CHARACTER}", str(text))


def _number(value: float) -> str:
    return repr(float(value))


def junit_tree(checks: Sequence[Check], *, seconds: float,
               properties: Mapping[str, str] | None = None,
               started: datetime | None = None) -> ET.ElementTree:
    """The JUnit document of ``checks`` (one ``testsuite``, one ``testcase`` per check).

    Parameters
    ----------
    checks : sequence of Check
        In the order they were made.
    seconds : float
        The whole run's wall time (the suite's ``time``).
    properties : mapping of str to str, optional
        The suite's ``<properties>`` (baseline file, cases file, mode).
    started : datetime, optional
        The suite's ``timestamp`` (default now, UTC).
    """
    counts = {status: sum(c.status == status for c in checks) for status in STATUSES}
    totals = {"tests": str(len(checks)), "failures": str(counts["fail"]),
              "errors": str(counts["error"])}
    root = ET.Element("testsuites", name=SUITE, **totals, time=f"{seconds:.3f}")
    stamp = (started or datetime.now(timezone.utc)).isoformat(timespec="seconds")
    suite = ET.SubElement(root, "testsuite", name=SUITE, **totals, skipped="0",
                          time=f"{seconds:.3f}", timestamp=stamp, hostname=socket.gethostname())
    if properties:
        props = ET.SubElement(suite, "properties")
        for key, value in properties.items():
            ET.SubElement(props, "property", name=_xml(key), value=_xml(value))
    for check in checks:
        case = ET.SubElement(suite, "testcase", classname=_xml(CLASS_PREFIX + check.case),
                             name=_xml(check.test), time=f"{check.seconds:.3f}")
        numbers = {k: v for k, v in (("value", check.value), ("baseline", check.baseline),
                                     ("tolerance", check.tolerance)) if v is not None}
        if numbers:
            props = ET.SubElement(case, "properties")
            for key, value in numbers.items():
                ET.SubElement(props, "property", name=key, value=_number(value))
        if check.status != "ok":
            kind = "error" if check.status == "error" else "failure"
            verdict = ET.SubElement(case, kind, message=_xml(check.message),
                                    type="error" if kind == "error" else "regression")
            verdict.text = _xml("\n".join([check.message, *(f"{k}: {_number(v)}"
                                                           for k, v in numbers.items())]))
        out = [*check.notes, *([check.message] if check.passed else [])]  # else: in <failure>
        if out:
            ET.SubElement(case, "system-out").text = _xml("\n".join(out))
    ET.indent(root)
    return ET.ElementTree(root)


def write_junit(path: Path, checks: Sequence[Check], *, seconds: float,
                properties: Mapping[str, str] | None = None,
                started: datetime | None = None) -> None:
    """Write :func:`junit_tree` of ``checks`` to ``path`` atomically (UTF-8, with declaration)."""
    tree = junit_tree(checks, seconds=seconds, properties=properties, started=started)
    with atomic_path(Path(path)) as tmp:
        tree.write(tmp, encoding="utf-8", xml_declaration=True)

