"""The comparison site in a real browser: Debian's headless Chromium loads every page from the
file system (issue #16). No console errors, no broken image or link, one Pareto point per
stored configuration, the flip/slider/keyboard/exposure controls change what is displayed,
a click on a point opens its images; screenshots of the index and a scene page are taken.

Two sites: one built here from a smoke sweep (its screenshots stay in its temporary folder),
and the one ``make report`` wrote to ``reports/site`` when it exists (its screenshots are saved
under ``reports/site/screenshots/``: the README's).
"""

from __future__ import annotations

import io
import json
import math
from collections import defaultdict
from pathlib import Path
from urllib.parse import unquote, urlparse

import numpy as np
import pytest

from prtbench.site.build import MARKER, build
from prtbench.site.data import slug
from prtbench.store.results import ResultsStore
from prtbench.tradeoff.front import collect_points
from tests.prtbench.site import chromium
from tests.prtbench.site.site_store import add_protocol_rows, add_stability, make_store

pytestmark = [pytest.mark.browser,
              pytest.mark.skipif(chromium.executable() is None,
                                 reason="chromium is not installed (make setup installs it as root)")]

ROOT = Path(__file__).resolve().parents[3]
BUILT = ROOT / "reports" / "site"
SCREENSHOTS = BUILT / "screenshots"

_ALL_IMAGES_LOADED = """
(async () => {
  const images = [...document.images];
  images.forEach((i) => { i.loading = "eager"; });
  await Promise.all(images.map((i) => i.complete && i.naturalWidth ? 0 :
    new Promise((done) => { i.addEventListener("load", done); i.addEventListener("error", done);
                            setTimeout(done, 15000); })));
  return images.filter((i) => !i.getAttribute("src") || !i.naturalWidth).map((i) => i.getAttribute("src") || i.id);
})()
"""
_PLOTS_DRAWN = """
new Promise((done) => {
  const t0 = Date.now();
  (function poll() {
    const plots = [...document.querySelectorAll(".plot")];
    if (plots.every((p) => p.dataset.drawn === "true") || Date.now() - t0 > 20000) done(plots.length);
    else setTimeout(poll, 50);
  })();
})
"""
_LINKS = "[...document.querySelectorAll('a[href]')].map((a) => a.href)"


def _image(png: bytes) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), np.float32)


def _stage(browser) -> tuple[dict, np.ndarray]:
    """The comparison stage's box and its pixels, once its images have loaded."""
    browser.evaluate("""Promise.all(["cmp-top", "cmp-reference"].map((id) => {
        const i = document.getElementById(id);
        return i.complete && i.naturalWidth ? 0 : new Promise((d) => { i.onload = i.onerror = d; });
      }))""")
    box = browser.evaluate("""(() => { const s = document.getElementById('cmp-stage');
        s.scrollIntoView({block: 'start'}); const r = s.getBoundingClientRect();
        return {x: r.x, y: r.y, width: r.width, height: r.height}; })()""")
    return box, _image(browser.screenshot(clip=box))


def _configurations(store: Path) -> dict[tuple, int]:
    """(scene, light, profile) -> configurations with a finite frame time, one per protocol
    panel: front.py's collect_points on each set of scene parameters (what the site plots,
    counted here from the store without prtbench.site)."""
    groups = defaultdict(list)
    for r in ResultsStore(store, readonly=True).query(status="ok"):
        if r.reference_kind == "path":
            groups[(r.scene, r.light, r.profile, json.dumps(r.scene_params, sort_keys=True))].append(r)
    counts: dict[tuple, int] = defaultdict(int)
    for (scene, light, profile, _), rows in groups.items():
        points, _ = collect_points(rows, error="psnr_masked", cost="frame_ms")
        counts[(scene, light, profile)] += sum(math.isfinite(p.cost) for p in points)
    return dict(counts)


@pytest.fixture(scope="module")
def browser():
    with chromium.Chromium() as b:
        yield b


