"""Trained weights -> GLSL: every weight and bias hard-coded as mat4 / vec4 constants.

The thesis (§4.1.4.1) splits each layer's weight matrix into 4×4 blocks, writes them into the
fragment shader as ``mat4`` constants and evaluates the network with mat4·vec4 products. This
module emits only *data*: ``const mat4`` / ``const vec4`` arrays and ``#define``\\ s, written to
an include file ``learnt_weights.glsl`` in a cache directory keyed by the weights' hash. The
forward pass that reads them is ``methods/learnt/shaders/learnt_mlp.glsl``; the sub-scene selection
reads the partition tables of ``learnt_partition.glsl`` (also emitted here).

Block layout. Layer j maps in → out (both padded to multiples of 4). Block (r, c) is
W[4r:4r+4, 4c:4c+4], written column-major (GLSL's mat4 constructor order), so that
``block * x[c]`` is W_block @ x_c. The blocks of network g, layer j, row r, column c are at
``((g·R + r)·C + c)`` in that layer's array; hidden layers 1..l−1 share one array.

The size limit. Hard-coded constants are compiled into the shader program, so the compile
and the driver's JIT grow with the network; the thesis reports that k = 256 and 512 (l = 4)
fail to render in GLSL on an RTX 3090 (table 4.4). ``python -m methods.learnt.probe`` measures
it here (random weights, the real shaders, cold shader cache, 320x240, idle 2-core machine,
Mesa llvmpipe 22.3.6): k = 64 (18,740 constants) compiled and linked in 3.1 s, JIT-ed on the
first frame in 7.7 s and drew in 41 ms; k = 128 (62,004) took 43 s + 44 s and 191 ms per frame
(compile time grows ~14x for 3.3x the constants); k = 256 (225,368) had not produced a
first frame after 45 min in an earlier probe.
:data:`DEFAULT_WEIGHT_LIMIT` (65,536 constants = 4,096 mat4) therefore admits k ≤ 128 (l = 4,
one network) and rejects k ≥ 256, as on the thesis's GPU; ``glsl_weight_limit`` moves it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from methods.learnt.network import Network, NetworkSpec
from methods.learnt.subdivide import KINDS, Partition
from prtbench.api.cache import atomic_path, cache_root, content_key
from prtbench.api.errors import InvalidInputError

#: Most hard-coded weights/biases accepted in one fragment shader (see the module docstring).
DEFAULT_WEIGHT_LIMIT = 65_536
#: Bump when the emitted layout changes (part of the include's cache key).
EMIT_VERSION = 1


def pad4(n: int) -> int:
    """``n`` rounded up to a multiple of 4."""
    return (n + 3) // 4 * 4


def hardcoded_floats(spec: NetworkSpec, groups: int) -> int:
    """Floats the GLSL path hard-codes: padded weights, biases and the in/out maps."""
    n_in, k, n_out = pad4(spec.n_inputs), pad4(spec.hidden), pad4(spec.n_outputs)
    per_net = (n_in * k + k + (spec.layers - 1) * (k * k + k) + k * n_out + n_out
               + 2 * n_out + 4)
    return groups * per_net


#: Sub-scene networks the GLSL path can select between (``learnt_mlp.glsl`` spells them out).
MAX_GLSL_GROUPS = 16


def check_glsl_limit(spec: NetworkSpec, groups: int, limit: int) -> None:
    """InvalidInputError naming the limit (and ``renderer=torch``) when the network is too big."""
    if groups > MAX_GLSL_GROUPS:
        raise InvalidInputError(
            f"learnt partition has {groups} sub-scene networks; the GLSL path selects among at "
            f"most {MAX_GLSL_GROUPS}; accepted: fewer grid_cells, merge_variance > 0, or "
            "--set renderer=torch")
    count = hardcoded_floats(spec, groups)
    if count > limit:
        raise InvalidInputError(
            f"learnt network k={spec.hidden}, l={spec.layers}, {groups} sub-scene(s) needs "
            f"{count:,} hard-coded weights in the fragment shader; the GLSL path's limit is "
            f"glsl_weight_limit={limit:,} (k >= 256 fails to compile/render in GLSL, thesis "
            f"table 4.4); accepted: a smaller network, or --set renderer=torch")


def _floats(values: np.ndarray) -> str:
    # 9 significant digits round-trip float32 exactly; the exponent form is a GLSL float literal.
    return ",".join(np.char.mod("%.9e", np.asarray(values, np.float32).ravel()).tolist())


def _blocks(weight: np.ndarray, rows4: int, cols4: int) -> list[str]:
    """mat4 constructors of a (out, in) matrix zero-padded to (4·rows4, 4·cols4)."""
    padded = np.zeros((4 * rows4, 4 * cols4), np.float32)
    padded[:weight.shape[0], :weight.shape[1]] = weight
    blocks = padded.reshape(rows4, 4, cols4, 4).transpose(0, 2, 3, 1)  # (r, c, col, row)
    return [f"mat4({_floats(b)})" for b in blocks.reshape(-1, 16)]


def _vec4s(values: np.ndarray, n4: int) -> list[str]:
    padded = np.zeros(4 * n4, np.float32)
    padded[:len(values)] = values
    return [f"vec4({_floats(v)})" for v in padded.reshape(n4, 4)]


def _array(kind: str, name: str, items: list[str]) -> str:
    return f"const {kind} {name}[{len(items)}] = {kind}[](\n  " + ",\n  ".join(items) + ");"


def weights_source(networks: list[Network], spec: NetworkSpec) -> str:
    """Text of ``learnt_weights.glsl`` for ``networks`` (one per sub-scene)."""
    in4, k4, out4 = pad4(spec.n_inputs) // 4, pad4(spec.hidden) // 4, pad4(spec.n_outputs) // 4
    hidden_layers = spec.layers - 1
    w_in, b_in, w_hid, b_hid, w_out, b_out, pos, centre, half = ([] for _ in range(9))
    for net in networks:
        w_in += _blocks(net.weights[0], k4, in4)
        b_in += _vec4s(net.biases[0], k4)
        for j in range(1, spec.layers):
            w_hid += _blocks(net.weights[j], k4, k4)
            b_hid += _vec4s(net.biases[j], k4)
        w_out += _blocks(net.weights[-1], out4, k4)
        b_out += _vec4s(net.biases[-1], out4)
        pos.append(f"vec4({_floats(np.append(net.pos_center, net.pos_scale))})")
        centre += _vec4s(net.out_center, out4)
        half += _vec4s(net.out_half, out4)
    if hidden_layers == 0:  # GLSL has no empty arrays; the forward pass skips these
        w_hid, b_hid = ["mat4(0.0)"], ["vec4(0.0)"]
    lines = [
        "// Generated by methods/learnt/glsl.py: trained weights of the learnt transfer, hard-",
        "// coded as mat4 blocks (thesis §4.1.4.1). Do not edit; regenerated from the artifact.",
        f"#define LEARNT_GROUPS {len(networks)}",
        f"#define LEARNT_IN4 {in4}",
        f"#define LEARNT_K4 {k4}",
        f"#define LEARNT_OUT4 {out4}",
        f"#define LEARNT_HIDDEN_LAYERS {hidden_layers}",
        f"#define LEARNT_FREQS {spec.frequencies}",
        f"#define LEARNT_SLOPE {float(spec.leaky_slope):.9e}",
        _array("mat4", "LEARNT_W_IN", w_in), _array("vec4", "LEARNT_B_IN", b_in),
        _array("mat4", "LEARNT_W_HID", w_hid), _array("vec4", "LEARNT_B_HID", b_hid),
        _array("mat4", "LEARNT_W_OUT", w_out), _array("vec4", "LEARNT_B_OUT", b_out),
        _array("vec4", "LEARNT_POS", pos),
        _array("vec4", "LEARNT_OUT_CENTER", centre), _array("vec4", "LEARNT_OUT_HALF", half),
    ]
    return "\n".join(lines) + "\n"


def partition_source(partition: Partition) -> str:
    """Text of ``learnt_partition_data.glsl``: the tables fragments pick a network with."""
    cells = [str(int(g)) for g in partition.group_of_cell]
    objects = [str(int(g)) for g in partition.group_of_object] or ["0"]
    nx, ny, nz = (int(c) for c in partition.grid_cells)
    lines = [
        "// Generated by methods/learnt/glsl.py: sub-scene tables of the learnt transfer.",
        f"#define LEARNT_PARTITION {KINDS[partition.kind]}",
        f"const vec3 LEARNT_GRID_LO = vec3({_floats(partition.grid_lo)});",
        f"const vec3 LEARNT_GRID_CELL = vec3({_floats(partition.cell_size)});",
        f"const ivec3 LEARNT_GRID_N = ivec3({nx}, {ny}, {nz});",
        _array("int", "LEARNT_GROUP_OF_CELL", cells),
        _array("int", "LEARNT_GROUP_OF_OBJECT", objects),
    ]
    return "\n".join(lines) + "\n"


def include_dir(networks: list[Network] | None, spec: NetworkSpec | None,
                partition: Partition) -> Path:
    """A cache directory holding the generated includes for these weights (written once).

    ``networks=None`` writes only the partition tables (the torch renderer's G-buffer pass).
    """
    parts = [EMIT_VERSION, partition.to_arrays()]
    if networks is not None:
        parts += [spec, [net.to_arrays("") for net in networks]]
    directory = cache_root() / "learnt-glsl" / content_key(*parts)
    files = {"learnt_partition_data.glsl": lambda: partition_source(partition)}
    if networks is not None:
        files["learnt_weights.glsl"] = lambda: weights_source(networks, spec)
    for name, text in files.items():
        path = directory / name
        if not path.exists():
            with atomic_path(path) as tmp:
                tmp.write_text(text())
    return directory
