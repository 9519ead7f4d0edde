"""The Pareto report of one scene and light: markdown, CSV and an ann-benchmarks style plot.

Every number printed is a stored row's value or a mean of them (:mod:`.pareto`); the CSV keeps
full float precision. Files are written to a temporary name and renamed into place, so an
interrupted run leaves the previous report intact. The PNG and SVG carry no date or software
version (fixed SVG hash salt), so the same store gives the same files.
"""

from __future__ import annotations

import csv
import io
import json
import math
import re
from collections import defaultdict
from pathlib import Path

from prtbench.api.cache import atomic_path
from prtbench.api.method import METHODS
from prtbench.bench.reproduction import load_note
from prtbench.store.results import git_sha
from prtbench.tradeoff import cost as cost_mod
from prtbench.tradeoff.front import ERROR_LABELS, ERRORS, ParetoResult, Point, knobs_text

_MARKERS = ("o", "s", "^", "v", "D", "P", "X", "*", "h", "<", ">", "p")
_CSV_COLUMNS = ("scene", "light", "variant", "width", "height", "profile", "method", "config",
                "panel", "reference", "light_class", "split", "error_kind", "error",
                "error_lo", "error_hi", "error_unclipped", "clipped", "noise_ceiling_db",
                "cost_kind", "cost", "on_front", "dominated", "tied_with", "views", "rows",
                "run_ids", "timing_workers", "ops_madds", "ops_fetches", "ops_bytes",
                "frame_components", "memory_breakdown", "light_change_ms", "note")
#: Configurations a rank correlation needs before a report prints it (fewer say so instead).
MIN_CORRELATION_CONFIGS = 8
#: Markers of the light classes drawn over a method's own marker.
_CLASS_OVERLAY = {"family": "+", "fixed": "x"}


def report_stem(scene: str, light: str) -> str:
    """``pareto-<scene>-<light>`` with anything but letters, digits, ``.``, ``_`` replaced."""
    def safe(text: str) -> str:
        return re.sub(r"[^A-Za-z0-9._]+", "_", Path(text).stem if "/" in text else text)

    return f"pareto-{safe(scene)}-{safe(light)}"


def method_style(method: str) -> tuple[str, tuple]:
    """A marker and colour per method, fixed by its place among the registered methods."""
    import matplotlib

    names = METHODS.names()
    index = names.index(method) if method in names else len(names) + sum(map(ord, method))
    colours = matplotlib.colormaps["tab10"].colors
    return _MARKERS[index % len(_MARKERS)], colours[index % len(colours)]


def _fmt(value: float, digits: int = 4) -> str:
    if value is None or not math.isfinite(value):
        return "—"
    if abs(value) >= 1e5 or (value != 0 and abs(value) < 1e-3):
        return f"{value:.{digits - 1}e}"
    return f"{value:.{digits}g}"


def _panels(points: list[Point]) -> dict[str, list[Point]]:
    panels: dict[str, list[Point]] = defaultdict(list)
    for p in points:
        panels[p.panel].append(p)
    return dict(sorted(panels.items()))


def reference_of(panel: str) -> str:
    """The reference a panel scores against (``path/b0/256spp``), from its name."""
    match = re.search(r"ref=(\S+)", panel)
    return match.group(1) if match else ""


def _interval(p: Point) -> str:
    if not (math.isfinite(p.error_lo) and math.isfinite(p.error_hi)):
        return "—"
    return f"{_fmt(p.error_lo)}–{_fmt(p.error_hi)}"


