"""What the comparison site shows, read from the results store and the cache only.

A *scene page* is one (scene, light, profile) of the store. Its *configurations* are the
distinct (method, config, scene parameters, variant, resolution) measured there against the
path reference; each is the group of its stored rows. The numbers a page prints are stored
values (one row's metric, frame time, memory) or the means :mod:`prtbench.tradeoff.pareto`
takes of them (masked PSNR clipped at the reference noise ceiling, masked FLIP, frame time of
the rows measured with one worker), so the site agrees with ``prtbench pareto`` to the digit.
Rows of other statuses (degenerate, failed) and rows compared with a method reference are
listed with their reason, never plotted.

Images come from the cache (:mod:`prtbench.render.renders` for each view's render and the path
reference it was compared with); a row whose images are gone is shown without them.
"""

from __future__ import annotations

import json
import re
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

from prtbench.api import config as config_mod
from prtbench.api.errors import PrtbenchError
from prtbench.api.method import METHODS
from prtbench.api.profiles import PROFILES
from prtbench.bench.reproduction import FIGURES, TABLES
from prtbench.io.imageio import read_exr_metadata
from prtbench.render import renders
from prtbench.site.stability import collect as stability_pages
from prtbench.store import measurements
from prtbench.store.results import ResultsStore
from prtbench.tradeoff.front import collect_points, mark_fronts, noise_ceiling_db

#: Metrics a configuration's view table prints, in order.
VIEW_METRICS = ("psnr_masked", "ssim_masked", "flip_masked", "psnr")
#: The command that fills an empty store (DESIGN.md §15: sweeps feed the site).
FILL_COMMAND = "`prtbench sweep sweeps/plants-all.toml --profile quick` (or `make pareto`) fills it"


def slug(*parts: str) -> str:
    """A file-name-safe identifier of ``parts``: each part keeps letters, digits, ``.`` and
    ``_`` (anything else, ``-`` included, becomes ``_``), and ``-`` joins the parts."""
    return "-".join(re.sub(r"[^A-Za-z0-9._]+", "_", str(p)) for p in parts)


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
    """One measured configuration on a scene page."""

    id: str
    method: str
    config: dict
    knobs: str
    scene_params: dict
    variant: str
    width: int
    height: int
    rows: list
    views: list[ViewEntry] = field(default_factory=list)
    #: The Pareto point of the masked-PSNR / frame-ms front (None: nothing finite to place).
    point: object = None
    #: Mean masked FLIP as the FLIP front computes it (None: no finite value).
    flip: float | None = None
    memory_bytes: int | None = None
    precompute_s: float | None = None

    #: The scene parameters that differ between the page's configurations (the rest is noise).
    varying_params: dict = field(default_factory=dict)

    @property
    def description(self) -> str:
        """Knobs, then the scene parameters that tell it apart from its page's others."""
        params = ", ".join(f"{k}={v}" for k, v in sorted(self.varying_params.items()))
        return f"{self.knobs}{'; ' + params if params else ''}"

    @property
    def label(self) -> str:
        return f"{self.method}: {self.description}"

    @property
    def panel(self) -> tuple[str, int, int]:
        return (self.variant, self.width, self.height)


@dataclass
class ScenePage:
    """One (scene, light, profile) of the store."""

    scene: str
    light: str
    profile: str
    configurations: list[Configuration]
    #: Rows not plotted (degenerate, failed, method reference), one line each.
    unplotted: list[str]
    rows: list

    @property
    def file(self) -> str:
        return f"scene-{slug(self.scene, self.light, self.profile)}.html"

    @property
    def panels(self) -> list[tuple[str, int, int]]:
        return sorted({c.panel for c in self.configurations})


@dataclass
class Reproduced:
    """A paper table or figure with a complete report run in the store."""

    kind: str
    name: str
    profile: str
    report: object
    reproduction: object

    @property
    def file(self) -> str:
        return f"{self.kind}-{slug(self.name, self.profile)}.html"


