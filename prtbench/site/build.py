"""``prtbench report``: render the comparison site into a temporary folder, then rename it over ``--out``.

Everything is read first (:func:`prtbench.site.data.collect`: a missing or empty store is a
one-line error before anything is written), then the pages and images are written into a
temporary folder beside ``--out``, which replaces ``--out`` only when complete: an error or an
interrupt leaves the previous site (or nothing) in place. A previous site's ``screenshots/``
(written by the browser test, committed for the README) is carried over. ``--out`` must be
absent, empty or an earlier site (it holds the marker file :data:`MARKER`): the rename would
otherwise delete someone's folder.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import sys
import tempfile
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import jinja2

from prtbench.api.errors import InvalidInputError
from prtbench.bench import claims as claims_mod
from prtbench.bench import claims_page, outputs
from prtbench.bench.reproduction import run_table
from prtbench.render import renders
from prtbench.site import data as data_mod
from prtbench.site import plot as plot_mod
from prtbench.site import stability as stability_mod
from prtbench.site.images import STOPS, ImageMaker, stop_name
from prtbench.site.panels import exact, fmt
from prtbench.store import measurements

#: Marks a folder as a site this command wrote (so rebuilding may replace it).
MARKER = ".prtbench-site"
#: Files of ``static/`` copied next to the pages; plotly.js comes from the plotly package.
STATIC = ("site.css", "compare.js", "pareto.js")
PLOTLY_JS = "plotly.min.js"
#: The claims ledger's page (a reproduction certificate).
CLAIMS_PAGE = "claims.html"
#: Folders of a previous site kept across rebuilds.
KEPT = ("screenshots",)


@dataclass
class BuildSummary:
    out: Path
    pages: list[str]
    images_made: int
    images_reused: int


def _cell(text: str) -> str:
    """A CSV cell as the site prints it: integers as they are, other numbers by :func:`fmt`."""
    try:
        int(text)
        return text
    except ValueError:
        pass
    try:
        return fmt(float(text))
    except ValueError:
        return text


def _environment():
    env = jinja2.Environment(loader=jinja2.PackageLoader("prtbench.site", "templates"),
                             autoescape=jinja2.select_autoescape(["html"]),
                             undefined=jinja2.StrictUndefined, trim_blocks=True, lstrip_blocks=True)
    env.filters["num"] = fmt
    env.filters["exact"] = exact
    env.filters["cellfmt"] = _cell
    env.filters["mib"] = lambda v: None if v is None else float(v) / 2**20
    return env


def check_out(out: Path) -> None:
    """``out`` may be written: a creatable folder, absent, empty or an earlier site."""

    outputs.check_folder("--out", out)
    foreign = [p for p in out.iterdir() if p.name not in KEPT] if out.is_dir() else []
    if foreign and not (out / MARKER).is_file():
        raise InvalidInputError(f"--out '{out}' is a folder that is not a prtbench site (no {MARKER}); "
                                f"accepted: a new or empty folder, or an earlier `prtbench report` output")


def build(*, results_path: Path, out: Path, cache: Path | None = None,
          echo: bool = True) -> BuildSummary:
    """Build the site of the store at ``results_path`` into ``out``.

    Raises
    ------
    PrtbenchError
        A missing or empty store, or an unusable ``out`` (one line, nothing written).
    """
    out = Path(out)
    check_out(out)
    site = data_mod.collect(Path(results_path), cache=cache)
    out.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent))
    try:
        summary = _write(site, staging, cache=cache, echo=echo)
        for name in KEPT:
            if (out / name).is_dir():
                shutil.copytree(out / name, staging / name)
        _swap(staging, out)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    summary.out = out
    return summary


def _swap(staging: Path, out: Path) -> None:
    """Put ``staging`` at ``out``; the old ``out`` is moved aside first, then removed."""
    os.chmod(staging, 0o755)  # mkdtemp makes it private
    old = None
    if out.exists():
        old = Path(tempfile.mkdtemp(prefix=f".{out.name}.old.", dir=out.parent))
        os.replace(out, old / "site")
    os.replace(staging, out)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def _write(site: data_mod.SiteData, root: Path, *, cache: Path | None, echo: bool) -> BuildSummary:
    env = _environment()
    # The store it was built from, for the browser test (tests/prtbench/site/test_site_browser.py).
    (root / MARKER).write_text(json.dumps({"written_by": "prtbench report",
                                           "results": str(site.results_path.resolve())}) + "\n")
    static = root / "static"
    static.mkdir()
    for name in STATIC:
        shutil.copyfile(resources.files("prtbench.site") / "static" / name, static / name)
    shutil.copyfile(_plotly_js(), static / PLOTLY_JS)
    maker = ImageMaker(root, cache=cache)
    pages = []
    for page in site.pages:
        if echo:
            print(f"[report] {page.file}: {len(page.configurations)} configurations",
                  file=sys.stderr, flush=True)
        viewer = _page_images(page, maker)
        plots = []
        for panel in page.panels:
            plots.append({"id": f"pareto-{panel.id}", "panel": panel,
                          "figure": plot_mod.figure(panel.configurations,
                                                    title=f"{panel.title}, {page.profile}"),
                          "points": len(plot_mod.placed(panel.configurations)),
                          "members": len(panel.configurations)})
        html = env.get_template("scene.html").render(
            page=page, viewer=viewer, plots=plots,
            viewer_images={c["id"]: c["views"] for c in viewer["configs"]}, stops=STOPS, site=site,
            provenance=data_mod.provenance(page.rows, cache=cache),
            title=f"{page.scene} under {page.light} ({page.profile})")
        (root / page.file).write_text(html, encoding="utf-8")
        pages.append(page.file)
    reproduced = []
    for item in site.reproduced:
        pages.append(_reproduction_page(item, site, root, env, maker_cache=cache))
        reproduced.append(item)
    for page in site.stability:
        html = env.get_template("stability.html").render(
            page=page, site=site, title=f"stability at the extremes ({page.profile})",
            provenance=data_mod.provenance([], cache=cache, measured=stability_mod.measured(page)))
        (root / page.file).write_text(html, encoding="utf-8")
        pages.append(page.file)
    pages.append(_claims_page(site, root, env, reproduced=reproduced, cache=cache))
    html = env.get_template("index.html").render(
        site=site, overview=_overview(site), reproduced=reproduced, claims=CLAIMS_PAGE,
        provenance=data_mod.provenance(site.rows, cache=cache),
        title="prtbench comparison report")
    (root / "index.html").write_text(html, encoding="utf-8")
    pages.insert(0, "index.html")
    return BuildSummary(out=root, pages=pages, images_made=maker.made, images_reused=maker.reused)


def _claims_page(site: data_mod.SiteData, root: Path, env, *,
                 reproduced: list[data_mod.Reproduced], cache: Path | None) -> str:
    """The reproduction certificate: every claim of the ledger decided from the site's store
    (:func:`prtbench.bench.claims.evaluate`), linked to the report pages the site has."""
    assessments, error = [], ""
    try:
        assessments = claims_mod.evaluate(claims_mod.all_claims(), results_path=site.results_path)
    except Exception as exc:  # noqa: BLE001 - a broken ledger must not sink the site
        error = " ".join(str(exc).split()) or type(exc).__name__
    html = env.get_template("claims.html").render(
        site=site, assessments=assessments, counts=claims_page.counts(assessments), error=error,
        provenance=data_mod.provenance(site.rows, cache=cache),
        report_pages={f"{item.kind} {item.name}": item.file for item in reproduced},
        title="the papers' claims")
    (root / CLAIMS_PAGE).write_text(html, encoding="utf-8")
    return CLAIMS_PAGE


def _plotly_js() -> Path:
    import plotly

    path = Path(plotly.__file__).parent / "package_data" / PLOTLY_JS
    if not path.is_file():
        raise InvalidInputError(f"plotly's {PLOTLY_JS} is missing from '{path.parent}'; "
                                f"reinstall plotly (`make setup`)")
    return path


def _page_images(page: data_mod.ScenePage, maker: ImageMaker) -> dict:
    """Make every PNG of a page; returns the comparison viewer's JSON."""

    folder = f"images/{data_mod.slug(page.scene, page.light, page.profile)}"
    configs = []
    refs: dict[Path, str] = {}
    for conf in page.configurations:
        views = {}
        for entry in conf.views:
            if entry.render is None or entry.reference is None:
                continue
            ref_name = refs.get(entry.reference)
            if ref_name is None:
                checked = renders.load_reference(entry.reference)
                if checked is None:
                    continue
                ref_name = refs[entry.reference] = f"ref-{maker.source_hash(entry.reference)[:12]}"
            stem = f"{folder}/{conf.id}-v{entry.view:02d}"
            ref_stem = f"{folder}/{ref_name}"
            e = entry.exposure
            view = {
                "method": {str(ev): maker.display(entry.render, exposure=e, ev=ev,
                                                  target=f"{stem}-{stop_name(ev)}.png") for ev in STOPS},
                "reference": {str(ev): maker.display(entry.reference, exposure=e, ev=ev,
                                                     target=f"{ref_stem}-{stop_name(ev)}.png") for ev in STOPS},
                "flip": maker.flip(entry.render, entry.reference, exposure=e, target=f"{stem}-flip.png"),
                "thumb": maker.thumbnail(entry.render, exposure=e, target=f"{stem}-thumb.png"),
                "reference_thumb": maker.thumbnail(entry.reference, exposure=e,
                                                   target=f"{ref_stem}-thumb.png"),
                "flip_thumb": maker.flip(entry.render, entry.reference, exposure=e,
                                         target=f"{stem}-flip-thumb.png", thumb=True),
                "exr": _copy(entry.render, maker.site, f"{stem}.exr"),
                "reference_exr": _copy(entry.reference, maker.site, f"{ref_stem}.exr"),
            }
            views[str(entry.view)] = view
        configs.append({"id": conf.id, "label": conf.label, "method": conf.method, "views": views})
    return {"stops": list(STOPS), "configs": configs,
            "views": sorted({int(v) for c in configs for v in c["views"]})}


