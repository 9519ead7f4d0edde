"""A scene page's configurations, grouped into the ranking protocol's panels (docs/PROTOCOL.md).

A *panel* is one reference (path tracer with its bounces and spp) and one view set: the
stored row field ``panel`` (legacy rows without one get :mod:`prtbench.tradeoff.front`'s
legacy panel). Configurations share a plot and a table only when they share the panel; a
fixed-view panel (all its rows on one view: a per-pixel method) also takes every other
method's row on that view. A configuration measured in two panels is one
:class:`Configuration` in each, with the point, the rows and the images of that panel.

Every number is the one ``prtbench pareto`` prints: the site calls
:func:`~prtbench.tradeoff.front.collect_points` and :func:`~prtbench.tradeoff.front.mark_fronts`
on the page's rows. It adds one dimension the fronts do not group by, the scene parameters
(a tessellation level is a configuration of its own): each set of scene parameters is
collected on its own, and every point of a panel is then marked on one front. Diagnostic
configurations and rows of a split the ranking does not take (``trained``) are never placed:
the page lists them with the protocol's reason.
"""

from __future__ import annotations

import json
import math
import re
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

from prtbench.render import renders
from prtbench.tradeoff.front import (
    collect_points,
    knobs_text,
    mark_fronts,
    panel_memberships,
)
from prtbench.tradeoff.pareto_report import reference_of

#: The splits a ranking takes (collect_points' default); rows of other splits are listed.
RANKED_SPLITS = ("held-out", "in-family")
#: The view count in a panel's name (``views=4:1a2b3c4d``).
_VIEW_COUNT = re.compile(r"\bviews=(\d+):")


def fmt(value, digits: int = 4) -> str:
    """How the site prints a number: 4 significant digits, ``—`` for a missing value."""
    if value is None or isinstance(value, str):
        return "—" if value in (None, "") else value
    if isinstance(value, (bool, int)):
        return str(value)
    value = float(value)
    if not math.isfinite(value):
        return "—"
    if abs(value) >= 1e5 or (value != 0 and abs(value) < 1e-3):
        return f"{value:.{digits - 1}e}"
    return f"{value:.{digits}g}"


def exact(value) -> str:
    """The stored value as a page's ``data-value`` attribute keeps it: ``repr`` of a float
    (every digit), ``""`` for a missing or non-finite one."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return ""
    return repr(float(value)) if isinstance(value, float) else str(value)


def error_text(value: float, lo: float, hi: float, unit: str = "") -> str:
    """``27.31 dB [26.9, 27.72]``: a value and its 95 % interval (the value alone when the
    interval is unknown)."""
    if math.isfinite(lo) and math.isfinite(hi):
        return f"{fmt(value)}{unit} [{fmt(lo)}, {fmt(hi)}]"
    return f"{fmt(value)}{unit}"


@dataclass
class ViewEntry:
    """One stored view of a configuration: the row and where its images are cached.

    Attributes
    ----------
    row : prtbench.store.results.ResultRow
        The newest row of this view (a re-timed cell has several; their metrics agree).
    render, reference : Path or None
        The cached linear render and the reference EXR it was compared with.
    exposure : float or None
        The scene's display exposure, from the render's header.
    """

    view: int
    row: object
    render: Path | None = None
    reference: Path | None = None
    exposure: float | None = None


@dataclass
class Configuration:
    """One configuration in one panel: its masked-PSNR / frame-ms point and the rows behind it.

    Attributes
    ----------
    point : prtbench.tradeoff.front.Point
        The masked-PSNR point (error, interval, cost, light class, split, ``tied_with``,
        frame components, memory breakdown, ``light_change_ms``), marked on its panel's front.
    flip : float or None
        Mean masked FLIP as the FLIP front computes it (None: no finite value).
    rows : list of ResultRow
        The ranked rows of this panel (``trained`` rows are left out, as the front leaves them).
    """

    id: str
    method: str
    config: dict
    knobs: str
    scene_params: dict
    panel: str
    point: object
    rows: list
    views: list[ViewEntry] = field(default_factory=list)
    flip: float | None = None
    memory_bytes: int | None = None
    precompute_s: float | None = None
    #: The scene parameters that differ between the page's configurations (the rest is noise).
    varying_params: dict = field(default_factory=dict)
    #: The panel's reference and view count, in the label when the page has several panels.
    panel_note: str = ""
    #: ``c003 vertex: sh_bands=2``: the configurations of its panel it ties with (the point's
    #: ``tied_with``: they would dominate it were it not for the intervals).
    ties: list[str] = field(default_factory=list)

    @property
    def description(self) -> str:
        """Knobs, then the scene parameters that tell it apart from its page's others."""
        params = ", ".join(f"{k}={v}" for k, v in sorted(self.varying_params.items()))
        return f"{self.knobs}{'; ' + params if params else ''}"

    @property
    def label(self) -> str:
        note = f" [{self.panel_note}]" if self.panel_note else ""
        return f"{self.method}: {self.description}{note}"

    @property
    def params_json(self) -> str:
        return json.dumps(self.scene_params, sort_keys=True)

    @property
    def error_text(self) -> str:
        p = self.point
        return error_text(p.error, p.error_lo, p.error_hi, " dB")

    @property
    def front(self) -> str:
        """``yes``, ``tie`` (on the front only through the intervals), ``not placed`` (cost
        unknown) or empty (dominated)."""
        if self.point.dominated is None:
            return "not placed"
        if self.point.dominated:
            return ""
        return "tie" if self.point.tied_with else "yes"


