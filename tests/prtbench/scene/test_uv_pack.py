"""xatlas runs in a child process: a native crash there is retried, never fatal to the caller."""

from __future__ import annotations

import subprocess

import numpy as np
import pytest

from prtbench.api.errors import InvalidInputError, PrtbenchError
from prtbench.scene import uv_pack
from prtbench.scene.geometry import grid_plane


def _quad():
    mesh = grid_plane(1.0, 2)
    return [(mesh.positions, mesh.faces, mesh.normals)]


def test_child_packs_a_plane_into_the_requested_texture():
    (part,) = uv_pack.pack_atlas(_quad(), resolution=64, padding=2)
    assert part["faces"].shape == (8, 3) and part["faces"].dtype == np.int32
    assert part["uvs"].dtype == np.float32 and 0.0 <= part["uvs"].min() <= part["uvs"].max() <= 1.0
    assert part["vertex_map"].max() == 8  # every one of the 3x3 grid vertices is mapped
    assert 0.1 < float(part["utilization"]) <= 1.0


def _crash_then_run(crashes: int, signal_number: int = 11):
    """A stand-in for subprocess.run whose first ``crashes`` children die of a signal."""
    real, calls = subprocess.run, []

    def run(args, **kwargs):
        calls.append(args)
        if len(calls) <= crashes:
            return subprocess.CompletedProcess(args, -signal_number, "", "")
        return real(args, **kwargs)
    return run, calls


def test_a_child_killed_by_a_signal_is_retried_with_the_same_result(monkeypatch):
    expected = uv_pack.pack_atlas(_quad(), resolution=64, padding=2)
    run, calls = _crash_then_run(uv_pack.ATTEMPTS - 1)
    monkeypatch.setattr(uv_pack.subprocess, "run", run)
    again = uv_pack.pack_atlas(_quad(), resolution=64, padding=2)
    assert len(calls) == uv_pack.ATTEMPTS
    assert all(np.array_equal(again[0][k], expected[0][k]) for k in expected[0])


def test_a_child_that_always_crashes_is_a_clear_error(monkeypatch):
    run, calls = _crash_then_run(uv_pack.ATTEMPTS)
    monkeypatch.setattr(uv_pack.subprocess, "run", run)
    with pytest.raises(PrtbenchError, match=r"crashed .* 3 attempts \(SIGSEGV, SIGSEGV, SIGSEGV\)"):
        uv_pack.pack_atlas(_quad(), resolution=64, padding=2)
    assert len(calls) == uv_pack.ATTEMPTS


def test_a_python_error_in_the_child_is_not_retried():
    # Faces naming a vertex that does not exist: xatlas's binding refuses them with an
    # exception, which the same input would raise again.
    positions, faces, normals = _quad()[0]
    with pytest.raises(PrtbenchError, match="xatlas packing failed") as info:
        uv_pack.pack_atlas([(positions, faces + 1000, normals)], resolution=64, padding=2)
    assert not isinstance(info.value, InvalidInputError)
