"""The demo's last word: what to use on this scene, in plain language, from stored results.

``prtbench answer`` reads the scene analysis (``analyze --json``), the advice (``advise
--json``) and the results store, and prints a few lines a newcomer can act on: the scene and
light, what the scene requires, the advised configuration with its interval and cost, the
runner-up, and the front of the main panel in three lines (cheapest, middle, best). Every
number is read from those files or computed from stored rows (docs/PROTOCOL.md: the interval of
the advised configuration comes from its stored views), never typed in.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from prtbench.api.config import format_bytes
from prtbench.api.errors import InvalidInputError, PrtbenchError
from prtbench.store.results import ResultsStore, default_path
from prtbench.tradeoff.cost import OPS_WEIGHTS
from prtbench.tradeoff.front import Point, collect_points, knobs_text, mark_fronts


def _read_json(path: Path, what: str) -> dict[str, Any]:
    try:
        return json.loads(Path(path).read_text())
    except FileNotFoundError:
        raise InvalidInputError(f"{what} '{path}' does not exist; accepted: the file "
                                f"`prtbench {what.split()[0]} --json` wrote") from None
    except (OSError, ValueError) as exc:
        raise InvalidInputError(f"{what} '{path}' is not readable JSON ({exc}); accepted: the "
                                f"file `prtbench {what.split()[0]} --json` wrote") from None


def requirements(analysis: Mapping[str, Any]) -> str:
    """What the analysis found the scene needs, as one sentence."""
    parts = [f"{analysis['required_bands']} SH bands for a {100 * analysis['target']:g} % "
             "irradiance error" if analysis["required_bands"] <= 16 else
             "more than 16 SH bands for a 1 % irradiance error (all-frequency light)"]
    parts.append("glossy transfer" if analysis["needs_glossy"] else "diffuse transfer only")
    parts.append("shadows" if analysis["needs_shadows"] else "no shadowing")
    if analysis["needs_textures"]:
        parts.append("per-texel detail (vertices are too coarse)")
    parts.append("interreflections" if analysis["needs_bounces"] else "direct light dominates")
    return ", ".join(parts)


def _knobs(config: Mapping[str, Any], keys: Sequence[str] | None = None) -> str:
    keys = list(keys) if keys is not None else sorted(config)
    return " ".join(f"{k}={config[k]}" for k in keys if k in config) or "(defaults)"


def _config_point(points: Sequence[Point], method: str, config: Mapping[str, Any], *,
                  psnr: float | None = None) -> Point | None:
    """The stored point of ``method`` whose config agrees with ``config`` on its keys; of
    several (the same configuration in the sweep's panel, a fixed-view panel and the advice's
    own verification run), the one whose mean is the advised value."""
    matches = [p for p in points
               if p.method == method and all(p.config.get(k) == v for k, v in config.items())]
    if not matches:
        return None
    if psnr is None:
        return max(matches, key=lambda p: p.views)
    return min(matches, key=lambda p: (abs(p.error_unclipped - psnr), -p.views))


def _interval(p: Point | None) -> str:
    if p is None or not (math.isfinite(p.error_lo) and math.isfinite(p.error_hi)):
        return ""
    return f" [{p.error_lo:.1f}, {p.error_hi:.1f}]"


def _cost_text(entry: Mapping[str, Any], point: Point | None, renderer: str) -> str:
    """Frame time (with its renderer), resident memory and operations of a configuration."""
    parts = []
    if entry.get("frame_ms") is not None:
        parts.append(f"{entry['frame_ms']:.3g} ms a frame on {renderer or 'this device'}")
    if entry.get("memory_bytes") is not None:
        parts.append(f"{format_bytes(int(entry['memory_bytes']))} resident")
    if point is not None and point.ops_counts:
        ops = sum(OPS_WEIGHTS[k] * point.ops_counts[k] for k in OPS_WEIGHTS)
        parts.append(f"{ops:.3g} ops a frame")
    return ", ".join(parts)


def _front_lines(points: Sequence[Point]) -> list[str]:
    """The front of the main panel, in at most three lines: the panel with most configurations
    among those scored on more than one view (a fixed-view panel re-scores the same rows on one
    view; it is the main panel only when there is no other)."""
    panels: dict[str, list[Point]] = {}
    for p in points:
        panels.setdefault(p.panel, []).append(p)
    if not panels:
        return ["  (no stored front)"]
    panel, members = max(panels.items(), key=lambda kv: (
        max(p.views for p in kv[1]) > 1, len(kv[1]), max(p.views for p in kv[1])))
    front = sorted((p for p in members if p.dominated is False), key=lambda p: p.cost)
    if not front:
        return [f"  (no configuration of panel {panel} has a finite cost)"]
    # The cheapest, the most accurate and one between them by cost: with few views the
    # intervals keep many points on the front, and the costliest of them need not be the best.
    best = max(front, key=lambda p: p.error)  # masked PSNR: higher is better
    between = [p for p in front if p.cost < best.cost and p is not front[0]]
    picks = []
    for p in [front[0], *between[len(between) // 2:][:1], best]:
        if all(p is not q for q in picks):
            picks.append(p)
    labels = (["cheapest", "middle", "accurate"] if len(picks) == 3
              else ["cheapest", "accurate"] if len(picks) == 2 else ["only"])
    views = max(p.views for p in members)
    wide = (f"; with {views} views per configuration the intervals keep most of them on it, "
            "more views separate them" if views <= 2 and 2 * len(front) > len(members) else "")
    out = [f"  the front ({len(front)} of {len(members)} configurations; {panel}{wide}):"]
    for label, p in zip(labels, picks):
        tie = " (tied within the intervals)" if p.tied_with else ""
        out.append(f"    {label:8s} {p.method} {knobs_text(p)}: {p.error:.1f} dB"
                   f"{_interval(p)} at {p.cost:.3g} ms a frame, {p.light_class}{tie}")
    return out


def answer(*, analysis_path: Path, advice_path: Path, results_path: Path | None = None,
           profile: str = "quick", target: str = "", site: Path | None = None) -> str:
    """The plain-language answer (module docstring).

    Raises
    ------
    PrtbenchError
        A missing or unreadable file, or a store without the scene's rows (one line).
    """
    analysis = _read_json(Path(analysis_path), "analyze JSON")
    advice = _read_json(Path(advice_path), "advise JSON")
    path = Path(results_path) if results_path else default_path()
    if not path.exists():
        raise PrtbenchError(f"no results store at '{path}'; `make demo` fills it")
    scene, light = analysis["scene"], analysis["light"]
    rows = [r for r in ResultsStore(path, readonly=True).query(scene=scene, profile=profile,
                                                                 status="ok")
            if r.light == light]
    points, _ = collect_points(rows, error="psnr_masked", cost="frame_ms")
    mark_fronts(points, error="psnr_masked")
    renderer = next((r.renderer for r in rows if r.renderer), "")
    lines = [f"Answer for {scene} ({analysis['variant']}) under {light}, {profile} profile:",
             f"  the scene needs {requirements(analysis)}."]
    psnr = (advice.get("metrics") or {}).get("psnr_masked")
    chosen = _config_point(points, advice["method"], advice.get("config") or {}, psnr=psnr)
    use = (f"  use {advice['method']} {_knobs(advice.get('config') or {}, _searched(advice))}: "
           f"{psnr:.1f} dB masked PSNR{_interval(chosen)}" if psnr is not None else
           f"  use {advice['method']}")
    cost = _cost_text(advice, chosen, renderer)
    lines.append(use + (f"; {cost}" if cost else "")
                 + f" -- the cheapest by {advice.get('cost_kind')} that meets "
                 + (f"{target}." if target else "the target."))
    runner = advice.get("runner_up")
    if runner:
        rpsnr = (runner.get("metrics") or {}).get("psnr_masked")
        lines.append(f"  runner-up: {runner['method']} "
                     f"{_knobs(runner.get('config') or {}, _searched(runner))}"
                     + (f", {rpsnr:.1f} dB" if rpsnr is not None else ""))
    lines += _front_lines(points)
    if site is not None:
        lines.append(f"  the comparison site: open {site}")
    return "\n".join(lines)


def _searched(entry: Mapping[str, Any]) -> list[str]:
    """The knobs worth naming: those the advisor searched (else every knob)."""
    config = entry.get("config") or {}
    named = [k for k in ("sh_bands", "resolution", "texture_resolution", "light_terms", "basis",
                         "hidden", "terms", "bounces") if k in config]
    return named or sorted(config)