@pytest.fixture(scope="module")
def smoke_site(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("browser-site")
    store = make_store(folder, table=False)
    add_protocol_rows(store)  # three panels, every light class, rows without cached images
    add_stability(store)
    build(results_path=store, out=folder / "site", echo=False)
    return folder / "site"


def _check_site(site: Path, browser, *, screenshots: Path | None) -> None:
    store = Path(json.loads((site / MARKER).read_text())["results"])
    expected_points = _configurations(store)
    pages = sorted(site.glob("*.html"))
    scene_pages = [p for p in pages if p.name.startswith("scene-")]
    assert scene_pages and (site / "index.html") in pages
    if site.name == "site" and site.parent.name.startswith("browser-site"):  # the smoke site
        assert (site / "stability-smoke.html") in pages  # its colours are checked below
    for page in pages:
        before = len(browser.console_errors)
        browser.open(page)
        if page in scene_pages:
            assert browser.evaluate(_PLOTS_DRAWN) >= 1
        broken = browser.evaluate(_ALL_IMAGES_LOADED)
        assert broken == [], (page.name, broken)
        for href in browser.evaluate(_LINKS):
            url = urlparse(href)
            assert url.scheme == "file", (page.name, href)  # offline: no network link
            target = Path(unquote(url.path))
            assert target.is_file(), (page.name, href)
            if url.fragment and target.suffix == ".html":
                assert f'id="{url.fragment}"' in target.read_text(), (page.name, href)
        if page.name.startswith("stability-"):
            # Each outcome class has its own colour, the same on every cell of that class.
            colours = browser.evaluate("""[...document.querySelectorAll('td.outcome')].map(
                (td) => [td.dataset.outcome, getComputedStyle(td).backgroundColor])""")
            by_outcome = defaultdict(set)
            for outcome, colour in colours:
                by_outcome[outcome].add(colour)
            assert colours and all(len(c) == 1 for c in by_outcome.values()), by_outcome
            shown = [next(iter(c)) for c in by_outcome.values()]
            assert len(set(shown)) == len(shown) and "rgba(0, 0, 0, 0)" not in shown, by_outcome
        if page in scene_pages:
            stem = page.stem.split("-")
            points = browser.evaluate("document.querySelectorAll('.plot .scatterlayer path.point').length")
            # Page names slug each part ('sdf-rabbit' -> 'sdf_rabbit'): '-' joins the parts.
            key = next(k for k in expected_points if page.name == f"scene-{slug(*k)}.html")
            assert points == expected_points[key], (page.name, points, expected_points[key], stem)
        assert browser.console_errors[before:] == [], (page.name, browser.console_errors[before:])
    page = scene_pages[0]
    browser.open(page)
    browser.evaluate(_PLOTS_DRAWN)
    label = lambda: browser.evaluate("document.getElementById('cmp-label').textContent")  # noqa: E731
    showing = lambda: browser.evaluate("document.getElementById('cmp-stage').dataset.showing")  # noqa: E731
    box, half = _stage(browser)
    assert showing() == "method | reference"
    # A click on the image flips to the reference; the slider at 100 shows the method alone.
    browser.click(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    box, reference = _stage(browser)
    assert showing() == "reference"
    browser.evaluate("(() => { const w = document.getElementById('cmp-wipe'); w.value = '100';"
                     " w.dispatchEvent(new Event('input')); })()")
    box, method = _stage(browser)
    assert showing() == "method"
    assert np.abs(method - reference).mean() > 0.5, "flip/slider did not change the displayed image"
    assert np.abs(half - reference).mean() > 0.1
    # Keyboard: the next configuration; exposure +2 EV brightens what is shown.
    first = label()
    browser.key("ArrowRight", "ArrowRight", 39)
    assert label() != first and label().split()[0] != first.split()[0]
    browser.key("ArrowLeft", "ArrowLeft", 37)
    assert label() == first
    browser.evaluate("document.querySelector('button.ev[data-ev=\"2\"]').click()")
    box, bright = _stage(browser)
    assert "+2 EV" in label() and bright.mean() > method.mean() + 2.0
    browser.key("0", "Digit0", 48)
    # A click on a Pareto point opens that configuration's images (the last point of a
    # configuration that has cached images).
    target = browser.evaluate("""(() => {
        const data = JSON.parse(document.getElementById('compare-data').textContent);
        const shown = new Set(data.configs.filter((c) => Object.keys(c.views).length).map((c) => c.id));
        const p = [...document.querySelectorAll('.plot .scatterlayer path.point')].filter(
            (e) => e.__data__ && shown.has(e.__data__.data));
        const last = p[p.length - 1]; last.scrollIntoView({block: 'center'});
        const r = last.getBoundingClientRect();
        return {x: r.x + r.width / 2, y: r.y + r.height / 2,
                id: last.__data__.data}; })()""")
    browser.click(target["x"], target["y"])
    chosen = browser.evaluate("location.hash.slice(1)")
    assert chosen == target["id"] and label().startswith(chosen + " "), (chosen, target, label())
    assert browser.console_errors == [], browser.console_errors
    if screenshots is not None:
        browser.open(site / "index.html")
        browser.screenshot(screenshots / "index.png", full_page=True)
        browser.open(page)
        browser.evaluate(_PLOTS_DRAWN)
        _stage(browser)
        browser.evaluate("window.scrollTo(0, 0)")
        # The comparison and the Pareto plot (the README's picture of a scene page).
        browser.screenshot(screenshots / "scene.png", full_page=True, max_height=1450)


def test_smoke_site_in_chromium(smoke_site, browser):
    # The smoke site's screenshots stay beside it (a temporary folder): the committed ones in
    # reports/site/screenshots are the README's pictures of the `make report` site, and a test
    # run in a checkout without that site must not overwrite them with the smoke site's.
    own = smoke_site / "screenshots"
    _check_site(smoke_site, browser, screenshots=own)
    assert (own / "index.png").stat().st_size > 10_000 and (own / "scene.png").stat().st_size > 10_000


def test_built_site_in_chromium(browser):
    if not (BUILT / MARKER).is_file():
        pytest.skip("no reports/site from `make report` here (run it after `make pareto`)")
    _check_site(BUILT, browser, screenshots=SCREENSHOTS)