@dataclass
class Panel:
    """One protocol panel of a scene page: one reference, one view set, one front."""

    id: str
    name: str
    views: int
    configurations: list[Configuration]

    @property
    def reference(self) -> str:
        """``path/b1/256spp`` (from the panel's name)."""
        return reference_of(self.name) or "unknown"

    @property
    def fixed_view(self) -> bool:
        return self.views == 1 and "views=" in self.name

    @property
    def note(self) -> str:
        """``reference path/b0/32spp, 2 views``."""
        return f"reference {self.reference}, {self.views} view{'s' if self.views != 1 else ''}"

    @property
    def title(self) -> str:
        p = self.configurations[0].point
        return f"{p.scene}/{p.variant} under {p.light}, {p.width}×{p.height}: {self.note}"


def _views(rows: list, cache: Path | None) -> list[ViewEntry]:
    newest: dict[int, tuple] = {}
    for row in rows:  # insertion order: the last row of a view wins, if its images exist
        entry = renders.load(row.run_id, row.view, root=cache) if row.run_id else None
        if entry is not None or row.view not in newest:
            newest[row.view] = (row, entry)
    out = []
    for view in sorted(newest):
        row, entry = newest[view]
        out.append(ViewEntry(view=view, row=row,
                             render=entry.path if entry is not None else None,
                             reference=entry.reference_path if entry is not None else None,
                             exposure=entry.exposure if entry is not None else None))
    return out


def _key(method: str, config_json: str, variant: str, light: str, profile: str, width: int,
         height: int, panel: str) -> tuple:
    """What collect_points groups a configuration by, within one set of scene parameters."""
    return (method, config_json, variant, light, profile, int(width), int(height), panel)


def _point_key(p) -> tuple:
    return _key(p.method, p.config_json, p.variant, p.light, p.profile, p.width, p.height,
                p.panel_name)


def _row_key(row, panel: str) -> tuple:
    return _key(row.method, json.dumps(row.config, sort_keys=True), row.scene_variant,
                row.light, row.profile, row.width, row.height, panel)


def _params_prefix(params_json: str, varying: set[str]) -> str:
    params = {k: v for k, v in json.loads(params_json).items() if k in varying}
    return f"[{', '.join(f'{k}={v}' for k, v in sorted(params.items()))}] " if params else ""


def _collect(part: list, *, prefix: str) -> tuple[list[tuple], list[str]]:
    """collect_points on the rows of one set of scene parameters.

    Returns
    -------
    found : list of (Point, Point or None, list of ResultRow)
        Each masked-PSNR point (not yet marked), its masked-FLIP point and its ranked rows:
        its panel memberships (front.py's, fixed-view panels included) without the
        ``trained`` rows collect_points leaves out.
    left_out : list of str
        collect_points' skipped lines with the panels they apply to, and one line per
        ``trained`` row of a point; each starts with ``prefix`` (the scene parameters).
    """
    points, skipped = collect_points(part, error="psnr_masked", cost="frame_ms")
    flips = {_point_key(p): p for p in collect_points(part, error="flip_masked",
                                                      cost="frame_ms")[0]}
    members: dict[tuple, list] = defaultdict(list)
    for row, panel in panel_memberships(part):
        members[_row_key(row, panel)].append(row)
    placed = {_point_key(p) for p in points}
    left_out = []
    for line in dict.fromkeys(skipped):
        # The panels it was left out of: the configuration's memberships with no point (its
        # line starts with the method and the config, as collect_points writes it).
        where = sorted({key[-1] for key in members if key not in placed
                        and line.startswith(f"{key[0]} {key[1]}")})
        left_out.append(f"{prefix}{line}" + (f" (panel {'; '.join(where)})" if where else ""))
    found = []
    for p in points:
        group = members[_point_key(p)]
        # Rows stored before the protocol have no split: collect_points ranks them.
        ranked = [r for r in group if (r.split or "unknown") in (*RANKED_SPLITS, "unknown")]
        left_out += [f"{prefix}{p.method} ({knobs_text(p)}) view {r.view}, panel "
                     f"{p.panel_name}: split '{r.split}' (measured on a light or view it "
                     "trained or fitted on), left out of the ranking (docs/PROTOCOL.md)"
                     for r in group if (r.split or "unknown") not in (*RANKED_SPLITS, "unknown")]
        found.append((p, flips.get(_point_key(p)), ranked))
    return found, left_out


