"""``prtbench report``: the site is built from the store and the cache only, every number it
prints equals the store's, and bad input is one line with nothing half-written (issue #16)."""

from __future__ import annotations

import csv
import json
import math
from collections import defaultdict
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from prtbench.bench.reproduction import TABLES, run_table
from prtbench.cli import main
from prtbench.render.mitsuba_variant import select_variant
from prtbench.site.build import MARKER, build, fmt
from prtbench.store.results import ResultsStore
from prtbench.tradeoff.front import collect_points, noise_ceiling_db
from tests.prtbench.site.site_store import CELLS, STABILITY_ROWS, add_stability, make_store

_VOID = {"img", "input", "br", "meta", "link", "hr", "source", "wbr"}


class _Cells(HTMLParser):
    """Every element with ``data-field`` (its value, text and the enclosing row's data), every
    table cell of reproduction tables, every ``src``/``href``."""

    def __init__(self):
        super().__init__()
        self.stack: list[tuple[str, dict]] = []
        self.numbers: list[dict] = []
        self.cells: list[list[str]] = []
        self.links: list[str] = []
        self._open: dict | None = None
        self._row: list[str] | None = None

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        for key in ("src", "href"):
            if key in attrs:
                self.links.append(attrs[key])
        if tag in _VOID:
            return
        self.stack.append((tag, attrs))
        if "data-field" in attrs:
            rows = [a for t, a in self.stack if t == "tr"]
            self._open = {"field": attrs["data-field"], "value": attrs["data-value"], "text": "",
                          "row": rows[-1] if rows else {}, "outer": rows[0] if rows else {}}
        if tag == "tr" and "reproduction" in (self._table_class() or ""):
            self._row = []
        if tag == "td" and attrs.get("class") == "cell" and self._row is not None:
            self._row.append("")

    def _table_class(self):
        tables = [a for t, a in self.stack if t == "table"]
        return tables[-1].get("class") if tables else None

    def handle_endtag(self, tag):
        if tag in _VOID:
            return
        while self.stack:
            name, attrs = self.stack.pop()
            if "data-field" in attrs and self._open is not None:
                self.numbers.append(self._open)
                self._open = None
            if name == "tr" and self._row is not None:
                if self._row:
                    self.cells.append(self._row)
                self._row = None
            if name == tag:
                break

    def handle_data(self, data):
        if self._open is not None:
            self._open["text"] += data
        if self._row is not None and self.stack and self.stack[-1][0] == "td":
            self._row[-1] += data


def _parse(path: Path) -> _Cells:
    parser = _Cells()
    parser.feed(path.read_text(encoding="utf-8"))
    return parser


@pytest.fixture(scope="module")
def store(tmp_path_factory) -> Path:
    return make_store(tmp_path_factory.mktemp("site-store"))