def _copy(source: Path, site: Path, target: str) -> str:
    out = site / target
    if not out.exists():
        out.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(source, out)
    return target


def _overview(site: data_mod.SiteData) -> list[dict]:
    """Index rows: per scene page, panel and method, its best configuration by masked PSNR
    (errors against different references or view sets are never compared)."""
    rows = []
    for page in site.pages:
        for panel in page.panels:
            by_method: dict[str, list] = {}
            for conf in panel.configurations:
                by_method.setdefault(conf.method, []).append(conf)
            for method, confs in sorted(by_method.items()):
                best = max(confs, key=lambda c: c.point.error)
                flips = [c.flip for c in confs if c.flip is not None]
                rows.append({"page": page, "panel": panel, "method": method, "best": best,
                             "configs": len(confs), "best_flip": min(flips) if flips else None})
    return rows


def _reproduction_page(item: data_mod.Reproduced, site: data_mod.SiteData, root: Path, env, *,
                       maker_cache: Path | None) -> str:
    """A table's or figure's page from its newest complete report run (``--from-store``)."""

    work = Path(tempfile.mkdtemp(prefix=".reproduction-", dir=root))
    try:
        header, table_rows, notes, images = [], [], "", []
        error = ""
        try:
            if item.kind == "table":
                md, csv_path = run_table(item.reproduction, profile=item.profile,
                                         results_path=site.results_path, reports_dir=work,
                                         progress=False, from_store=True)
                with open(csv_path, newline="") as fh:
                    reader = list(csv.reader(fh))
                header, table_rows = reader[0], reader[1:]
                notes = md.read_text()
            else:
                paths = item.reproduction.make(profile=item.profile, reports_dir=work,
                                               results_path=site.results_path, progress=False,
                                               from_store=True)
                for path in paths:
                    if path.suffix == ".png":
                        images.append(_copy(path, root, f"images/{item.kind}s/{data_mod.slug(item.name, item.profile)}-{path.name}"))
                    elif path.suffix == ".md":
                        notes = path.read_text()
        except Exception as exc:  # noqa: BLE001 - one broken formatter must not sink the site
            error = " ".join(str(exc).split()) or type(exc).__name__
        members = set(item.report.members)
        rows = [r for r in site.rows if r.run_id in members]
        html = env.get_template("reproduction.html").render(
            item=item, header=header, table_rows=table_rows, notes=notes, images=images,
            error=error, provenance=data_mod.provenance(
                rows, cache=maker_cache,
                measured=measurements.provenance(item.report.run_id, results_path=site.results_path)),
            title=f"{item.kind} {item.name} ({item.profile})")
    finally:
        shutil.rmtree(work, ignore_errors=True)
    (root / item.file).write_text(html, encoding="utf-8")
    return item.file
