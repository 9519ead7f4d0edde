"""Shared fixtures: every test session gets its own cache and results store."""

from __future__ import annotations

import pytest


@pytest.fixture(autouse=True)
def _isolated_cache(tmp_path_factory, monkeypatch):
    # One cache per session keeps tests fast (transfer, references) but never touches ~/.cache.
    root = tmp_path_factory.getbasetemp() / "prtbench-cache"
    monkeypatch.setenv("PRTBENCH_CACHE", str(root))
    # Never append test rows to the user's ./results store.
    monkeypatch.setenv("PRTBENCH_RESULTS", str(tmp_path_factory.getbasetemp() / "results.sqlite"))
    yield