@pytest.fixture(scope="module")
def site(store, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("site") / "site"
    build(results_path=store, out=out, echo=False)
    return out


def _configurations(rows) -> dict[tuple, list]:
    """The store's configurations, grouped here independently of prtbench.site.data."""
    groups = defaultdict(list)
    for r in rows:
        if r.status == "ok" and r.reference_kind == "path":
            groups[(r.method, json.dumps(r.config, sort_keys=True),
                    json.dumps(r.scene_params, sort_keys=True))].append(r)
    return groups


def _check(number: dict, expected) -> None:
    """The printed text and the exact value both equal the expected stored quantity."""
    if expected is None:
        assert number["text"] == "—" and number["value"] == "", number
        return
    assert number["text"] == fmt(expected), (number, expected)
    if isinstance(expected, float):
        assert float(number["value"]) == expected, (number, expected)  # exact, not rounded
        assert math.isclose(float(number["text"]), expected, rel_tol=5e-4, abs_tol=1e-6)
    else:
        assert number["value"] == str(expected), (number, expected)


def test_every_number_on_the_scene_page_is_the_stores(store, site):
    rows = ResultsStore(store, readonly=True).query()
    groups = _configurations(rows)
    # 3 sweep configurations + 4 tessellation ground levels (vertex at its defaults).
    assert len(groups) == len(CELLS) + 4
    page = _parse(site / "scene-plants-sky-smoke.html")
    by_config = defaultdict(dict)
    view_numbers = []
    for n in page.numbers:
        if n["field"].startswith("view_"):
            view_numbers.append(n)
        else:
            by_config[n["row"]["data-config"]][n["field"]] = n
    assert len(by_config) == len(groups)
    # Which configuration id is which: the page's rows carry the run ids of their views.
    run_to_config = {}
    for n in view_numbers:
        run_to_config[n["outer"]["data-run"]] = n["outer"]["data-config"]
    checked = 0
    for key, group in groups.items():
        ids = {run_to_config[r.run_id] for r in group}
        assert len(ids) == 1, (key, ids)
        numbers = by_config[ids.pop()]
        (psnr,), _ = collect_points(group, error="psnr_masked", cost="frame_ms")
        (flip,), _ = collect_points(group, error="flip_masked", cost="frame_ms")
        _check(numbers["psnr_masked"], psnr.error)
        _check(numbers["flip_masked"], flip.error)
        _check(numbers["frame_ms"], psnr.cost)
        _check(numbers["memory_mib"], group[-1].memory_bytes / 2**20)
        _check(numbers["precompute_s"], group[-1].precompute_s)
        _check(numbers["views"], len({r.view for r in group}))
        assert set(numbers) == {"psnr_masked", "flip_masked", "frame_ms", "memory_mib",
                                "precompute_s", "views"}
        checked += 6
    stored = {(r.run_id, r.view): r for r in rows}
    for n in view_numbers:
        row = stored[(n["outer"]["data-run"], int(n["outer"]["data-view"]))]
        name = n["field"][len("view_"):]
        expected = {"frame_ms": row.frame_ms, "frame_ms_p95": row.frame_ms_p95}.get(
            name, row.metrics.get(name))
        _check(n, expected)
        checked += 1
    assert checked == 6 * len(groups) + 6 * sum(len({r.view for r in g}) for g in groups.values())


def test_every_number_on_the_index_is_the_stores(store, site):
    rows = ResultsStore(store, readonly=True).query()
    groups = _configurations(rows)
    index = _parse(site / "index.html")
    seen = set()
    for method in ("vertex", "irradiance-volume"):
        mine = [g for k, g in groups.items() if k[0] == method]
        points = [collect_points(g, error="psnr_masked", cost="frame_ms")[0][0] for g in mine]
        flips = [collect_points(g, error="flip_masked", cost="frame_ms")[0][0].error for g in mine]
        best = max(range(len(mine)), key=lambda i: points[i].error)
        numbers = [n for n in index.numbers if n["row"].get("data-method") == method]
        fields = {n["field"]: n for n in numbers}
        _check(fields["configs"], len(mine))
        _check(fields["psnr_masked"], points[best].error)
        _check(fields["flip_masked"], flips[best])
        _check(fields["frame_ms"], points[best].cost)
        _check(fields["memory_mib"], mine[best][-1].memory_bytes / 2**20)
        _check(fields["best_flip_masked"], min(flips))
        seen.add(method)
    assert seen == {r.method for r in rows}
    assert len(index.numbers) == 6 * len(seen)  # nothing printed that was not checked
    footer = (site / "index.html").read_text()
    ceilings = [noise_ceiling_db(r.reference_noise) for r in rows]
    assert f"{min(ceilings):.2f} to {max(ceilings):.2f}" in footer
    assert f'data-provenance="reference spp">{rows[0].reference_spp}<' in footer
    assert rows[0].renderer in footer and rows[0].git_sha in footer and select_variant() in footer


def test_table_page_equals_the_table_from_the_store(store, site, tmp_path):
    _, csv_path = run_table(TABLES.get("tessellation"), profile="smoke", results_path=store,
                            reports_dir=tmp_path, progress=False, from_store=True)
    with open(csv_path, newline="") as fh:
        expected = list(csv.reader(fh))[1:]
    page = _parse(site / "table-tessellation-smoke.html")
    assert len(page.cells) == len(expected) == 4
    for shown, stored in zip(page.cells, expected):
        assert len(shown) == len(stored)
        for text, value in zip(shown, stored):
            assert text == (value if value.lstrip("-").isdigit() else fmt(float(value))), (text, value)


def test_links_and_images_resolve_inside_the_site_and_the_index_is_small(site):
    pages = sorted(site.glob("*.html"))
    assert {p.name for p in pages} >= {"index.html", "scene-plants-sky-smoke.html",
                                       "table-tessellation-smoke.html"}
    for page in pages:
        for link in _parse(page).links:
            target = link.split("#")[0]
            assert "://" not in link, (page, link)  # offline: nothing from the network
            if target:
                assert (site / target).is_file(), (page.name, link)
    index_bytes = sum((site / l.split("#")[0]).stat().st_size for l in _parse(site / "index.html").links
                      if l.split("#")[0].startswith("static/")) + (site / "index.html").stat().st_size
    assert index_bytes < 2 * 2**20
    assert "plotly" not in (site / "index.html").read_text()
    for page in pages:  # the provenance footer, Mitsuba variant included, on every page
        text = page.read_text()
        assert 'id="provenance"' in text and f'data-provenance="Mitsuba variant">{select_variant()}<' in text, page


def test_images_are_the_display_images_and_are_made_once(store, site, tmp_path):
    from prtbench.io import imageio
    from prtbench.render import renders

    rows = [r for r in ResultsStore(store, readonly=True).query() if r.method == "vertex"]
    data = json.loads(_script(site / "scene-plants-sky-smoke.html", "compare-data"))
    row = rows[0]
    entry = renders.load(row.run_id, row.view)
    (shown,) = {c["views"][str(row.view)]["method"]["0"] for c in data["configs"]
                if str(row.view) in c["views"]
                and (site / c["views"][str(row.view)]["exr"]).read_bytes() == entry.path.read_bytes()}
    # The 0 EV PNG of the run's cached render is the display image the metrics compared.
    expected = imageio.png_pixels(imageio.display(entry.image, exposure=entry.exposure))
    assert (imageio.png_pixels(imageio.read_png(site / shown)) == expected).all()
    brighter = imageio.read_png(site / data["configs"][0]["views"]["0"]["method"]["1"]).mean()
    darker = imageio.read_png(site / data["configs"][0]["views"]["0"]["method"]["-1"]).mean()
    assert brighter > darker + 0.02
    # A rebuild over the first site makes no PNG again and keeps screenshots/.
    out = tmp_path / "again"
    first = build(results_path=store, out=out, echo=False)
    (out / "screenshots").mkdir()
    (out / "screenshots" / "index.png").write_bytes(b"png")
    again = build(results_path=store, out=out, echo=False)
    assert first.images_made == 0 or again.images_made == 0
    assert again.images_made == 0 and again.images_reused > 0
    assert (out / "screenshots" / "index.png").read_bytes() == b"png"
    assert (out / MARKER).is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["again"]  # no temporary folder left


def _script(page: Path, element_id: str) -> str:
    text = page.read_text()
    start = text.index(f'id="{element_id}">') + len(f'id="{element_id}">')
    return text[start:text.index("</script>", start)]


@pytest.mark.parametrize("kind", ["missing", "empty-file", "no-rows"])
def test_missing_or_empty_store_is_one_line_and_writes_nothing(tmp_path, capsys, kind):
    store = tmp_path / "store.sqlite"
    if kind == "empty-file":
        store.write_bytes(b"")
    elif kind == "no-rows":
        ResultsStore(store)._connect().close()  # the schema, no rows
    before = sorted(p.name for p in tmp_path.iterdir())
    out = tmp_path / "site"
    assert main(["report", "--results", str(store), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("prtbench: error: ") and "\n" not in err, err
    assert ("no results store at" if kind == "missing" else "has no rows") in err
    assert str(store) in err and "prtbench sweep" in err
    assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_a_failed_build_leaves_the_previous_site(store, site, tmp_path, capsys, monkeypatch):
    out = tmp_path / "site"
    build(results_path=store, out=out, echo=False)
    snapshot = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    from prtbench.site import build as build_mod

    def broken(*args, **kwargs):
        raise KeyboardInterrupt  # the user interrupts half-way through the pages

    monkeypatch.setattr(build_mod, "_overview", broken)
    assert main(["report", "--results", str(store), "--out", str(out), "--quiet"]) == 130
    assert {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()} == snapshot
    assert sorted(p.name for p in tmp_path.iterdir()) == ["site"]


def test_out_that_is_not_a_site_is_refused(store, tmp_path, capsys):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("keep me")
    assert main(["report", "--results", str(store), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert "--out" in err and "not a prtbench site" in err and "\n" not in err
    assert [p.name for p in out.iterdir()] == ["notes.txt"]
    (tmp_path / "file").write_text("x")
    assert main(["report", "--results", str(store), "--out", str(tmp_path / "file")]) == 2
    assert "is a file" in capsys.readouterr().err


def test_render_cache_entries_are_checked(tmp_path, monkeypatch):
    from prtbench.render import renders

    monkeypatch.setenv("PRTBENCH_CACHE", str(tmp_path))
    image = np.linspace(0.0, 4.0, 48 * 64 * 3, dtype=np.float32).reshape(48, 64, 3)
    path = renders.store("run1", 0, image, exposure=1.5, reference_image=image * 0.5)
    entry = renders.load("run1", 0)
    assert entry.exposure == 1.5 and entry.path == path
    np.testing.assert_allclose(entry.image, image, rtol=1e-3, atol=1e-3)  # half floats
    reference, _ = renders.load_reference(entry.reference_path)
    np.testing.assert_allclose(reference, image * 0.5, rtol=1e-3, atol=1e-3)
    # Past the kept views, or not finite: nothing stored.
    assert renders.store("run1", renders.MAX_VIEWS, image, exposure=1.0) is None
    assert renders.store("run1", 1, image * np.nan, exposure=1.0) is None
    assert sorted(p.name for p in path.parent.iterdir()) == ["view00-reference.exr", "view00.exr"]
    # An edited entry (here: its pixels) is not shown, never trusted.
    from prtbench.io.imageio import read_exr_metadata, write_exr

    write_exr(path, image * 2.0, metadata=read_exr_metadata(path), half=True)
    assert renders.load("run1", 0) is None
    assert renders.load("nosuchrun", 0) is None


def test_rows_without_cached_images_are_shown_without_images(store, tmp_path):
    out = tmp_path / "site"
    build(results_path=store, out=out, cache=tmp_path / "empty-cache", echo=False)
    page = (out / "scene-plants-sky-smoke.html").read_text()
    assert "<img" not in page and "No cached images" in page
    assert "(no cached images)" in page and 'id="compare-data"' not in page
    assert not list((tmp_path / "empty-cache").rglob("*.png"))  # nothing made from nothing


def test_stability_page_colours_each_outcome_and_prints_the_stored_numbers(store, tmp_path):
    import re
    import shutil

    copy = tmp_path / "store.sqlite"
    shutil.copyfile(store, copy)
    add_stability(copy)
    out = tmp_path / "site"
    build(results_path=copy, out=out, echo=False)
    page = out / "stability-smoke.html"
    text = page.read_text()
    assert 'href="stability-smoke.html"' in (out / "index.html").read_text()
    outcomes = re.findall(r'<tr data-case="([^"]+)">\s*<td>[^<]*</td>\s*'
                          r'<td class="outcome outcome-(\w+)" data-outcome="(\w+)">', text)
    # In the catalogue's order (moderate first), each cell classed by its stored outcome.
    assert outcomes[0][0] == "moderate" and len(outcomes) == len(STABILITY_ROWS)
    assert sorted(outcomes) == sorted((r["case"], r["outcome"], r["outcome"])
                                      for r in STABILITY_ROWS)
    stored = {r["case"]: r for r in STABILITY_ROWS}
    from prtbench.site.stability import COLUMNS

    numbers = [n for n in _parse(page).numbers if "data-case" in n["row"]]
    assert len(numbers) == len(STABILITY_ROWS) * len(COLUMNS)  # every column of every row
    for number in numbers:
        row = stored[number["row"]["data-case"]]
        key = number["field"]
        expected = (row["peak_rss_bytes"] / 2**20 if key == "peak_rss_mib" and
                    "peak_rss_bytes" in row else row.get(key))
        _check(number, expected)
    assert "light=black ‡" in text and "use 3-5 bands" in text
    css = (out / "static" / "site.css").read_text()
    colours = {o: re.search(rf"\.outcome-{o} {{ background: (#[0-9a-f]+)", css).group(1)
               for o in ("ok", "degraded", "refused", "failed")}
    assert len(set(colours.values())) == 4, colours
