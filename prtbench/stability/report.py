"""``reports/table-stability.{md,csv}``: one row per (method, case), from the stored rows only.

The Markdown starts with a per-method summary line ("vertex: ok in 14 cases, degraded at
light=below-horizon (...), refused 2 (...)"), then what was not measured (given the catalogue:
a registered method without rows is listed as not measured, never silently absent), then, for
each method, its table, and ends with what a user should do instead for every ``degraded`` row.
The CSV holds every stored number (measured rows only).
"""

from __future__ import annotations

import csv
import io
import math
import statistics
from collections import Counter
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from prtbench.api.cache import atomic_path
from prtbench.stability.outcome import FLIP_MARGIN, OUTCOMES, PSNR_MARGIN_DB

#: The column (and stored key) naming the CSV a row was imported from
#: (:mod:`prtbench.stability.importing`); empty for rows measured into the store.
IMPORTED_FROM = "imported_from"
#: CSV columns, in order (every number the Markdown prints is among them).
CSV_COLUMNS = (
    "method", "case", "group", "outcome", "reason", "scene", "variant", "psnr_masked",
    "flip_masked", "ssim_masked", "moderate_psnr_masked", "moderate_flip_masked",
    "psnr_vs_moderate", "flip_vs_moderate", "image_nonfinite", "artifact_nonfinite",
    "image_peak", "reference_peak", "artifact_peak", "storage_dtype", "storage_max", "overflow",
    "underflow", "precompute_s", "precompute_cached", "memory_bytes", "artifact_bytes",
    "peak_rss_bytes", "frame_ms", "wall_s", "status", "run_id", "git_sha", "profile",
    "renderer", "device", "ringing", "rel_l2", "advice", "note", "load_1m", "timestamp",
    "partial_run", IMPORTED_FROM)


def _num(value: Any, fmt: str = ".2f") -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    if isinstance(value, float) and math.isinf(value):
        return "inf" if value > 0 else "-inf"
    if fmt == "d":  # counts read back through pandas may be floats
        value = int(value)
    return format(value, fmt)


def _mib(value: Any) -> str:
    return "-" if value is None else f"{float(value) / 2**20:.1f}"


def _kib(value: Any) -> str:
    return "-" if value is None else f"{float(value) / 2**10:.1f}"


def _short(text: Any, limit: int = 90) -> str:
    text = " ".join(str(text or "").split()).replace("|", "/")
    return text if len(text) <= limit else text[:limit - 1] + "…"


def method_summary(method: str, rows: Sequence[Mapping[str, Any]]) -> str:
    """One line: counts per outcome, naming the degraded, refused and failed cases."""
    counts = Counter(r["outcome"] for r in rows)
    parts = [f"ok in {counts.get('ok', 0)} cases"]
    for outcome in ("degraded", "refused", "failed"):
        named = [r for r in rows if r["outcome"] == outcome]
        if not named:
            continue
        if outcome == "degraded":
            parts.append("degraded at " + ", ".join(
                f"{r['case']} ({_short(r['reason'], 60)})" for r in named))
        else:
            parts.append(f"{outcome} {len(named)} ({', '.join(r['case'] for r in named)})")
    return f"{method}: " + ", ".join(parts)


def _duration(seconds: float) -> str:
    return f"{seconds:.0f} s" if seconds < 120 else f"{seconds / 60:.1f} min"


def _have(count: int) -> str:
    """The verb after "N of the cases" (one of them has, two have)."""
    return "has" if count == 1 else "have"


def _missing(rows: Sequence[Mapping[str, Any]],
             expected: Mapping[str, Sequence[str]]) -> dict[str, list[str]]:
    """Per expected method, its catalogue cases without a row (in catalogue order)."""
    have = {(r["method"], r["case"]) for r in rows}
    return {m: [c for c in names if (m, c) not in have] for m, names in expected.items()}


def coverage_lines(rows: Sequence[Mapping[str, Any]],
                   expected: Mapping[str, Sequence[str]] | None,
                   notes: Sequence[str] = ()) -> list[str]:
    """The report's "Not measured" section: every expected case without a stored row.

    Parameters
    ----------
    rows : sequence of mapping
        The report's rows.
    expected : mapping of str to sequence of str, or None
        Method name -> its catalogue's case names (every registered method for a report of the
        whole store). None: no coverage section (nothing to compare with).
    notes : sequence of str
        Why cases were not measured (or, with every case measured, how they were), as the
        person who wrote the report states it.

    Returns
    -------
    list of str
        Markdown lines (empty without ``expected``).
    """
    if expected is None:
        return []
    missing = _missing(rows, expected)
    total = sum(len(v) for v in expected.values())
    absent = sum(len(v) for v in missing.values())
    lines = ["", "## Not measured", "",
             f"{total - absent} of the {total} catalogue cases of {len(expected)} "
             f"method{'' if len(expected) == 1 else 's'} {_have(total - absent)} a stored row; "
             f"{absent} {_have(absent)} none"
             + (":" if absent else ".")]
    if absent:
        lines.append("")
    for method, names in missing.items():
        if not names:
            continue
        mine = [r for r in rows if r["method"] == method]
        if not mine:
            lines.append(f"- {method}: **not measured** (no stored row; {len(names)} cases in "
                         "its catalogue)")
            continue
        walls = sorted(float(r["wall_s"]) for r in mine
                       if isinstance(r.get("wall_s"), (int, float)) and math.isfinite(r["wall_s"]))
        took = (f"; its measured cases took {_duration(statistics.median(walls))} median, "
                f"{_duration(walls[-1])} at most" if walls else "")
        lines.append(f"- {method}: {len(names)} of {len(expected[method])} cases not measured"
                     f"{took}: {', '.join(f'`{n}`' for n in names)}")
    stale = sorted({(r["method"], r["case"]) for r in rows if r["method"] in expected
                    and r["case"] not in set(expected[r["method"]])})
    if stale:
        lines += ["", "Stored cases no longer in the catalogue (kept): "
                  + ", ".join(f"{m} `{c}`" for m, c in stale)]
    if notes:
        # With every case measured the notes explain how, not why something is missing.
        lines += ["", "Why:" if absent else "Notes:", ""] + [f"- {n}" for n in notes]
    return lines


