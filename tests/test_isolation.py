"""The test suite never writes into the user's cache or results store, even from module fixtures."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from prtbench.api.cache import cache_root
from tests.conftest import run_root


@pytest.fixture(scope="module")
def cache_seen_by_a_module_fixture() -> Path:
    # Trained networks and transfer live in module-scoped fixtures; they must see the run's
    # cache, not ~/.cache/prtbench.
    return cache_root()


def test_module_fixtures_use_the_session_cache(cache_seen_by_a_module_fixture,
                                               tmp_path_factory):
    assert cache_seen_by_a_module_fixture.is_relative_to(run_root(tmp_path_factory))
    assert Path(os.environ["PRTBENCH_RESULTS"]).is_relative_to(tmp_path_factory.getbasetemp())