@dataclass
class SiteData:
    """Everything the site shows."""

    results_path: Path
    pages: list[ScenePage]
    reproduced: list[Reproduced]
    missing_reproductions: list[str]
    rows: list
    #: ``prtbench stability``'s stored matrices, one page per profile (:mod:`.stability`).
    stability: list = field(default_factory=list)


def _knobs(method: str, config: dict, profile: str) -> str:
    """The knobs that differ from the method's config in ``profile``, ``k=v`` (the whole
    config if the method is no longer registered), as the Pareto reports print them."""

    try:
        defaults = config_mod.to_dict(METHODS.get(method).make_config({}, profile=profile))
    except PrtbenchError:  # a method no longer registered, or a profile it rejects
        defaults = {}
    changed = {k: v for k, v in sorted(config.items()) if defaults.get(k, object()) != v}
    return ", ".join(f"{k}={v}" for k, v in changed.items()) or "(profile defaults)"


def _config_key(row) -> tuple:
    return (row.method, json.dumps(row.config, sort_keys=True),
            json.dumps(row.scene_params or {}, sort_keys=True), row.scene_variant,
            int(row.width), int(row.height))


def _views(rows: list, cache: Path | None) -> list[ViewEntry]:
    newest: dict[int, object] = {}
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


def _page(scene: str, light: str, profile: str, rows: list, cache: Path | None) -> ScenePage:
    plotted = [r for r in rows if r.status == "ok" and r.reference_kind == "path"]
    chosen = {id(r) for r in plotted}
    unplotted = [f"{r.method} view {r.view} ({r.status}, reference {r.reference_kind}): "
                 f"{r.status_reason or 'compared with a method, not the path reference'}"
                 for r in rows if id(r) not in chosen]
    groups: dict[tuple, list] = defaultdict(list)
    for row in plotted:
        groups[_config_key(row)].append(row)
    configurations = []
    points = []
    for number, key in enumerate(sorted(groups)):
        group = groups[key]
        method, config_json, params_json, variant, width, height = key
        config = json.loads(config_json)
        psnr_points, _ = collect_points(group, error="psnr_masked", cost="frame_ms")
        flip_points, _ = collect_points(group, error="flip_masked", cost="frame_ms")
        memory = [r.memory_bytes for r in group if r.memory_bytes is not None]
        precompute = [r.precompute_s for r in group if r.precompute_s is not None]
        conf = Configuration(
            id=f"c{number:03d}", method=method, config=config, knobs=_knobs(method, config, profile),
            scene_params=json.loads(params_json), variant=variant, width=width, height=height,
            rows=group, views=_views(group, cache),
            point=psnr_points[0] if psnr_points else None,
            flip=flip_points[0].error if flip_points else None,
            memory_bytes=memory[-1] if memory else None,
            precompute_s=precompute[-1] if precompute else None)
        if conf.point is not None:
            points.append(conf.point)
        configurations.append(conf)
    mark_fronts(points, error="psnr_masked")
    keys = {k for c in configurations for k in c.scene_params}
    varying = {k for k in keys if len({json.dumps(c.scene_params.get(k)) for c in configurations}) > 1}
    for conf in configurations:
        conf.varying_params = {k: v for k, v in conf.scene_params.items() if k in varying}
    return ScenePage(scene=scene, light=light, profile=profile, configurations=configurations,
                     unplotted=unplotted, rows=rows)


def _reproduced(results_path: Path) -> tuple[list[Reproduced], list[str]]:
    """Tables and figures with a complete report run in the store, newest per profile."""

    found, missing = [], []
    for kind, registry in (("table", TABLES), ("figure", FIGURES)):
        for name in registry.names():
            reports = [measurements.latest_report(kind, name, profile=p, results_path=results_path)
                       for p in PROFILES]
            reports = [r for r in reports if r is not None]
            if not reports:
                missing.append(f"{kind} {name}")
                continue
            reproduction = registry.get(name)
            found += [Reproduced(kind, name, r.profile, r, reproduction) for r in reports]
    return found, missing