def _count(rows: Sequence[Mapping[str, Any]], method: str, *, partial: bool = False) -> int:
    return sum(r["method"] == method and (not partial or bool(r.get("partial_run"))) for r in rows)


def _newest_revision(rows: Sequence[Mapping[str, Any]]) -> str:
    stamped = [r for r in rows if r.get("timestamp")]
    newest = max(stamped, key=lambda r: str(r["timestamp"])) if stamped else rows[-1]
    return str(newest.get("git_sha", "?"))


def _load_text(rows: Sequence[Mapping[str, Any]]) -> str:
    loads = [float(r["load_1m"]) for r in rows
             if isinstance(r.get("load_1m"), (int, float)) and math.isfinite(r["load_1m"])]
    if not loads:
        return ""
    return (f" Load (1-min average, the higher of each case's start and end) "
            f"{min(loads):.2f}-{max(loads):.2f} over the {len(loads)} rows that recorded it.")


def _marks(row: Mapping[str, Any]) -> str:
    """† a row of an interrupted run, ‡ a row imported from an earlier report's CSV."""
    return (" †" if row.get("partial_run") else "") + (" ‡" if row.get(IMPORTED_FROM) else "")


def _imported_lines(rows: Sequence[Mapping[str, Any]]) -> list[str]:
    """Where rows came from a CSV (``stability --import-csv``) rather than a run into this
    store: how many, from which file, and what they keep."""
    sources = Counter(str(r[IMPORTED_FROM]) for r in rows if r.get(IMPORTED_FROM))
    if not sources:
        return []
    files = ", ".join(f"`{source}` ({count})" for source, count in sources.items())
    return ["", f"Imported: {sum(sources.values())} of {len(rows)} rows were carried over from "
            f"an earlier report's CSV ({files}; ‡ in the tables), because the results store "
            "they were measured into was not kept. They are the earlier runs' own numbers, "
            "each with its revision, device, load and time; rows without ‡ were measured "
            "into this store."]


