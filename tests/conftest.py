"""Shared fixtures: every test session gets its own cache and results store."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

# Assets the user fetched once (`make assets`) stay visible to `assets`-marked tests even
# though each session gets an empty artifact cache.
_USER_ASSETS = os.environ.get("PRTBENCH_ASSETS") or str(
    Path(os.environ.get("PRTBENCH_CACHE", Path.home() / ".cache" / "prtbench")) / "assets")


@pytest.fixture(scope="session", autouse=True)
def _isolated_cache(tmp_path_factory):
    # One cache per session keeps tests fast (transfer, references) but never touches ~/.cache.
    # Session scope, so that module- and class-scoped fixtures (trained networks) see it too.
    root = tmp_path_factory.getbasetemp() / "prtbench-cache"
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("PRTBENCH_CACHE", str(root))
        patch.setenv("PRTBENCH_ASSETS", _USER_ASSETS)
        # Never append test rows to the user's ./results store.
        patch.setenv("PRTBENCH_RESULTS", str(tmp_path_factory.getbasetemp() / "results.sqlite"))
        yield
