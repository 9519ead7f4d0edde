"""Precompute threads (PRTBENCH_THREADS): every thread count gives one thread's bits.

Three threads on this two-core machine also checks that more threads than cores is harmless.
Each comparison is exact (``assert_array_equal``), and each parallel run is checked to have
really run on several threads, so a silently serial implementation cannot pass.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np
import pytest

from prtbench.api.errors import InvalidInputError
from prtbench.scene.registry import get_scene
from prtbench.transport import parallel
from prtbench.transport.bounce_transfer import compute_bounce_transfer
from prtbench.transport.raytrace import Tracer
from prtbench.transport.transfer import compute_transfer, compute_transfer_with_stderr

THREAD_COUNTS = ("1", "2", "3")


@pytest.fixture(scope="module")
def scene():
    return get_scene("sphere-over-plane", sphere_segments=48)


class _ThreadLog:
    """Stands in for a tracer's embree scene, recording which threads sent it rays."""

    def __init__(self, tracer: Tracer):
        self.idents: set[int] = set()
        self._lock = threading.Lock()
        self._scene = tracer._scene
        tracer._scene = self

    def run(self, *args, **kwargs):
        with self._lock:
            self.idents.add(threading.get_ident())
        return self._scene.run(*args, **kwargs)


# --- the thread count ---------------------------------------------------------------------------

def test_thread_count_defaults_to_the_usable_cores(monkeypatch):
    monkeypatch.delenv("PRTBENCH_THREADS", raising=False)
    assert parallel.thread_count() == parallel.available_cores() >= 1
    monkeypatch.setenv("PRTBENCH_THREADS", "")
    assert parallel.thread_count() == parallel.available_cores()
    monkeypatch.setenv("PRTBENCH_THREADS", " 3 ")
    assert parallel.thread_count() == 3


@pytest.mark.parametrize("value", ["0", "-2", "two", "1.5", "1e3", "257", "nan"])
def test_invalid_thread_counts_are_one_line_errors(monkeypatch, scene, value):
    monkeypatch.setenv("PRTBENCH_THREADS", value)
    with pytest.raises(InvalidInputError) as caught:
        parallel.thread_count()
    message = str(caught.value)
    assert "\n" not in message
    assert f"PRTBENCH_THREADS={value!r}" in message and "accepted: an integer 1..256" in message
    # Every tracer user reads it, and fails before tracing anything.
    positions, normals, _, _ = scene.merged()
    with pytest.raises(InvalidInputError, match="PRTBENCH_THREADS"):
        compute_transfer(scene, positions[:4], normals[:4], bands=2, rays_per_point=8,
                         use_cache=False, progress=False)
    tracer = Tracer.from_scene(scene)
    with pytest.raises(InvalidInputError, match="PRTBENCH_THREADS"):
        tracer.occluded(np.zeros((2, 3)), np.ones((2, 3)))


# --- the pool -----------------------------------------------------------------------------------

def test_map_chunks_keeps_chunk_order_and_runs_nested_calls_inline():
    def slow_first(i):
        if i == 0:
            threading.Event().wait(0.05)  # finishes last: results must still come in order
        inner = list(parallel.map_chunks(lambda j: (j, threading.get_ident()), range(3),
                                         threads=4))
        return i, threading.get_ident(), inner

    results = list(parallel.map_chunks(slow_first, range(8), threads=3))
    assert [r[0] for r in results] == list(range(8))
    assert len({r[1] for r in results}) >= 2  # really on several threads
    assert threading.get_ident() not in {r[1] for r in results}
    for _, ident, inner in results:  # nested: inline on the worker, no second pool
        assert [j for j, _ in inner] == [0, 1, 2] and {t for _, t in inner} == {ident}


def test_map_chunks_raises_the_first_error_and_stops():
    started = []

    def fail_at_two(i):
        started.append(i)
        if i == 2:
            raise ValueError("chunk 2")
        return i

    out = []
    with pytest.raises(ValueError, match="chunk 2"):
        for value in parallel.map_chunks(fail_at_two, range(1000), threads=2):
            out.append(value)
    assert out == [0, 1]
    assert len(started) < 20  # at most two chunks per thread were ever queued ahead


def test_blas_is_single_threaded_meanwhile_and_restored():
    threads = parallel._openblas_threads()
    if threads is None:
        pytest.skip("numpy is not linked against its bundled OpenBLAS")
    get, put = threads
    before = get()
    inside = list(parallel.map_chunks(lambda _: get(), range(4), threads=2))
    assert inside == [1, 1, 1, 1]
    assert get() == before


def test_freed_chunk_arrays_are_reused_without_page_faults():
    import resource

    if not parallel.keep_freed_memory():
        pytest.skip("not glibc: the allocator keeps its own policy")

    def chunk() -> float:
        arrays = [np.ones(3 << 17) for _ in range(4)]  # four 3 MiB arrays, like a chunk's rays
        return sum(float(a[-1]) for a in arrays)

    chunk()  # the heap grows once
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for _ in range(20):
        chunk()
    faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before
    # glibc's own policy trims the freed 12 MiB off the heap every time: measured 60819 faults
    # (~3000 per chunk) in a fresh process here, 0 with keep_freed_memory().
    assert faults < 20 * 300, faults