def display_path(path: Path) -> str:
    """A path as a report may name it: relative to the working folder, else its name only
    (committed reports never name a machine's absolute path)."""
    path = Path(path)
    try:
        return str(path.resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return path.name


def csv_text(result: ParetoResult) -> str:
    """Every point, one line each (full float precision)."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(_CSV_COLUMNS)
    for p in result.points:
        finite = lambda v: repr(v) if v is not None and math.isfinite(v) else ""  # noqa: E731
        writer.writerow([
            p.scene, p.light, p.variant, p.width, p.height, p.profile, p.method, p.config_json,
            p.panel, reference_of(p.panel), p.light_class, p.split,
            result.error, repr(p.error), finite(p.error_lo), finite(p.error_hi),
            repr(p.error_unclipped), int(p.clipped),
            "" if p.ceiling_db is None else repr(p.ceiling_db), result.cost, finite(p.cost),
            "" if p.dominated is None else int(not p.dominated),
            "" if p.dominated is None else int(p.dominated), ";".join(p.tied_with), p.views,
            p.rows, ";".join(p.run_ids), ";".join(map(str, p.timing_workers)),
            *(repr(p.ops_counts[k]) if k in p.ops_counts else "" for k in ("madds", "fetches", "bytes")),
            json.dumps(p.frame_components, sort_keys=True),
            json.dumps(p.memory_breakdown, sort_keys=True), finite(p.light_change_ms), p.note])
    return out.getvalue()


def rho_interval(rho: float, n: int) -> tuple[float, float]:
    """95 % interval of a Spearman ρ over ``n`` pairs (Fisher z, Bonett–Wright's standard
    error √(1 + ρ²/2) / √(n − 3))."""
    if n <= 3 or not math.isfinite(rho):
        return -1.0, 1.0
    z = math.atanh(max(min(rho, 0.999999), -0.999999))
    half = 1.96 * math.sqrt(1.0 + rho * rho / 2.0) / math.sqrt(n - 3)
    return math.tanh(z - half), math.tanh(z + half)


def _correlation_lines(result: ParetoResult) -> list[str]:
    """One line per renderer: how well ``ops`` ranks the measured frame times -- only where
    there are :data:`MIN_CORRELATION_CONFIGS` configurations, with the interval of ρ."""
    lines = []
    for renderer, c in result.correlation.items():
        rho_c, p_c, n_c = c["configs"]
        where = f"{renderer}; {', '.join(c['devices']) or 'unknown device'}"
        if n_c < MIN_CORRELATION_CONFIGS or not math.isfinite(rho_c):
            lines.append(f"ops model vs measured frame_ms ({where}): {n_c} configurations with "
                         f"both; a rank correlation needs at least {MIN_CORRELATION_CONFIGS}, "
                         "so none is reported")
            continue
        lo, hi = rho_interval(rho_c, n_c)
        lines.append(f"ops model vs measured frame_ms ({where}): Spearman ρ = {_fmt(rho_c, 3)} "
                     f"(95 % interval {_fmt(lo, 2)} to {_fmt(hi, 2)}, p = {_fmt(p_c, 2)}) over "
                     f"{n_c} configurations")
    return lines or ["ops model vs measured frame_ms: no timed rows"]


def _load_note(points, cost: str) -> str:
    """The load range of the timed rows (reproduction.load_note's wording); '' if none."""
    if cost != "frame_ms":
        return ""
    import pandas as pd

    frame = pd.DataFrame({"load_average": [v for p in points for v in p.loads],
                          "device": [d for p in points for _ in p.loads
                                     for d in (p.devices[:1] or [None])]})
    return load_note([frame])


def markdown_text(result: ParetoResult, *, results_path: Path, figure_name: str) -> str:
    """The report: provenance, how error and cost are defined, the model check, each front."""

    error, cost = result.error, result.cost
    unit = cost_mod.COST_UNITS[cost]
    points = result.points
    devices = sorted({d for p in points for d in p.devices})
    renderers = sorted({r for p in points for r in p.renderers})
    shas = sorted({s for p in points for s in p.git_shas})
    better = "higher" if ERRORS[error] else "lower"
    lines = [
        f"# Pareto front: {result.scene} under {result.light} ({error} vs {cost})", "",
        f"Generated by `prtbench pareto --scene {result.scene} --light {result.light} "
        f"--error {error} --cost {cost} --profile {result.profile}` from "
        f"`{display_path(results_path)}` (read-only) with prtbench {git_sha()}, under the "
        "protocol of docs/PROTOCOL.md.", "",
        f"- Profile: {result.profile}. Rows measured by code version(s): {', '.join(shas) or 'unknown'}.",
        f"- Renderer(s): {'; '.join(renderers) or 'unknown'}. Device(s): {'; '.join(devices) or 'unknown'}."
        + _load_note(points, cost),
        f"- Error: {ERROR_LABELS[error]} against the path-traced reference, mean over a "
        f"configuration's views ({better} is better), with its 95 % interval (the reference's "
        "Monte Carlo noise and the spread over views). One configuration dominates another "
        "only when it is better beyond the intervals; a configuration kept on the front only "
        "by them is marked 'tie'.",
        "- Panels: rows share a panel, and a front, only when they share the reference "
        "(bounces, spp) and the view set. Light class: relight (any light), family (fitted to "
        "a family of lights), fixed (one baked light). Learnt or fitted configurations are "
        "ranked on held-out or in-family lights only (split).",
    ]
    if error == "psnr_masked":
        lines.append("- Noise ceiling: a view's PSNR above −20·log10(reference noise RMSE) of "
                     "its reference is clipped to that ceiling before averaging (column "
                     "'clipped'); configurations at the ceiling tie on error.")
    else:
        lines.append("- Noise ceiling: none is stored for FLIP (no reference-against-itself FLIP "
                     "is measured), so FLIP values are not clipped.")
    cost_text = {
        "frame_ms": (f"each row's median frame time, averaged over the views, measured on "
                     f"{'; '.join(renderers) or 'unknown'} ({'; '.join(devices) or 'unknown device'})"
                     ": device-specific (timer queries on a GPU, host clock around draw + finish "
                     "on llvmpipe); only rows measured with one worker are averaged where a "
                     "configuration has any"),
        "memory": ("every byte the renderer keeps to draw the next frame (the sum of its "
                   "memory_breakdown: transfer data, textures, weights, G-buffers, render "
                   "targets, cached images)"),
        "precompute": "precompute wall time (s) of the artifact",
        "ops": (f"device-independent operations per frame: madds + {cost_mod.OPS_WEIGHTS['fetches']:g}"
                f"·fetches + {cost_mod.OPS_WEIGHTS['bytes']:g}·bytes (prtbench/tradeoff/cost.py "
                "and each method's op_counts)"),
    }[cost]
    lines += [f"- Cost: {cost} ({unit}): {cost_text}.",
              *[f"- {line}." for line in _correlation_lines(result)], "",
              f"![Pareto front]({figure_name}.png)", ""]
    for panel, members in _panels(points).items():
        front = sorted((p for p in members if p.dominated is False), key=lambda p: p.cost)
        lines += [f"## {panel}", "",
                  f"{len(front)} of {len(members)} configurations on the front; reference "
                  f"{reference_of(panel) or 'unknown'}.", "",
                  f"| front | method | knobs | light class | split | {error} | interval "
                  f"| {cost} ({unit}) | views | clipped | runs |",
                  "|---|---|---|---|---|---:|---|---:|---:|---|---|"]
        order = sorted(members, key=lambda p: (p.dominated is not False, p.dominated is None,
                                               p.cost if math.isfinite(p.cost) else math.inf))
        for p in order:
            mark = ("tie" if p.tied_with else "yes") if p.dominated is False else (
                "—" if p.dominated is None else "")
            runs = ", ".join(p.run_ids) if p.run_ids else "—"
            lines.append(f"| {mark} | {p.method} | {knobs_text(p)} | {p.light_class} | {p.split} "
                         f"| {_fmt(p.error)} | {_interval(p)} | {_fmt(p.cost)} | {p.views} "
                         f"| {'yes' if p.clipped else ''} | {runs} |")
        ties = [p for p in members if p.tied_with]
        if ties:
            lines += ["", "Ties (on the front only because the intervals overlap):"]
            lines += [f"- {p.method} ({knobs_text(p)}) with {'; '.join(p.tied_with)}" for p in ties]
        missing = [p for p in members if p.dominated is None]
        if missing:
            lines += ["", "Not placed (cost unknown):"]
            lines += [f"- {p.method} ({knobs_text(p)}): {p.note}" for p in missing]
        lines.append("")
    if result.skipped:
        lines += ["Left out:", *[f"- {s}" for s in result.skipped], ""]
    return "\n".join(lines)


def plot(result: ParetoResult, *, png: Path, svg: Path) -> None:
    """ann-benchmarks style: a marker and colour per method, the front as a step line, the
    better direction labelled, the reference noise ceiling as a horizontal band."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import pyplot as plt

    panels = _panels(result.points)
    higher = ERRORS[result.error]
    with plt.rc_context({"svg.hashsalt": "prtbench-pareto", "font.size": 9}):
        fig, axes = plt.subplots(1, len(panels), figsize=(8.0 * len(panels), 4.6), squeeze=False)
        for ax, (panel, members) in zip(axes[0], panels.items()):
            placed = [p for p in members if p.dominated is not None]
            for method in sorted({p.method for p in placed}):
                marker, colour = method_style(method)
                mine = [p for p in placed if p.method == method]
                on = [p for p in mine if not p.dominated]
                off = [p for p in mine if p.dominated]
                # Filled: on the front; hollow: dominated. One legend entry per method.
                label = f"{method} ({mine[0].light_class})"
                for p in mine:  # the 95 % interval of the error
                    if math.isfinite(p.error_lo) and math.isfinite(p.error_hi):
                        ax.plot([p.cost, p.cost], [p.error_lo, p.error_hi], color=colour,
                                linewidth=0.8, alpha=0.6, zorder=1)
                if on:
                    ax.scatter([p.cost for p in on], [p.error for p in on], marker=marker,
                               color=colour, s=42, label=label, zorder=3, edgecolors="black",
                               linewidths=0.5)
                if off:
                    ax.scatter([p.cost for p in off], [p.error for p in off], marker=marker,
                               facecolors="none", edgecolors=colour, s=36, zorder=2,
                               label=None if on else label)
                for p in mine:  # the light class, drawn over the marker
                    if p.light_class in _CLASS_OVERLAY:
                        ax.scatter([p.cost], [p.error], marker=_CLASS_OVERLAY[p.light_class],
                                   color="black", s=20, zorder=4, linewidths=0.8)
            front = sorted((p for p in placed if not p.dominated), key=lambda p: (p.cost, -p.error if higher else p.error))
            if front:
                ax.step([p.cost for p in front], [p.error for p in front], where="post",
                        color="black", linewidth=1.2, zorder=1, label="Pareto front")
            ceilings = [p.ceiling_db for p in members if p.ceiling_db is not None]
            if result.error == "psnr_masked" and ceilings:
                lo, hi = min(ceilings), max(ceilings)
                ax.axhspan(lo - 0.15, hi + 0.15, color="0.6", alpha=0.35, zorder=0,
                           label="reference noise ceiling")
            costs = [p.cost for p in placed]
            if costs and min(costs) > 0 and max(costs) / min(costs) > 20:
                ax.set_xscale("log")
            # ann-benchmarks labels the better direction on the axes themselves.
            ax.set_xlabel(f"{result.cost} ({cost_mod.COST_UNITS[result.cost]})  (better ←)")
            ax.set_ylabel(f"{ERROR_LABELS[result.error]}  (better {'↑' if higher else '↓'})")
            ax.set_title(f"{panel}, {result.profile}\n(filled: on the front, hollow: dominated; "
                         "bars: 95 % intervals; +: family, x: fixed light)", fontsize=8)
            ax.grid(True, which="major", alpha=0.3)
            # Beside the axes: with a dozen methods any corner inside hides points.
            ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
        fig.tight_layout()
        with atomic_path(png) as tmp:
            fig.savefig(tmp, format="png", dpi=110, metadata={"Software": None})
        with atomic_path(svg) as tmp:
            fig.savefig(tmp, format="svg", metadata={"Date": None, "Creator": None})
        plt.close(fig)


def write_reports(result: ParetoResult, *, reports_dir: Path, results_path: Path) -> list[Path]:
    """``pareto-<scene>-<light>.{md,csv,png,svg}`` in ``reports_dir``, each written atomically."""
    stem = report_stem(result.scene, result.light)
    md, csv_path = reports_dir / f"{stem}.md", reports_dir / f"{stem}.csv"
    png, svg = reports_dir / f"{stem}.png", reports_dir / f"{stem}.svg"
    plot(result, png=png, svg=svg)
    with atomic_path(csv_path) as tmp:
        tmp.write_text(csv_text(result))
    with atomic_path(md) as tmp:
        tmp.write_text(markdown_text(result, results_path=results_path, figure_name=stem) + "\n")
    return [md, csv_path, png, svg]


def summary_text(result: ParetoResult) -> str:
    """What the CLI prints: the front, the model check and where the files went."""
    front = sorted((p for p in result.points if p.dominated is False),
                   key=lambda p: (p.panel, p.cost))
    lines = [f"pareto {result.scene}/{result.light}: {result.error} vs {result.cost} "
             f"({result.profile}), {len(result.points)} configurations, {len(front)} on the front"]
    panel = None
    for p in front:
        if p.panel != panel:  # one front per panel: one reference, one view set
            panel = p.panel
            members = sum(q.panel == panel for q in result.points)
            on = sum(q.panel == panel for q in front)
            lines.append(f" panel {panel}: {on} of {members} on its front")
        lines.append(f"  {p.variant:8s} {p.method:18s} {knobs_text(p):40s} {result.error}="
                     f"{_fmt(p.error)} [{_interval(p)}]{' (clipped)' if p.clipped else ''}  "
                     f"{result.cost}={_fmt(p.cost)}  {p.light_class}{'  tie' if p.tied_with else ''}")
    missing = sorted({p.method for p in result.points if p.dominated is None})
    if missing:
        lines.append(f"  cost '{result.cost}' unavailable for: {', '.join(missing)}")
    lines += ["  " + line for line in _correlation_lines(result)]
    lines += [f"wrote {p}" for p in result.paths]
    return "\n".join(lines)
