"""Where the GLSL path breaks: compile, link and frame time against network width.

Each width is probed in a child process (a driver may crash or run out of memory compiling a
huge shader; a timeout bounds the wait) with random weights of the real layout, the real
``learnt.frag`` and a cold shader cache (``MESA_SHADER_CACHE_DISABLE``). The child renders the
``plane`` scene at 320x240 and reports compile+link seconds, first-frame seconds (llvmpipe JITs
on first use) and the median of 3 further frames. Run::

    .venv/bin/python -m methods.learnt.probe --hidden 64 128 256 --timeout 1800

The numbers quoted in :mod:`methods.learnt.glsl` come from this probe.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

from methods.learnt.config import LearntConfig
from methods.learnt.glsl import hardcoded_floats
from methods.learnt.model import LearntModel
from methods.learnt.network import Network, NetworkSpec
from methods.learnt.renderer import GLSLRenderer
from methods.learnt.subdivide import build_partition
from prtbench.scene.registry import get_scene
from prtbench.transport.lights import get_light


def _child(hidden: int, layers: int, frequencies: int) -> dict:
    spec = NetworkSpec(4, hidden, layers, frequencies, 0.01)
    rng = np.random.default_rng(0)
    net = Network([rng.normal(0, 1 / np.sqrt(i), (o, i)).astype(np.float32)
                   for i, o in spec.layer_dims()],
                  [np.zeros(o, np.float32) for _, o in spec.layer_dims()],
                  np.zeros(3, np.float32), 1.0, np.zeros(16, np.float32),
                  np.ones(16, np.float32))
    scene = get_scene("plane").with_views(1)
    partition = build_partition(scene, None, kind="none")
    model = LearntModel(spec, [net], partition)
    config = LearntConfig(hidden=hidden, layers=layers, pe_frequencies=frequencies,
                          glsl_weight_limit=1 << 26)
    start = time.perf_counter()
    renderer = GLSLRenderer(scene, model, config, width=320, height=240)
    compiled = time.perf_counter() - start
    view, light = scene.trajectory.views[0], get_light("sky")
    start = time.perf_counter()
    renderer.render(view, light)
    first = time.perf_counter() - start
    frame = renderer.frame_time(view, light, warmup=1, frames=3)
    return {"hidden": hidden, "layers": layers, "constants": hardcoded_floats(spec, 1),
            "compile_link_s": compiled, "first_frame_s": first, "frame_ms": frame.median_ms,
            "renderer": frame.renderer, "status": "ok"}


def probe(hidden: int, *, layers: int = 4, frequencies: int = 6, timeout: float = 1800.0) -> dict:
    """Probe one width in a child process; ``status`` is ok, timeout or the child's failure."""
    env = {**os.environ, "MESA_SHADER_CACHE_DISABLE": "true"}
    command = [sys.executable, "-m", "methods.learnt.probe", "--child", str(hidden),
               "--layers", str(layers), "--frequencies", str(frequencies)]
    start = time.perf_counter()
    try:
        done = subprocess.run(command, capture_output=True, text=True, timeout=timeout, env=env)
    except subprocess.TimeoutExpired:
        return {"hidden": hidden, "status": f"timeout after {timeout:.0f} s"}
    wall = time.perf_counter() - start
    lines = [line for line in done.stdout.splitlines() if line.startswith("{")]
    if done.returncode == 0 and lines:
        return {**json.loads(lines[-1]), "wall_s": wall}
    reason = (f"killed by signal {-done.returncode}" if done.returncode < 0
              else f"exit {done.returncode}")
    tail = " ".join(done.stderr.strip().splitlines()[-1:])[:300]
    return {"hidden": hidden, "status": f"failed ({reason}) after {wall:.0f} s: {tail}"}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hidden", type=int, nargs="+", default=[64, 128, 256])
    parser.add_argument("--layers", type=int, default=4)
    parser.add_argument("--frequencies", type=int, default=6)
    parser.add_argument("--timeout", type=float, default=1800.0)
    parser.add_argument("--child", type=int, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child is not None:
        print(json.dumps(_child(args.child, args.layers, args.frequencies)), flush=True)
        return 0
    for hidden in args.hidden:
        print(json.dumps(probe(hidden, layers=args.layers, frequencies=args.frequencies,
                               timeout=args.timeout)), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