# --- bit-identical results ----------------------------------------------------------------------

def test_tracer_queries_are_identical_and_split_across_threads(monkeypatch, scene):
    tracer = Tracer.from_scene(scene)
    rng = np.random.default_rng(3)
    n = 200_000  # above PARALLEL_RAYS: split into chunks across the threads
    origins = rng.uniform(-1.5, 1.5, (n, 3)) + [0.0, 1.0, 0.0]
    dirs = rng.normal(size=(n, 3))
    tfar = rng.uniform(0.1, 3.0, n)
    results = {}
    for count in THREAD_COUNTS:
        monkeypatch.setenv("PRTBENCH_THREADS", count)
        hits = tracer.first_hit(origins, dirs)
        results[count] = (tracer.occluded(origins, dirs), tracer.occluded(origins, dirs, tfar=tfar),
                          hits.t, hits.face, hits.u, hits.v)
    assert 0.2 < results["1"][0].mean() < 0.8  # a real mix of hits and misses
    for count in THREAD_COUNTS[1:]:
        for a, b in zip(results["1"], results[count]):
            np.testing.assert_array_equal(a, b, err_msg=f"PRTBENCH_THREADS={count}")


def _runs(monkeypatch, scene, compute) -> dict:
    """{count: (result, distinct threads that queried the tracer)} for each thread count."""
    out = {}
    for count in THREAD_COUNTS:
        monkeypatch.setenv("PRTBENCH_THREADS", count)
        tracer = Tracer.from_scene(scene)
        log = _ThreadLog(tracer)
        out[count] = (compute(tracer), len(log.idents))
    return out


def _check(runs: dict) -> None:
    reference = runs["1"][0]
    reference = reference if isinstance(reference, tuple) else (reference,)
    for count, (value, used) in runs.items():
        value = value if isinstance(value, tuple) else (value,)
        for a, b in zip(reference, value):
            np.testing.assert_array_equal(a, b, err_msg=f"PRTBENCH_THREADS={count}")
        if count == "1":
            assert used == 1, used
        else:
            assert used >= 2, (count, used)  # the chunks really ran on several threads


def test_transfer_is_identical_on_any_thread_count(monkeypatch, scene):
    positions, normals, _, _ = scene.merged()
    kw = dict(bands=4, rays_per_point=64, chunk_points=40, use_cache=False, progress=False)
    _check(_runs(monkeypatch, scene, lambda tracer: compute_transfer(
        scene, positions, normals, tracer=tracer, **kw)))
    _check(_runs(monkeypatch, scene, lambda tracer: compute_transfer_with_stderr(
        scene, positions, normals, tracer=tracer, **kw)))


def test_transfer_with_the_default_chunks_is_identical(monkeypatch, scene):
    positions, normals, _, _ = scene.merged()
    rng = np.random.default_rng(0)
    pick = rng.choice(len(positions), 1200)
    # 1200 points x 512 rays = 600k rays: three default chunks (2^17, 2^18 and the rest).
    _check(_runs(monkeypatch, scene, lambda tracer: compute_transfer(
        scene, positions[pick], normals[pick], bands=3, rays_per_point=512, use_cache=False,
        progress=False, tracer=tracer)))


def test_bounce_transfer_is_identical_on_any_thread_count(monkeypatch, scene):
    positions, normals, _, _ = scene.merged()
    shadowed = compute_transfer(scene, positions, normals, bands=3, rays_per_point=32,
                                use_cache=False, progress=False)
    points = positions[::3] + 0.0  # not the vertices: gathers at points and at vertices
    kw = dict(vertex_transfer=shadowed, bounces=2, rays_per_point=512, use_cache=False,
              progress=False)  # 512 points per chunk
    runs = _runs(monkeypatch, scene, lambda tracer: compute_bounce_transfer(
        scene, points, normals[::3], tracer=tracer, **kw))
    _check(runs)
    direct = compute_bounce_transfer(scene, points, normals[::3], **{**kw, "bounces": 0})
    gain = runs["1"][0][:, 0] - direct[:, 0]
    assert gain.min() > -1e-6 and gain.sum() > 0.01 * direct[:, 0].sum()  # bounces add light
    _check(_runs(monkeypatch, scene, lambda tracer: compute_bounce_transfer(
        scene, positions, normals, tracer=tracer, **kw)))


def test_probes_are_identical_on_any_thread_count(monkeypatch, scene, tmp_path):
    from methods.irradiance_volume.method import probe_grid, probe_visibility

    _, _, probes = probe_grid(scene, resolution=8, padding=0.05)
    runs = _runs(monkeypatch, scene, lambda tracer: probe_visibility(
        tracer, probes, bands=3, rays_per_probe=2048, seed=1))  # two chunks of 256 probes
    _check(runs)
    visibility, backface = runs["1"][0]
    assert 0.0 < backface.max() and visibility[:, 0].std() > 0  # probes see different things


