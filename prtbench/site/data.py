"""What the comparison site shows, read from the results store and the cache only.

A *scene page* is one (scene, light, profile) of the store, laid out in the ranking
protocol's panels (docs/PROTOCOL.md, :mod:`.panels`): one reference and one view set per
panel, each with its own plot, table and front. The numbers a page prints are stored values
(one row's metric, frame time, memory) or the means and intervals
:func:`prtbench.tradeoff.front.collect_points` takes of them (masked PSNR clipped at the
reference noise ceiling, masked FLIP, frame time of the rows measured with one worker), so the
site agrees with ``prtbench pareto`` to the digit. Rows of other statuses (degenerate,
failed), rows compared with a method reference, diagnostic configurations and ``trained``
rows are listed with their reason, never plotted.

Images come from the cache (:mod:`prtbench.render.renders` for each view's render and the path
reference it was compared with); a row whose images are gone is shown without them.
"""

from __future__ import annotations

import re
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

from prtbench.api.errors import PrtbenchError
from prtbench.api.profiles import PROFILES
from prtbench.bench.reproduction import FIGURES, TABLES
from prtbench.io.imageio import read_exr_metadata
from prtbench.render import renders
from prtbench.site.panels import Configuration, Panel, page_panels
from prtbench.site.stability import collect as stability_pages
from prtbench.store import measurements
from prtbench.store.results import ResultsStore
from prtbench.tradeoff.front import noise_ceiling_db

#: Metrics a configuration's view table prints, in order.
VIEW_METRICS = ("psnr_masked", "ssim_masked", "flip_masked", "psnr")
#: The command that fills an empty store (DESIGN.md §15: sweeps feed the site).
FILL_COMMAND = "`prtbench sweep sweeps/plants-all.toml --profile quick` (or `make pareto`) fills it"


def slug(*parts: str) -> str:
    """A file-name-safe identifier of ``parts``: each part keeps letters, digits, ``.`` and
    ``_`` (anything else, ``-`` included, becomes ``_``), and ``-`` joins the parts."""
    return "-".join(re.sub(r"[^A-Za-z0-9._]+", "_", str(p)) for p in parts)


@dataclass
class ScenePage:
    """One (scene, light, profile) of the store, in the protocol's panels (:mod:`.panels`)."""

    scene: str
    light: str
    profile: str
    panels: list[Panel]
    #: Rows and configurations not plotted (degenerate, failed, method reference, diagnostic,
    #: trained), one line each with the reason.
    unplotted: list[str]
    rows: list

    @property
    def file(self) -> str:
        return f"scene-{slug(self.scene, self.light, self.profile)}.html"

    @property
    def configurations(self) -> list[Configuration]:
        """Every panel's configurations, in page order (one per configuration and panel)."""
        return [c for panel in self.panels for c in panel.configurations]


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


def _page(scene: str, light: str, profile: str, rows: list, cache: Path | None) -> ScenePage:
    usable = {id(r) for r in rows if r.status == "ok" and r.reference_kind == "path"}
    unplotted = [f"{r.method} view {r.view} ({r.status}, reference {r.reference_kind}): "
                 f"{r.status_reason or 'compared with a method, not the path reference'}"
                 for r in rows if id(r) not in usable]
    panels, left_out = page_panels(rows, cache=cache)
    return ScenePage(scene=scene, light=light, profile=profile, panels=panels,
                     unplotted=unplotted + left_out, rows=rows)


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
    # A page whose ok rows are all left out (diagnostic, trained) still says why.
    pages = [p for p in pages
             if any(r.status == "ok" and r.reference_kind == "path" for r in p.rows)]
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
