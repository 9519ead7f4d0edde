"""precompute_s is the cost from scratch: cached sub-steps count at their recorded time.

The issue this guards: a new artifact key over an unchanged transfer cache (a knob added to a
config, a corrupt artifact) used to report only the assembly of cached parts (0.011 s for a
0.29 s precompute).
"""

import time

import numpy as np

from prtbench.api import cache
from prtbench.api.method import METHODS, load_or_precompute
from prtbench.scene.registry import get_scene


def _slow(seconds: float):
    def compute():
        time.sleep(seconds)
        return {"x": np.arange(3)}
    return compute


def test_a_cache_hit_credits_its_recorded_compute_time(monkeypatch, tmp_path):
    monkeypatch.setenv("PRTBENCH_CACHE", str(tmp_path))
    with cache.credit_cached_compute() as first:
        cache.cached_arrays("demo", "k", _slow(0.2))
    assert first.credited_s == 0.0 and first.unknown == 0
    with cache.credit_cached_compute() as second:
        start = time.perf_counter()
        cache.cached_arrays("demo", "k", _slow(0.2))
        assert time.perf_counter() - start < 0.1  # a hit: nothing recomputed
    assert 0.2 <= second.credited_s < 1.0 and second.unknown == 0


def test_nested_cached_parts_propagate_to_the_outer_entry(monkeypatch, tmp_path):
    monkeypatch.setenv("PRTBENCH_CACHE", str(tmp_path))
    cache.cached_arrays("inner", "a", _slow(0.3))

    def outer():
        cache.cached_arrays("inner", "a", _slow(0.3))  # a hit worth 0.3 s
        return {"y": np.ones(2)}

    cache.cached_arrays("outer", "b", outer)  # 0.3 s from scratch, ~0 s of its own
    with cache.credit_cached_compute() as credit:
        cache.cached_arrays("outer", "b", outer)
    assert 0.3 <= credit.credited_s < 1.0


def test_an_entry_without_a_time_record_is_unknown_not_zero(monkeypatch, tmp_path):
    monkeypatch.setenv("PRTBENCH_CACHE", str(tmp_path))
    cache.cached_arrays("demo", "old", _slow(0.0))
    (tmp_path / "demo" / "old.time.json").unlink()  # an entry from before the record existed
    with cache.credit_cached_compute() as credit:
        cache.cached_arrays("demo", "old", _slow(0.0))
    assert credit.unknown == 1 and credit.credited_s == 0.0


def test_a_new_artifact_over_a_cached_transfer_reports_the_full_cost(monkeypatch, tmp_path):
    """The artifact removed, its transfer kept (as when a config gains a knob the transfer
    does not depend on): the artifact is assembled from the cached transfer in a fraction of
    the time, and still reports at least the transfer's recorded compute time."""
    monkeypatch.setenv("PRTBENCH_CACHE", str(tmp_path))
    method = METHODS.get("vertex")
    scene = get_scene("sphere-over-plane")
    config = method.make_config({"rays_per_point": 256}, profile="smoke")
    first = load_or_precompute(method, scene, config, progress=False)
    transfer_times = [cache._read_compute_time(p) for p in (tmp_path / "transfer").glob("*.time.json")]
    assert transfer_times and all(t is not None and t > 0 for t in transfer_times)
    for artifact in (tmp_path / "artifacts" / "vertex").iterdir():
        artifact.unlink()  # the artifact (and its build record) gone, the transfer kept
    second = load_or_precompute(method, scene, config, progress=False)
    assert not second.cache_hit
    assert second.precompute_s >= sum(transfer_times)
    assert second.precompute_s >= 0.5 * first.precompute_s
