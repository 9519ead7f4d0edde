"""Cached method renders: the HDR image of every measured view, for the comparison site.

A sweep writes no image files (its cells run with ``write_images=False``), yet the site
(:mod:`prtbench.site`, DESIGN.md §18) shows every stored configuration beside its reference,
and it is built from the results store and the cache alone. So :func:`prtbench.bench.runner.execute`
keeps each view's linear render here, at ``cache_root()/renders/<run_id>/view<NN>.exr``: the
row's ``run_id`` and ``view`` find it again. The header records the scene exposure (the
display transform of DESIGN.md §7 needs it), the reference the metrics were computed against
(the cached path-traced EXR's name, or, for a ``method:<name>`` reference, a second EXR beside
this one) and a checksum over pixels and header (:func:`prtbench.render.reference.reference_checksum`):
an entry that does not match is treated as absent, never shown.

Pixels are stored as half floats: they only feed 8-bit display images, and half the bytes
matter at paper resolution. Only the first :data:`MAX_VIEWS` views of a run are kept (the
paper profile renders 30 per configuration).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from prtbench.api.cache import cache_root
from prtbench.api.errors import InvalidInputError
from prtbench.io.imageio import read_exr, read_exr_metadata, write_exr
from prtbench.render.reference import CHECKSUM_KEY, reference_checksum

#: Bump when the layout or header of an entry changes.
RENDER_VERSION = 1
#: Views kept per run (the first ones): enough to compare, bounded at paper resolution.
MAX_VIEWS = 4
_KIND = "renders"


@dataclass(frozen=True)
class CachedRender:
    """One cached view of one run.

    Attributes
    ----------
    image : ndarray, shape (H, W, 3), float32
        The method's linear render.
    exposure : float
        The scene's display exposure.
    reference_path : Path or None
        The reference EXR (path-traced: in ``cache_root()/references``; method reference:
        beside this entry); None when it is gone.
    path : Path
        This entry.
    """

    image: np.ndarray
    exposure: float
    reference_path: Path | None
    path: Path


#: The largest finite half float.
HALF_MAX = 65504.0

def entry_path(run_id: str, view: int, *, root: Path | None = None) -> Path:
    """Where the render of ``view`` of run ``run_id`` lives (it may not exist)."""
    return (root or cache_root()) / _KIND / run_id / f"view{int(view):02d}.exr"


def store(run_id: str, view: int, image: np.ndarray, *, exposure: float,
          reference_file: Path | None = None, reference_image: np.ndarray | None = None) -> Path | None:
    """Keep ``image`` (H, W, 3) linear as the render of ``view`` of run ``run_id``.

    Parameters
    ----------
    reference_file : Path, optional
        The cached path-traced reference EXR the metrics used (recorded by name).
    reference_image : ndarray, shape (H, W, 3), optional
        A method reference's render, stored beside the entry (it is cached nowhere else).

    Returns
    -------
    Path or None
        The entry, or None for a view past :data:`MAX_VIEWS` or a non-finite image.
    """
    if int(view) >= MAX_VIEWS or not np.isfinite(image).all():
        return None
    path = entry_path(run_id, view)
    reference = ""
    if reference_file is not None:
        reference = f"references/{Path(reference_file).name}"
    elif reference_image is not None and np.isfinite(reference_image).all():
        ref_path = path.with_name(f"{path.stem}-reference.exr")
        _write(ref_path, reference_image, {"prtbench_render": str(RENDER_VERSION)})
        reference = f"{_KIND}/{run_id}/{ref_path.name}"
    _write(path, image, {"prtbench_render": str(RENDER_VERSION), "exposure": repr(float(exposure)),
                         "reference": reference, "run_id": run_id, "view": str(int(view))})
    return path


def _write(path: Path, image: np.ndarray, metadata: dict[str, str]) -> None:
    image = np.asarray(image, np.float32)
    # Half floats where they hold the image; a brighter one (a 10^6 light) stays float32
    # rather than turning into infinities.
    fits = not np.isfinite(image).all() or float(np.abs(image).max(initial=0.0)) <= HALF_MAX
    stored = image.astype(np.float16) if fits else image
    metadata = dict(metadata)
    metadata[CHECKSUM_KEY] = reference_checksum(stored.astype(np.float32), metadata)
    write_exr(path, stored, metadata=metadata, half=fits)


def _read_checked(path: Path) -> tuple[np.ndarray, dict[str, str]] | None:
    if not path.is_file():
        return None
    try:
        meta = read_exr_metadata(path)
        image = read_exr(path)
    except InvalidInputError:
        return None
    if meta.get(CHECKSUM_KEY) != reference_checksum(image, meta):
        return None
    return image, meta


def load(run_id: str, view: int, *, root: Path | None = None) -> CachedRender | None:
    """The cached render of ``view`` of run ``run_id``; None when absent or corrupt."""
    root = root or cache_root()
    path = entry_path(run_id, view, root=root)
    checked = _read_checked(path)
    if checked is None:
        return None
    image, meta = checked
    if meta.get("prtbench_render") != str(RENDER_VERSION):
        return None
    ref = meta.get("reference") or ""
    ref_path = root / ref if ref else None
    return CachedRender(image=image, exposure=float(meta.get("exposure", "1.0")),
                        reference_path=ref_path if ref_path is not None and ref_path.is_file() else None,
                        path=path)


def load_reference(path: Path) -> tuple[np.ndarray, dict[str, str]] | None:
    """A reference EXR named by :func:`load` (pixels and header), None when unusable.

    A path-traced reference is verified with its own checksum exactly as the reference
    cache does (:mod:`prtbench.render.reference`); a method reference with this module's.
    """
    return _read_checked(Path(path))
