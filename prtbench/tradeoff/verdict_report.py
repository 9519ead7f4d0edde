"""The engine verdict's reports: ``verdict-….{md,csv}`` and the CLI's summary
(:mod:`prtbench.tradeoff.verdict` computes what they show). Every number is a stored row's
value or a mean of them."""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path
from typing import TYPE_CHECKING

from prtbench.bench.reproduction import load_note
from prtbench.store.results import git_sha
from prtbench.tradeoff.budget import format_cost, interval_text, none_text
from prtbench.tradeoff.front import Point, knobs_text
from prtbench.tradeoff.pareto_report import display_path, reference_of

if TYPE_CHECKING:  # the verdict imports this module to write its reports
    from prtbench.tradeoff.verdict import BudgetBlock, FamilyRow, VerdictResult


def _fmt(value: float | None, digits: int = 4) -> str:
    if value is None or not math.isfinite(value):
        return "—"
    return f"{value:.{digits}g}"


def _family_text(row: FamilyRow) -> str:
    return f"{row.family}{' (engine)' if row.engine else ''}"


def _cost_text(row: FamilyRow, kind: str) -> str:
    p = row.point
    return format_cost(p.cost, kind) if p else "—"


CSV_COLUMNS = ("scene", "light", "panel", "reference", "profile", "budget_kind", "budget",
               "budget_as_written", "family", "engine_baseline", "mark", "method", "config",
               "knobs", "psnr_masked", "psnr_masked_lo", "psnr_masked_hi", "flip_masked",
               "flip_masked_lo", "flip_masked_hi", "cost", "light_class", "split", "views",
               "run_ids", "git_shas", "load_average", "device", "renderer", "note")


