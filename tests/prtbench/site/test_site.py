"""``prtbench report``: the site is built from the store and the cache only, every number it
prints equals the store's, and bad input is one line with nothing half-written (issue #16)."""

from __future__ import annotations

import csv
import html
import json
import math
import re
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
from prtbench.tradeoff.front import collect_points, mark_fronts, noise_ceiling_db
from tests.prtbench.site.site_store import (
    CELLS,
    PANEL_FIXED_VIEW,
    PANEL_TWO_VIEWS,
    PROTOCOL_CELLS,
    STABILITY_ROWS,
    add_protocol_rows,
    add_stability,
    make_store,
    protocol_config,
)

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
    path = make_store(tmp_path_factory.mktemp("site-store"))
    add_protocol_rows(path)
    return path


@pytest.fixture(scope="module")
def site(store, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("site") / "site"
    build(results_path=store, out=out, echo=False)
    return out


def _view_key(row):
    return json.dumps(row.view_json, sort_keys=True) if row.view_json else int(row.view)


def _expected(rows) -> list[dict]:
    """The page's configurations under the protocol, computed here from front.py's
    collect_points and mark_fronts on each set of scene parameters (independently of
    prtbench.site): one entry per configuration and panel, with the rows behind its point."""
    usable = [r for r in rows if r.status == "ok" and r.reference_kind == "path"]
    by_params = defaultdict(list)
    for r in usable:
        by_params[json.dumps(r.scene_params, sort_keys=True)].append(r)
    out = []
    for params, part in by_params.items():
        psnr, _ = collect_points(part, error="psnr_masked", cost="frame_ms")
        flip, _ = collect_points(part, error="flip_masked", cost="frame_ms")
        flips = {(p.label, p.panel): p for p in flip}
        for p in psnr:
            group = [r for r in part if r.method == p.method and r.run_id in p.run_ids
                     and json.dumps(r.config, sort_keys=True) == p.config_json
                     and _view_key(r) in p.per_view and r.split != "trained"]
            out.append({"params": params, "point": p, "flip": flips.get((p.label, p.panel)),
                        "rows": group})
    mark_fronts([e["point"] for e in out], error="psnr_masked")
    return out


def _page_configs(page: _Cells) -> dict[tuple, str]:
    """(panel, label, scene parameters) -> the configuration id of the page's rows."""
    ids = {}
    for n in page.numbers:
        row = n["outer"]
        if "data-label" in row:
            key = (row["data-panel"], row["data-label"], row["data-params"])
            assert ids.setdefault(key, row["data-config"]) == row["data-config"], key
    return ids


def _check(number: dict, expected) -> None:
    """The printed text and the exact value both equal the expected stored quantity."""
    if expected is None or (isinstance(expected, float) and not math.isfinite(expected)):
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
    expected = _expected(rows)
    # 3 sweep configurations + 4 tessellation ground levels (vertex at its defaults) in the
    # sweep's panel; vertex x2, texture-tp and data-driven in the two-view panel; those three
    # on its second camera and wavelet-image in the fixed-view panel.
    assert len(expected) == len(CELLS) + 4 + 4 + 4
    page = _parse(site / "scene-plants-sky-smoke.html")
    ids = _page_configs(page)
    by_config = defaultdict(dict)
    view_numbers = []
    for n in page.numbers:
        if n["field"].startswith("view_"):
            view_numbers.append(n)
        else:
            by_config[n["outer"]["data-config"]][n["field"]] = n
    assert len(by_config) == len(ids) == len(expected)
    checked = 0
    for e in expected:
        p, group = e["point"], e["rows"]
        numbers = by_config[ids[(p.panel, p.label, e["params"])]]
        _check(numbers["psnr_masked"], p.error)
        _check(numbers["psnr_masked_lo"], p.error_lo)
        _check(numbers["psnr_masked_hi"], p.error_hi)
        _check(numbers["flip_masked"], e["flip"].error)
        _check(numbers["frame_ms"], p.cost)
        _check(numbers["memory_mib"], group[-1].memory_bytes / 2**20)
        _check(numbers["precompute_s"], group[-1].precompute_s)
        _check(numbers["views"], p.views)
        assert p.views == len({r.view for r in group})
        # The detail: frame components, the per-light work and the memory breakdown.
        _check(numbers["light_change_ms"], p.light_change_ms)
        parts = {f"frame_part:{k}": v for k, v in p.frame_components.items()}
        parts.update({f"memory_part:{k}": v / 2**20 for k, v in p.memory_breakdown.items()})
        assert p.frame_components and p.memory_breakdown
        for field, value in parts.items():
            _check(numbers[field], value)
        assert set(numbers) == {"psnr_masked", "psnr_masked_lo", "psnr_masked_hi", "flip_masked",
                                "frame_ms", "memory_mib", "precompute_s", "views",
                                "light_change_ms", *parts}
        checked += 9 + len(parts)
        # Its views are the rows behind its point, and only those.
        shown = {(n["outer"]["data-run"], int(n["outer"]["data-view"])) for n in view_numbers
                 if n["outer"]["data-config"] == ids[(p.panel, p.label, e["params"])]}
        assert shown == {(r.run_id, r.view) for r in group}
    stored = {(r.run_id, r.view, r.method, json.dumps(r.config, sort_keys=True)): r for r in rows}
    labels = {v: k[1] for k, v in ids.items()}
    for n in view_numbers:
        method, config = labels[n["outer"]["data-config"]].split(" ", 1)
        row = stored[(n["outer"]["data-run"], int(n["outer"]["data-view"]), method, config)]
        name = n["field"][len("view_"):]
        expected_value = {"frame_ms": row.frame_ms, "frame_ms_p95": row.frame_ms_p95}.get(
            name, row.metrics.get(name))
        _check(n, expected_value)
        checked += 1
    assert checked == sum(9 + len(e["point"].frame_components) + len(e["point"].memory_breakdown)
                          + 6 * len(e["rows"]) for e in expected)


def test_every_number_on_the_index_is_the_stores(store, site):
    rows = ResultsStore(store, readonly=True).query()
    expected = _expected(rows)
    index = _parse(site / "index.html")
    by_row = defaultdict(dict)
    for n in index.numbers:
        by_row[(n["outer"]["data-panel"], n["outer"]["data-method"])][n["field"]] = n
    groups = defaultdict(list)  # one overview row per panel and method
    for e in expected:
        groups[(e["point"].panel, e["point"].method)].append(e)
    assert set(by_row) == set(groups)
    for key, mine in groups.items():
        best = max(mine, key=lambda e: e["point"].error)
        fields = by_row[key]
        _check(fields["configs"], len(mine))
        _check(fields["psnr_masked"], best["point"].error)
        _check(fields["psnr_masked_lo"], best["point"].error_lo)
        _check(fields["psnr_masked_hi"], best["point"].error_hi)
        _check(fields["flip_masked"], best["flip"].error)
        _check(fields["frame_ms"], best["point"].cost)
        _check(fields["memory_mib"], best["rows"][-1].memory_bytes / 2**20)
        _check(fields["best_flip_masked"], min(e["flip"].error for e in mine))
    assert len(index.numbers) == 8 * len(groups)  # nothing printed that was not checked
    footer = (site / "index.html").read_text()
    ceilings = [noise_ceiling_db(r.reference_noise) for r in rows]
    assert f"{min(ceilings):.2f} to {max(ceilings):.2f}" in footer
    assert f'data-provenance="reference spp">{rows[0].reference_spp}<' in footer
    assert rows[0].renderer in footer and rows[0].git_sha in footer and select_variant() in footer


def _figures(page: Path) -> dict[str, dict]:
    """The page's Pareto figures by their panel's name."""
    text = page.read_text()
    out = {}
    for target, body in re.findall(r'<script type="application/json" class="pareto-data" '
                                   r'data-target="([^"]+)">(.*?)</script>', text, re.DOTALL):
        panel = re.search(rf'<div class="plot" id="{target}"[^>]* data-panel="([^"]+)"', text)
        out[html.unescape(panel.group(1))] = json.loads(body)
    return out


def _plotted(figure: dict) -> dict[str, dict]:
    """Configuration id -> its marker (x, y, symbol, error bar, hover text) in ``figure``."""
    out = {}
    for trace in figure["data"]:
        for i, config in enumerate(trace.get("customdata") or []):
            symbols = trace["marker"]["symbol"]
            out[config] = {"x": trace["x"][i], "y": trace["y"][i],
                           "symbol": symbols[i] if isinstance(symbols, list) else symbols,
                           "above": trace["error_y"]["array"][i],
                           "below": trace["error_y"]["arrayminus"][i],
                           "hover": trace["hovertext"][i]}
    return out


def test_each_panel_is_a_plot_and_a_configuration_is_in_each_of_its_panels(store, site):
    page = site / "scene-plants-sky-smoke.html"
    figures = _figures(page)
    panels = {r.panel for r in ResultsStore(store, readonly=True).query()}
    assert set(figures) == panels and len(panels) == 3  # the sweep's and the two protocol ones
    ids = _page_configs(_parse(page))
    expected = _expected(ResultsStore(store, readonly=True).query())
    for name, figure in figures.items():
        mine = [e for e in expected if e["point"].panel == name]
        plotted = _plotted(figure)
        assert set(plotted) == {ids[(name, e["point"].label, e["params"])] for e in mine}
        for e in mine:  # each point where collect_points put it, in this panel
            marker = plotted[ids[(name, e["point"].label, e["params"])]]
            assert (marker["x"], marker["y"]) == (e["point"].cost, e["point"].error)
        # Titles name the reference and the view count.
        views = int(re.search(r"views=(\d+):", name).group(1))
        reference = re.search(r"ref=(\S+)", name).group(1)
        assert f"reference {reference}, {views} view{'s' if views > 1 else ''}" in \
            figure["layout"]["title"]["text"]
    # The sweep's vertex sh_bands=2 is in all three panels; on the fixed-view panel its point
    # is its row on that camera alone (24.4 dB), on the two-view panel the mean of both.
    vertex = protocol_config(PROTOCOL_CELLS[0])
    label = f"vertex {json.dumps(vertex, sort_keys=True)}"
    assert {k[0] for k in ids if k[1] == label} == panels
    values = {e["point"].panel: e["point"].error for e in expected if e["point"].label == label}
    assert values[PANEL_FIXED_VIEW] == 24.4 and values[PANEL_TWO_VIEWS] == pytest.approx(24.2)
    text = page.read_text()
    assert text.count('<section class="panel"') == 3
    assert "reference path/b1/32spp, 2 views</h3>" in text


def test_diagnostic_configs_and_trained_rows_are_listed_not_plotted(store, site):
    page = site / "scene-plants-sky-smoke.html"
    text = html.unescape(page.read_text())
    unplotted = re.findall(r"<li>(.*?)</li>", text[text.index('id="unplotted"'):], re.DOTALL)
    diagnostic, trained_only = PROTOCOL_CELLS[4], PROTOCOL_CELLS[5]
    diagnostic_label = f"neural-wavelet {json.dumps(protocol_config(diagnostic), sort_keys=True)}"
    trained_label = f"neural-wavelet {json.dumps(protocol_config(trained_only), sort_keys=True)}"
    # Never on a plot or in a table.
    ids = _page_configs(_parse(page))
    assert not [k for k in ids if k[1] in (diagnostic_label, trained_label)]
    assert "neural-wavelet" not in json.dumps(_figures(page))
    # Listed, with the protocol's reason.
    (line,) = [s for s in unplotted if diagnostic_label in s]
    assert "a diagnostic configuration" in line and "pixels from the reference renderer" in line
    (line,) = [s for s in unplotted if trained_label in s]
    assert "trained on, not ranked" in line and PANEL_TWO_VIEWS in line
    # data-driven: its in-family row is ranked, its trained row is listed on its own.
    trained_rows = [s for s in unplotted if s.startswith("[ground_subdivisions=1] data-driven")]
    assert any("view 1" in s and "split 'trained'" in s and PANEL_TWO_VIEWS in s
               for s in trained_rows), trained_rows
    # On the fixed-view panel (the trained camera) it has no ranked row at all.
    assert any("trained on, not ranked" in s and PANEL_FIXED_VIEW in s for s in trained_rows)
    data_driven = [e for e in _expected(ResultsStore(store, readonly=True).query())
                   if e["point"].method == "data-driven"]
    assert [(e["point"].panel, e["point"].views, e["point"].error) for e in data_driven] == \
        [(PANEL_TWO_VIEWS, 1, 26.0)]


def _row_html(text: str, config: str) -> str:
    """The HTML of configuration ``config``'s row in a scene page."""
    start = text.index(f'<tr class="config" id="{config}"')
    return text[start:text.index("</tr>", start)]


def test_intervals_light_classes_and_ties_are_shown(store, site):
    page = site / "scene-plants-sky-smoke.html"
    text = html.unescape(page.read_text())
    ids = _page_configs(_parse(page))
    expected = _expected(ResultsStore(store, readonly=True).query())
    figures = {name: _plotted(f) for name, f in _figures(page).items()}
    symbols = {"relight": "circle", "family": "diamond", "fixed": "square"}
    classes = set()
    for e in expected:
        p = e["point"]
        config = ids[(p.panel, p.label, e["params"])]
        marker = figures[p.panel][config]
        interval = f"{fmt(p.error)} dB [{fmt(p.error_lo)}, {fmt(p.error_hi)}]"
        # The error with its interval in the tooltip, the row and its detail.
        assert interval in marker["hover"] and f"masked PSNR {interval}" in text
        assert marker["above"] == pytest.approx(p.error_hi - p.error)
        assert marker["below"] == pytest.approx(p.error - p.error_lo)
        assert f"light class {p.light_class}, split {p.split}" in marker["hover"]
        assert marker["symbol"] == symbols[p.light_class] + ("" if not p.dominated else "-open")
        assert f'data-light-class="{p.light_class}"' in _row_html(text, config)
        classes.add(p.light_class)
    assert classes == set(symbols)  # the store has every class
    for name in figures:  # a legend entry per light class of the panel, drawing nothing
        legend = [t for t in _figures(page)[name]["data"] if t.get("legendgroup") == "light class"]
        assert {t["name"] for t in legend} == {e["point"].light_class for e in expected
                                               if e["point"].panel == name}
        assert all(t["x"] == [None] for t in legend)
    # vertex sh_bands=3 costs more than sh_bands=2 for an error within its intervals: a tie,
    # in both protocol panels, naming the configuration it ties with.
    for panel in (PANEL_TWO_VIEWS, PANEL_FIXED_VIEW):
        tied = [e for e in expected if e["point"].panel == panel and e["point"].tied_with]
        assert [e["point"].config["sh_bands"] for e in tied] == [3]
        config = ids[(panel, tied[0]["point"].label, tied[0]["params"])]
        rival = ids[(panel, tied[0]["point"].tied_with[0], tied[0]["params"])]
        assert f'<td class="front" data-front="tie" title="ties with {rival} vertex: sh_bands=2' \
            in _row_html(text, config)
        assert f"tie: within the intervals of {rival} vertex" in figures[panel][config]["hover"]


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


def test_claims_page_is_the_ledger_decided_from_the_store(store, site):
    # Every claim of the ledger, each with the verdict, ours and the command that
    # `prtbench claims` decides from the same store; a claim of a report the site has links to
    # that report's page, one without a run says so.
    from prtbench.bench.claims import all_claims, evaluate

    expected = {a.claim.id: a for a in evaluate(all_claims(), results_path=store)}
    text = (site / "claims.html").read_text()
    rows = re.findall(r'<tr id="([^"]+)" data-claim="[^"]+" data-verdict="([^"]+)">(.*?)</tr>',
                      text, re.S)
    assert len(rows) == len(expected) >= 45
    for claim_id, verdict, body in rows:
        a = expected[claim_id]
        assert html.unescape(verdict) == a.verdict, claim_id
        assert f"<code>{html.escape(a.command)}</code>" in body
    measured = [a for a in expected.values() if a.claim.report == "table tessellation"]
    assert measured and all(not a.no_data for a in measured)
    for a in measured:
        body = next(b for i, _, b in rows if i == a.claim.id)
        assert 'href="table-tessellation-smoke.html"' in body
    assert 'href="claims.html"' in (site / "index.html").read_text()