def page_panels(rows: list, *, cache: Path | None = None) -> tuple[list[Panel], list[str]]:
    """The protocol panels of one scene page's rows, and the lines of what is left out.

    Parameters
    ----------
    rows : list of ResultRow
        One (scene, light, profile) of the store, every status and reference kind (only ok
        rows against the path reference are collected).
    cache : Path, optional
        The cache holding the rows' renders (default: the configured cache).

    Returns
    -------
    panels : list of Panel
        Sorted by name; configuration ids ``c000``, ``c001``, ... in that order.
    left_out : list of str
        collect_points' skipped lines (a diagnostic configuration, a configuration measured
        only on lights or views it trained on, no finite masked PSNR), each with the panels it
        was left out of, and one line per ``trained`` row of a configuration that is placed.
    """
    usable = [r for r in rows if r.status == "ok" and r.reference_kind == "path"]
    by_params: dict[str, list] = defaultdict(list)
    for row in usable:
        by_params[json.dumps(row.scene_params or {}, sort_keys=True)].append(row)
    keys = {k for params in by_params for k in json.loads(params)}
    varying = {k for k in keys
               if len({json.dumps(json.loads(p).get(k)) for p in by_params}) > 1}
    by_panel: dict[str, list] = defaultdict(list)
    left_out: list[str] = []
    for params_json, part in sorted(by_params.items()):
        found, lines = _collect(part, prefix=_params_prefix(params_json, varying))
        left_out += lines
        for point, flip, ranked in found:
            by_panel[point.panel_name].append((json.loads(params_json), point, flip, ranked))
    # One front per panel over every set of scene parameters (tessellation levels compete).
    mark_fronts([item[1] for items in by_panel.values() for item in items], error="psnr_masked")
    panels = []
    for number, (name, items) in enumerate(sorted(by_panel.items())):
        match = _VIEW_COUNT.search(name)
        views = int(match.group(1)) if match else len({r.view for *_, g in items for r in g})
        panel = Panel(id=f"p{number}", name=name, views=views, configurations=[])
        items.sort(key=lambda i: (i[1].method, i[1].config_json, json.dumps(i[0], sort_keys=True)))
        for params, p, flip, group in items:
            memory = [r.memory_bytes for r in group if r.memory_bytes is not None]
            precompute = [r.precompute_s for r in group if r.precompute_s is not None]
            panel.configurations.append(Configuration(
                id="", method=p.method, config=p.config, knobs=knobs_text(p),
                scene_params=params, panel=name, point=p, rows=group,
                views=_views(group, cache), flip=flip.error if flip is not None else None,
                memory_bytes=memory[-1] if memory else None,
                precompute_s=precompute[-1] if precompute else None,
                varying_params={k: v for k, v in params.items() if k in varying}))
        panels.append(panel)
    for number, conf in enumerate(c for panel in panels for c in panel.configurations):
        conf.id = f"c{number:03d}"
    for panel in panels:
        for conf in panel.configurations:
            conf.panel_note = panel.note if len(panels) > 1 else ""
            # tied_with names configurations by method and config; other scene parameters
            # share that name, so only the rivals that could have dominated it are named.
            conf.ties = [f"{other.id} {other.method}: {other.description}"
                         for other in panel.configurations
                         if other is not conf and other.point.label in conf.point.tied_with
                         and other.point.cost <= conf.point.cost
                         and other.point.error >= conf.point.error]
    return panels, left_out