def format_markdown(rows: Sequence[Mapping[str, Any]], *,
                    expected: Mapping[str, Sequence[str]] | None = None,
                    notes: Sequence[str] = ()) -> str:
    """The Markdown report of stored rows.

    ``expected`` (method -> catalogue case names) adds the "Not measured" section and a
    summary line for every expected method without rows (:func:`coverage_lines`).
    """
    methods = list(dict.fromkeys(r["method"] for r in rows))
    first = rows[0] if rows else {}
    totals = Counter(r["outcome"] for r in rows)
    revisions = list(dict.fromkeys(str(r.get("git_sha", "?")) for r in rows))
    shas = (f"`{revisions[0]}`" if len(revisions) == 1 else
            f"at {len(revisions)} revisions (newest row `{_newest_revision(rows)}`)")
    devices = ", ".join(dict.fromkeys(str(r.get("device", "?")) for r in rows))
    lines = ["# Numerical stability at the extremes (issue #15)", "",
             f"Profile `{first.get('profile', '?')}`, code {shas} (per row in the CSV), "
             f"device {devices}. One view per case, path reference (Mitsuba). "
             f"Outcomes: {', '.join(f'{totals.get(o, 0)} {o}' for o in OUTCOMES)}."
             + _load_text(rows), "",
             f"`degraded`: finite, but masked PSNR more than {PSNR_MARGIN_DB:g} dB below, or "
             f"masked FLIP more than {FLIP_MARGIN:g} above, the method's `moderate` case (its "
             "profile defaults on the same base scene under `sky`). `refused`: a one-line error "
             "(the correct answer to an impossible request). `failed`: NaN/Inf, a crash, a "
             "traceback or a timeout (always a bug). `vs mod.`: the image against the moderate "
             "render, where the case renders the same picture (knobs, scale, translation). "
             "`peak / max`: the artifact's largest |value| and its storage type's maximum; "
             "`over`/`under`: values above that maximum / non-zero below its smallest normal.",
             "", "Method-specific edges (prtbench/stability/edges.py): a 10⁶-triangle mesh for "
             "the per-vertex methods (precompute time, peak RSS), CPCA with K = N, n′ = 0 and "
             "n′ = d, probes inside a solid block, SDF sphere tracing with |∇d| = 0.01; wavelet "
             "k = 1 / all and keep = 1 are knob cases.", "", "## Summary", ""]
    lines += [f"- {method_summary(m, [r for r in rows if r['method'] == m])}" for m in methods]
    unmeasured = [m for m in (expected or {}) if m not in methods]
    lines += [f"- {m}: **not measured** (no stored row)" for m in unmeasured]
    partial = [m for m in methods if any(r.get("partial_run") for r in rows if r["method"] == m)]
    if partial:
        lines += ["", "Partial: rows from matrix runs stopped before their end (each is still the "
                  "case's newest measurement; `partial_run` in the CSV, † in the tables): "
                  + ", ".join(f"{m} ({_count(rows, m, partial=True)} of {_count(rows, m)} rows)"
                              for m in partial)]
    lines += _imported_lines(rows)
    lines += coverage_lines(rows, expected, notes)
    for method in methods:
        mine = [r for r in rows if r["method"] == method]
        if mine[0].get("group") == "sh-core":
            lines += ["", f"## {method}", "", "SH projection of the case lights reconstructed on a "
                      "64x128 grid (ringing: most negative over largest value; rel. L2 against "
                      "the light), and the Phong zonal coefficients at 16 bands.", "",
                      "| case | outcome | ringing | rel. L2 | reason |", "|---|---|---:|---:|---|"]
            lines += [f"| {r['case']}{_marks(r)} | **{r['outcome']}** | "
                      f"{_num(r.get('ringing'), '.3f')} | "
                      f"{_num(r.get('rel_l2'), '.3f')} | {_short(r.get('reason'))} |" for r in mine]
            continue
        lines += ["", f"## {method}", "",
                  f"Base scene `{mine[0].get('scene')}`.", "",
                  "| case | outcome | PSNR_m | FLIP_m | vs mod. PSNR | peak / max (dtype) | over | under "
                  "| precompute s | memory KiB | peak RSS MiB | reason |",
                  "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|"]
        for r in mine:
            peak = ("-" if r.get("artifact_peak") is None else
                    f"{_num(r.get('artifact_peak'), '.3g')} / {_num(r.get('storage_max'), '.3g')} "
                    f"({r.get('storage_dtype')})")
            lines.append(
                f"| {r['case']}{_marks(r)} | **{r['outcome']}** | "
                f"{_num(r.get('psnr_masked'))} | "
                f"{_num(r.get('flip_masked'), '.3f')} | {_num(r.get('psnr_vs_moderate'))} | "
                f"{peak} | "
                f"{_num(r.get('overflow'), 'd')} | {_num(r.get('underflow'), 'd')} | "
                f"{_num(r.get('precompute_s'), '.1f')} | {_kib(r.get('memory_bytes'))} | "
                f"{_mib(r.get('peak_rss_bytes'))} | {_short(r.get('reason'))} |")
    degraded = [r for r in rows if r["outcome"] == "degraded"]
    lines += ["", "## What to do instead (degraded cases)", ""]
    lines += [f"- {r['method']} `{r['case']}` ({_short(r.get('note'), 80)}): {r.get('advice')}"
              for r in degraded] or ["- (none)"]
    failed = [r for r in rows if r["outcome"] == "failed"]
    if failed:
        lines += ["", "## Failed (bugs)", ""]
        lines += [f"- {r['method']} `{r['case']}`: {_short(r.get('reason'), 300)}" for r in failed]
    return "\n".join(lines) + "\n"


def _cell(value: Any) -> Any:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ""
    return value


def format_csv(rows: Sequence[Mapping[str, Any]]) -> str:
    """The CSV report: :data:`CSV_COLUMNS` of every stored row."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    for r in rows:
        # A fresh run's rows have no partial_run (they are the run); the store's say False.
        r = {**r, "partial_run": bool(r.get("partial_run"))}
        writer.writerow([_cell(r.get(c)) for c in CSV_COLUMNS])
    return buf.getvalue()


def write_reports(rows: Sequence[Mapping[str, Any]], folder: Path, *,
                  stem: str = "table-stability",
                  expected: Mapping[str, Sequence[str]] | None = None,
                  notes: Sequence[str] = ()) -> tuple[Path, Path]:
    """Write ``<stem>.md`` and ``<stem>.csv`` into ``folder`` atomically; their paths.

    A file scene's matrix uses ``table-stability-<scene name>`` (the name carries the file's
    content hash), so it never overwrites the committed ``table-stability.*``. ``expected`` and
    ``notes``: :func:`format_markdown`.
    """

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    md, csv_path = folder / f"{stem}.md", folder / f"{stem}.csv"
    for path, text in ((md, format_markdown(rows, expected=expected, notes=notes)),
                       (csv_path, format_csv(rows))):
        with atomic_path(path) as tmp:
            tmp.write_text(text)
    return md, csv_path