def csv_text(result: VerdictResult) -> str:
    """One line per scene, panel, budget and family (full float precision)."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    finite = lambda v: repr(v) if v is not None and math.isfinite(v) else ""  # noqa: E731
    for pv in result.panels:
        for block in pv.blocks:
            b = block.budget
            for f in block.rows:
                p, q = f.point, f.flip
                note = "" if p else none_text(f.row, b.kind)
                writer.writerow([
                    pv.scene, pv.light, pv.panel, reference_of(pv.panel), result.profile,
                    b.kind, repr(b.value), b.text, f.family, int(f.engine), f.row.mark,
                    f.row.method, p.config_json if p else "", knobs_text(p) if p else "",
                    finite(p.error) if p else "", finite(p.error_lo) if p else "",
                    finite(p.error_hi) if p else "", finite(q.error) if q else "",
                    finite(q.error_lo) if q else "", finite(q.error_hi) if q else "",
                    finite(p.cost) if p else "", p.light_class if p else "",
                    p.split if p else "", p.views if p else "",
                    ";".join(p.run_ids) if p else "", ";".join(p.git_shas) if p else "",
                    ";".join(f"{v:.2f}" for v in p.loads) if p else "",
                    ";".join(p.devices) if p else "", ";".join(p.renderers) if p else "", note])
    return out.getvalue()


def _block_lines(block: BudgetBlock) -> list[str]:
    kind = block.budget.kind
    lines = [f"**{kind} ≤ {block.budget.text}**" + (f" ({block.note})" if block.note else ""), "",
             "| mark | family | method | knobs | masked PSNR (dB) | interval | masked FLIP "
             f"| interval | {kind} | light class |",
             "|---|---|---|---|---:|---|---:|---|---:|---|"]
    for f in block.rows:
        p, q = f.point, f.flip
        family = _family_text(f)
        if p is None:
            lines.append(f"| | {family} | {f.row.method} | {none_text(f.row, kind)} "
                         "| | | | | | |")
            continue
        lines.append(f"| {f.row.mark} | {family} | {p.method} | {knobs_text(p)} | "
                     f"{_fmt(p.error)}{' (at ceiling)' if p.clipped else ''} | "
                     f"{interval_text(p)} | {_fmt(q.error if q else None, 3)} | "
                     f"{interval_text(q) if q else '—'} | {_cost_text(f, kind)} | "
                     f"{p.light_class} |")
    return lines + [""]


def _points(result: VerdictResult) -> list[Point]:
    return [f.point for pv in result.panels for b in pv.blocks for f in b.rows if f.point]


def markdown_text(result: VerdictResult, *, results_path: Path, command: str) -> str:
    """The report: provenance, how to read it, the conclusions, one section per scene/panel."""
    import pandas as pd  # as the Pareto report: only to hand load_note its frame

    points = _points(result)
    shas = sorted({s for p in points for s in p.git_shas})
    renderers = sorted({r for p in points for r in p.renderers})
    devices = sorted({d for p in points for d in p.devices})
    load = load_note([pd.DataFrame({"load_average": [v for p in points for v in p.loads],
                                    "device": [d for p in points for _ in p.loads
                                               for d in (p.devices[:1] or [None])]})])
    lines = [
        f"# Engine verdict: {', '.join(result.scenes)} ({result.profile})", "",
        f"Generated by `{command}` from `{display_path(results_path)}` with prtbench "
        f"{git_sha()}, under the protocol of docs/PROTOCOL.md.", "",
        f"- Profile: {result.profile}. Rows measured by code version(s): "
        f"{', '.join(shas) or 'unknown'}.",
        f"- Renderer(s): {'; '.join(renderers) or 'unknown'}. Device(s): "
        f"{'; '.join(devices) or 'unknown'}.{load}",
        "- Per budget, each method family's best configuration (families: `Method.family`; "
        "'(engine)' marks what engines ship today) with its masked PSNR and FLIP against the "
        "one-bounce path-traced reference, mean over the views with the 95 % interval (the "
        "reference's Monte Carlo noise and the spread over views). Memory is every resident "
        "byte; ops is the operation-count model per frame (frame times on a CPU rasteriser "
        "would rank llvmpipe, not the methods).",
        "- Mark: 'best' is better than every other family beyond the intervals (paired over "
        "shared views); 'tied' rows no other row beats beyond them.",
        "- Light class: relight (any light at run time), family (fitted to a family of "
        "lights), fixed (the light is baked in). Under a changing sky only relight counts.",
        "- Conclusion: at the middle memory budget, the best PRT family against the engine "
        "baselines, paired over the views: the one that beats it beyond the interval (else the "
        "closest it beats, else the best it ties with), with the difference in masked PSNR ± "
        "its interval half-width; under a changing sky, each family's best relightable "
        "configuration.", "",
        "## Conclusions", ""]
    for pv in result.panels:
        lines.append(f"- **{pv.scene} / {pv.light}** ({pv.panel}): {pv.conclusion}. Under a "
                     f"changing sky: {pv.relight_conclusion}.")
    lines.append("")
    for pv in result.panels:
        lines += [f"## {pv.scene} under {pv.light}", "",
                  f"Panel {pv.panel}; reference {reference_of(pv.panel) or 'unknown'}.", ""]
        for block in pv.blocks:
            lines += _block_lines(block)
    if result.skipped:
        lines += ["Left out:", *[f"- {s}" for s in result.skipped], ""]
    return "\n".join(lines)


def summary_text(result: VerdictResult) -> str:
    """What the CLI prints: the conclusions, each budget's family table, the files."""
    lines = []
    for pv in result.panels:
        lines.append(f"verdict {pv.scene}/{pv.light} ({pv.panel}, {result.profile})")
        for block in pv.blocks:
            lines.append(f"  {block.budget.kind} ≤ {block.budget.text}")
            for f in block.rows:
                p, q = f.point, f.flip
                family = _family_text(f)
                if p is None:
                    lines.append(f"    {'':5s} {family:26s} {f.row.method:22s} "
                                 f"{none_text(f.row, block.budget.kind)}")
                    continue
                lines.append(f"    {f.row.mark:5s} {family:26s} {p.method:22s} "
                             f"psnr={_fmt(p.error)} [{interval_text(p)}] flip="
                             f"{_fmt(q.error if q else None, 3)}  "
                             f"{block.budget.kind}={_cost_text(f, block.budget.kind)}  "
                             f"{p.light_class}")
        lines += [f"  {pv.conclusion}", f"  under a changing sky: {pv.relight_conclusion}"]
    lines += [f"wrote {p}" for p in result.paths]
    return "\n".join(lines)


