"""The site's PNGs: display images at several exposures, thumbnails and FLIP error maps.

Every PNG derives from cached EXRs (a view's render and its reference, :mod:`prtbench.render.renders`)
by the display transform of DESIGN.md §7, ``clip(srgb(2^ev · exposure · hdr), 0, 1)``. At
``ev = 0`` it is exactly the image the metrics were computed on; the other stops
(:data:`STOPS`) are what the scene page's exposure control switches between: pre-exposed
from the linear EXR, so highlights clipped at 0 EV come back at −2 EV (a tone-mapping of the
8-bit PNG in a canvas could not, and a canvas cannot read ``file://`` images anyway). The FLIP
map compares the two 0 EV display images, as the stored ``flip`` metric does.

PNGs are generated once: each is cached under ``cache_root()/site-images/<key>.png``, keyed by
the source EXR's bytes hash and what was done to it, and hard-linked (else copied) into the
site from there.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
from PIL import Image

from prtbench.api.cache import cache_root, content_key
from prtbench.bench.metrics import error_map
from prtbench.io.assets import sha256_of
from prtbench.io.imageio import display, read_exr, write_png

#: Exposure stops (EV relative to the scene's exposure) of the full-size display images.
STOPS = (-2, -1, 0, 1, 2)
#: Longest side of a thumbnail, in pixels.
THUMB_SIZE = 160
#: Bump when the PNGs of the same EXR change.
IMAGES_VERSION = 1
_KIND = "site-images"


def stop_name(ev: int) -> str:
    """``ev+0``, ``ev-2``: the stop's part of a file name."""
    return f"ev{int(ev):+d}"


class ImageMaker:
    """Makes (or finds in the cache) the site's PNGs and copies them into a site folder.

    Parameters
    ----------
    site : Path
        The folder the pages are written to; images go under ``site/images``.
    cache : Path, optional
        Cache root (default :func:`prtbench.api.cache.cache_root`).
    """

    def __init__(self, site: Path, *, cache: Path | None = None):
        self.site = Path(site)
        self.cache = Path(cache) if cache is not None else cache_root()
        self._hashes: dict[Path, str] = {}
        self._pixels: dict[Path, np.ndarray] = {}
        #: PNGs made now versus found in the cache (the build prints both).
        self.made = self.reused = 0

    def source_hash(self, path: Path) -> str:
        """SHA-256 of a source EXR's bytes (computed once per build)."""
        if path not in self._hashes:
            self._hashes[path] = sha256_of(path)
        return self._hashes[path]

    def _linear(self, path: Path) -> np.ndarray:
        if path not in self._pixels:
            if len(self._pixels) > 64:  # references repeat across a page; renders do not
                self._pixels.clear()
            self._pixels[path] = read_exr(path)
        return self._pixels[path]

    def _png(self, key_parts: tuple, make, target: str) -> str:
        """Cached PNG of ``make()`` ((H, W, 3) float in [0, 1]) copied to ``site/target``."""

        cached = self.cache / _KIND / f"{content_key('site-png', IMAGES_VERSION, *key_parts)}.png"
        if cached.is_file():
            self.reused += 1
        else:
            write_png(cached, make())
            os.chmod(cached, 0o644)  # shared with the site (a web server must read it)
            self.made += 1
        out = self.site / target
        if not out.exists():
            out.parent.mkdir(parents=True, exist_ok=True)
            try:  # the site is rebuilt whole, never edited: a hard link saves the copy
                os.link(cached, out)
            except OSError:  # another file system
                shutil.copyfile(cached, out)
        return target

    def display(self, exr: Path, *, exposure: float, ev: int, target: str) -> str:
        """Full-size display PNG of ``exr`` at ``ev`` stops; returns ``target`` (site-relative)."""

        return self._png(("display", self.source_hash(exr), repr(float(exposure)), int(ev)),
                         lambda: display(self._linear(exr), exposure=float(exposure) * 2.0 ** ev),
                         target)

    def thumbnail(self, exr: Path, *, exposure: float, target: str) -> str:
        """Thumbnail (0 EV display, longest side :data:`THUMB_SIZE`) of ``exr``."""

        return self._png(("thumb", self.source_hash(exr), repr(float(exposure)), THUMB_SIZE),
                         lambda: _shrink(display(self._linear(exr), exposure=float(exposure))),
                         target)

    def flip(self, render: Path, reference: Path, *, exposure: float, target: str,
             thumb: bool = False) -> str:
        """FLIP error map (magma) of the 0 EV display images of ``render`` against ``reference``."""
        def make() -> np.ndarray:
            image = error_map(display(self._linear(render), exposure=float(exposure)),
                              display(self._linear(reference), exposure=float(exposure)))
            return _shrink(image) if thumb else image

        return self._png(("flip", self.source_hash(render), self.source_hash(reference), repr(float(exposure)),
                          THUMB_SIZE if thumb else 0), make, target)


def _shrink(image: np.ndarray) -> np.ndarray:
    """Area-averaged downscale so the longest side is at most :data:`THUMB_SIZE`."""

    height, width = image.shape[:2]
    scale = min(1.0, THUMB_SIZE / max(height, width))
    if scale >= 1.0:
        return image
    size = (max(1, round(width * scale)), max(1, round(height * scale)))
    pixels = Image.fromarray(np.round(np.clip(image, 0, 1) * 255).astype(np.uint8))
    return np.asarray(pixels.resize(size, Image.Resampling.BOX), np.float32) / 255.0