def test_texture_texels_and_bounces_are_identical_on_any_thread_count(monkeypatch, tmp_path):
    import methods.texture  # noqa: F401 - registers the texture methods
    from prtbench.api.method import METHODS

    scene = get_scene("cornell", variant="diffuse")
    cls = METHODS.get("texture-tpfl")
    config = cls.make_config({"texture_resolution": 64, "rays_per_point": 64, "sh_bands": 2,
                              "bounces": 1}, profile="quick")
    arrays = {}
    for count in THREAD_COUNTS:
        monkeypatch.setenv("PRTBENCH_THREADS", count)
        monkeypatch.setenv("PRTBENCH_CACHE", str(tmp_path / f"cache-{count}"))  # no sharing
        arrays[count] = cls.precompute(scene, config, progress=False).arrays
    assert np.abs(arrays["1"]["bounce"]).max() > 0
    for count in THREAD_COUNTS[1:]:
        for name in ("transfer", "bounce"):
            np.testing.assert_array_equal(arrays["1"][name], arrays[count][name],
                                          err_msg=f"{name}, PRTBENCH_THREADS={count}")


@dataclass
class _Texels:
    points: np.ndarray
    normals: np.ndarray
    albedo: np.ndarray

    def __len__(self) -> int:
        return len(self.points)


def test_data_driven_bake_is_identical_on_any_thread_count(monkeypatch):
    from methods.data_driven.dataset import bake_lightmaps
    from methods.data_driven.lights import PointLight

    scene = get_scene("cornell", variant="diffuse")
    positions, normals, _, _ = scene.merged()
    pick = np.random.default_rng(1).choice(len(positions), 300)
    texels = _Texels(positions[pick].astype(np.float64), normals[pick].astype(np.float64),
                     np.full((300, 3), 0.5))
    lights = [PointLight((0.1 * k, 0.7, 0.1), (1.0, 1.0, 1.0)) for k in range(4)]
    out = {}
    for count in THREAD_COUNTS:
        monkeypatch.setenv("PRTBENCH_THREADS", count)
        out[count] = bake_lightmaps(scene, texels, lights, bounces=2, paths=16, env_samples=1,
                                    seed=5)
    assert out["1"].max() > 0 and not np.array_equal(out["1"][0], out["1"][1])
    for count in THREAD_COUNTS[1:]:
        np.testing.assert_array_equal(out["1"], out[count], err_msg=f"PRTBENCH_THREADS={count}")


def test_glossy_transfer_matrices_are_identical_on_any_thread_count(monkeypatch, scene):
    from methods.vertex import glossy as vertex_glossy

    positions, normals, _, _ = scene.merged()
    monkeypatch.setattr(vertex_glossy, "_MATRIX_SCRATCH_BYTES", 8 * 64 * 16 * 100)  # 100 points
    out = {}
    for count in THREAD_COUNTS:
        monkeypatch.setenv("PRTBENCH_THREADS", count)
        out[count] = vertex_glossy.compute_transfer_matrices(
            scene, positions[:450], normals[:450], bands=4, rays_per_point=64, progress=False)
    assert np.abs(out["1"]).max() > 0
    for count in THREAD_COUNTS[1:]:
        np.testing.assert_array_equal(out["1"], out[count], err_msg=f"PRTBENCH_THREADS={count}")


def test_network_weight_gradients_do_not_depend_on_torch_threads():
    # A sweep worker trains on one thread, a serial run on every core. MKL splits the
    # batch-long reduction of a weight gradient (Xᵀ·dY) over its threads unless its strict
    # reproducibility mode is on, which importing prtbench sets (MKL_CBWR): without it the
    # gradients below differ in their last bits between 1 and 2 threads (measured), and
    # neural-wavelet's smoke model by 0.04 dB.
    import os

    import prtbench  # noqa: F401  (sets MKL_CBWR on import)
    torch = pytest.importorskip("torch")

    assert os.environ.get("MKL_CBWR") == "AUTO,STRICT"
    generator = torch.Generator().manual_seed(0)
    x = torch.randn(16384, 78, generator=generator)
    y = torch.randn(16384, 16, generator=generator)
    torch.manual_seed(0)
    net = torch.nn.Sequential(torch.nn.Linear(78, 32), torch.nn.ReLU(), torch.nn.Linear(32, 16))

    def gradients(threads: int) -> list:
        previous = torch.get_num_threads()
        torch.set_num_threads(threads)
        try:
            net.zero_grad()
            (net(x) - y).abs().mean().backward()
            return [p.grad.clone() for p in net.parameters()]
        finally:
            torch.set_num_threads(previous)

    one, two = gradients(1), gradients(2)
    assert all(g.abs().max() > 0 for g in one)
    for a, b in zip(one, two):
        assert torch.equal(a, b)
