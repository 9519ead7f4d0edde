"""prtbench.api.method.wall_frame_times: the host-clock timer the CPU and torch renderers share."""

from __future__ import annotations

import pytest

from prtbench.api import method as method_mod


def test_warmup_is_untimed_and_every_timed_frame_is_one_sample(monkeypatch):
    calls = []
    clock = iter(float(t) for t in range(100))
    monkeypatch.setattr(method_mod.time, "perf_counter", lambda: next(clock))

    def frame() -> None:
        calls.append(len(calls))
        if len(calls) > 2:  # timed frames take 1, 2, 3 ... clock ticks
            for _ in range(len(calls) - 3):
                next(clock)

    times = method_mod.wall_frame_times(frame, warmup=2, frames=3, renderer="llvmpipe",
                                        source="wall+finish")
    assert len(calls) == 2 + 3  # the warm-up frames are run but never read the clock
    # Tick costs 1, 2, 3 ms·1e-3 -> samples 1000, 2000, 3000 ms.
    assert times.median_ms == pytest.approx(2000.0) and times.mean_ms == pytest.approx(2000.0)
    assert times.p95_ms == pytest.approx(2900.0)
    assert (times.frames, times.renderer, times.source) == (3, "llvmpipe", "wall+finish")
