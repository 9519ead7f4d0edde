"""Shared fixtures: every test session gets its own cache and results store."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

# Assets the user fetched once (`make assets`) stay visible to `assets`-marked tests even
# though each session gets an empty artifact cache.
_USER_ASSETS = os.environ.get("PRTBENCH_ASSETS") or str(
    Path(os.environ.get("PRTBENCH_CACHE", Path.home() / ".cache" / "prtbench")) / "assets")


@pytest.fixture(autouse=True)
def _isolated_cache(tmp_path_factory, monkeypatch):
    # One cache per session keeps tests fast (transfer, references) but never touches ~/.cache.
    root = tmp_path_factory.getbasetemp() / "prtbench-cache"
    monkeypatch.setenv("PRTBENCH_CACHE", str(root))
    monkeypatch.setenv("PRTBENCH_ASSETS", _USER_ASSETS)
    # Never append test rows to the user's ./results store.
    monkeypatch.setenv("PRTBENCH_RESULTS", str(tmp_path_factory.getbasetemp() / "results.sqlite"))
    yield