def collect(results_path: Path, *, cache: Path | None = None) -> SiteData:
    """Read the store (read-only) and the cache into :class:`SiteData`.

    Raises
    ------
    PrtbenchError
        A missing store, or one without rows (one line naming the command that fills it).
    """

    results_path = Path(results_path)
    if not results_path.exists():
        raise PrtbenchError(f"no results store at '{results_path}'; {FILL_COMMAND}")
    store = ResultsStore(results_path, readonly=True)
    rows = store.query()
    if not rows:
        raise PrtbenchError(f"results store '{results_path}' has no rows; {FILL_COMMAND}")
    by_page: dict[tuple, list] = defaultdict(list)
    for row in rows:
        by_page[(row.scene, row.light, row.profile)].append(row)
    pages = [_page(scene, light, profile, part, cache)
             for (scene, light, profile), part in sorted(by_page.items())]
    pages = [p for p in pages if p.configurations]
    if not pages:
        raise PrtbenchError(f"results store '{results_path}' has no ok rows against the path "
                            f"reference; {FILL_COMMAND}")
    reproduced, missing = _reproduced(results_path)

    return SiteData(results_path=results_path, pages=pages, reproduced=reproduced,
                    missing_reproductions=missing, rows=rows,
                    stability=stability_pages(results_path))


def mitsuba_variants(rows: list, *, cache: Path | None = None) -> list[str]:
    """The Mitsuba variants that rendered the path references of ``rows``' cached views.

    Rows do not store it; each cached path-traced reference records it in its header.
    """

    found, seen = set(), set()
    for row in rows:
        if row.reference_kind != "path" or not row.run_id:
            continue
        path = renders.entry_path(row.run_id, row.view, root=cache)
        if not path.is_file():
            continue
        try:
            ref = read_exr_metadata(path).get("reference", "")
            if ref and ref not in seen:
                seen.add(ref)
                reference = (cache or renders.cache_root()) / ref
                if reference.is_file():
                    found.add(read_exr_metadata(reference).get("variant", ""))
        except PrtbenchError:  # an unreadable entry: the page shows it without images anyway
            continue
    return sorted(found - {""})


def provenance(rows: list, *, cache: Path | None = None, measured: list[dict] = ()) -> dict[str, str]:
    """The footer's facts, each the distinct values of the rows (``n/a`` when none); the
    Mitsuba variant from the cached references' headers (:func:`mitsuba_variants`).

    ``measured`` adds the (profile, git_sha, renderer, device) of a report run's measurement
    rows (:func:`prtbench.store.measurements.provenance`): a figure of panels stores few result rows.
    """

    variants = mitsuba_variants(rows, cache=cache)

    def distinct(values) -> str:
        values = sorted({str(v) for v in values if v not in (None, "")})
        return ", ".join(values) or "n/a"

    ceilings = [c for c in (noise_ceiling_db(r.reference_noise) for r in rows
                            if r.reference_kind == "path") if c is not None]
    return {
        "git sha": distinct([*(r.git_sha for r in rows), *(m["git_sha"] for m in measured)]),
        "profile": distinct([*(r.profile for r in rows), *(m["profile"] for m in measured)]),
        "GL renderer": distinct([*(r.renderer for r in rows), *(m["renderer"] for m in measured)]),
        "timing": distinct(r.timing_source for r in rows),
        "Mitsuba variant": distinct(variants),
        "machine": distinct([*(r.device for r in rows), *(m["device"] for m in measured)]),
        "reference spp": distinct(r.reference_spp for r in rows if r.reference_kind == "path"),
        "noise ceiling (dB)": (f"{min(ceilings):.2f} to {max(ceilings):.2f}" if ceilings else "n/a"),
    }
