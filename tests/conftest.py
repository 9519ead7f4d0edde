"""Shared fixtures: every test run gets its own cache and results store.

Under pytest-xdist (``make test`` runs ``pytest -n 2``) the workers of one run share one
artifact cache, so a transfer or reference one worker computed is a hit for the other; the
cache's per-entry locks (:func:`prtbench.api.cache.entry_lock`) make concurrent workers compute an
entry once and never read it half-written. Each worker keeps its own results store.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

# Assets the user fetched once (`make assets`) stay visible to `assets`-marked tests even
# though each run gets an empty artifact cache.
_USER_ASSETS = os.environ.get("PRTBENCH_ASSETS") or str(
    Path(os.environ.get("PRTBENCH_CACHE", Path.home() / ".cache" / "prtbench")) / "assets")


def run_root(tmp_path_factory) -> Path:
    """The temporary folder of this whole test run: shared by the xdist workers of one run."""
    base = tmp_path_factory.getbasetemp()
    return base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base


@pytest.fixture(scope="session", autouse=True)
def _isolated_cache(tmp_path_factory):
    # One cache per run keeps tests fast (transfer, references) but never touches ~/.cache.
    # Session scope, so that module- and class-scoped fixtures (trained networks) see it too.
    root = run_root(tmp_path_factory) / "prtbench-cache"
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("PRTBENCH_CACHE", str(root))
        patch.setenv("PRTBENCH_ASSETS", _USER_ASSETS)
        # Never append test rows to the user's ./results store.
        patch.setenv("PRTBENCH_RESULTS", str(tmp_path_factory.getbasetemp() / "results.sqlite"))
        yield
