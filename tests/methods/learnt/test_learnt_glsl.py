"""Weights -> GLSL mat4 blocks: layout, the size limit and its message (no GL needed)."""

from __future__ import annotations

import re

import numpy as np
import pytest

from methods.learnt import glsl
from methods.learnt.network import Network, NetworkSpec, encode, predict
from methods.learnt.subdivide import Partition
from prtbench.api.errors import InvalidInputError


def _random_network(spec: NetworkSpec, seed: int) -> Network:
    rng = np.random.default_rng(seed)
    weights = [rng.normal(0, 1 / np.sqrt(i), (o, i)).astype(np.float32)
               for i, o in spec.layer_dims()]
    biases = [rng.normal(0, 0.1, o).astype(np.float32) for _, o in spec.layer_dims()]
    return Network(weights, biases, rng.normal(0, 1, 3).astype(np.float32), 0.7,
                   rng.normal(0, 1, spec.n_outputs).astype(np.float32),
                   rng.uniform(0.5, 2, spec.n_outputs).astype(np.float32))


def _arrays(source: str) -> dict[str, np.ndarray]:
    """The const arrays of an emitted include, as flat float arrays."""
    out = {}
    for kind, name, body in re.findall(r"const (mat4|vec4) (\w+)\[\d+\] = \w+\[\]\((.*?)\);",
                                       source, flags=re.S):
        values = re.findall(r"[-+]?\d\.\d+e[-+]\d+", body)
        out[name] = np.array(values, np.float32).reshape(-1, 16 if kind == "mat4" else 4)
    return out


def _glsl_forward(arrays, defines, group, points, normals):
    """The loops of learnt_mlp.glsl in numpy: mat4 blocks are column-major (col, row)."""
    in4, k4, out4 = defines["LEARNT_IN4"], defines["LEARNT_K4"], defines["LEARNT_OUT4"]
    hidden, freqs = defines["LEARNT_HIDDEN_LAYERS"], defines["LEARNT_FREQS"]

    def dense(w_name, b_name, row0, n_rows, n_cols, x, slope):
        out = np.zeros((len(x), n_rows, 4), np.float64)
        for r in range(n_rows):
            acc = np.broadcast_to(arrays[b_name][row0 + r], (len(x), 4)).astype(np.float64)
            for c in range(n_cols):
                block = arrays[w_name][(row0 + r) * n_cols + c].reshape(4, 4)  # [col][row]
                acc = acc + x[:, c, :] @ block
            out[:, r] = np.maximum(acc, slope * acc) if slope is not None else np.tanh(acc)
        return out

    box = arrays["LEARNT_POS"][group]
    import torch

    e = encode(torch, torch.as_tensor((points - box[:3]) * box[3]), torch.as_tensor(normals),
               freqs).numpy()
    e = np.pad(e, ((0, 0), (0, 4 * in4 - e.shape[1]))).reshape(len(points), in4, 4)
    h = dense("LEARNT_W_IN", "LEARNT_B_IN", group * k4, k4, in4, e, defines["LEARNT_SLOPE"])
    for layer in range(hidden):
        h = dense("LEARNT_W_HID", "LEARNT_B_HID", (group * hidden + layer) * k4, k4, k4, h,
                  defines["LEARNT_SLOPE"])
    y = dense("LEARNT_W_OUT", "LEARNT_B_OUT", group * out4, out4, k4, h, None)
    rows = slice(group * out4, (group + 1) * out4)
    t = arrays["LEARNT_OUT_CENTER"][rows] + arrays["LEARNT_OUT_HALF"][rows] * y
    return t.reshape(len(points), -1)


@pytest.mark.parametrize("bands,layers", [(4, 4), (3, 1)])
def test_emitted_blocks_evaluate_to_the_torch_network(bands, layers):
    # Two sub-scene networks, 9 outputs padded to 12 and a single hidden layer exercise the
    # padding and the group offsets; the loops of learnt_mlp.glsl replayed on the parsed
    # constants must give the torch network's transfer.
    spec = NetworkSpec(bands=bands, hidden=12, layers=layers, frequencies=2, leaky_slope=0.01)
    nets = [_random_network(spec, 1), _random_network(spec, 2)]
    source = glsl.weights_source(nets, spec)
    defines = {k: float(v) if "." in v else int(v)
               for k, v in re.findall(r"#define (\w+) (\S+)", source)}
    arrays = _arrays(source)
    rng = np.random.default_rng(0)
    points = rng.normal(0, 1, (50, 3)).astype(np.float32)
    normals = rng.normal(0, 1, (50, 3)).astype(np.float32)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    for g, net in enumerate(nets):
        want = predict(net, spec, points, normals)
        got = _glsl_forward(arrays, defines, g, points, normals)[:, :spec.n_outputs]
        assert np.allclose(got, want, rtol=1e-4, atol=1e-5), np.abs(got - want).max()


def test_literals_round_trip_float32_exactly():
    spec = NetworkSpec(4, 8, 2, 1, 0.01)
    net = _random_network(spec, 3)
    arrays = _arrays(glsl.weights_source([net], spec))
    first = arrays["LEARNT_W_IN"].reshape(2, 5, 4, 4).transpose(0, 3, 1, 2).reshape(8, 20)
    assert np.array_equal(first[:, :spec.n_inputs], net.weights[0])


def test_hardcoded_float_count_and_limit():
    spec64 = NetworkSpec(4, 64, 4, 6, 0.01)
    # 80·64 + 64 + 3·(64² + 64) + 64·16 + 16 + 2·16 + 4 (inputs 78 padded to 80).
    assert glsl.hardcoded_floats(spec64, 1) == 80 * 64 + 64 + 3 * (64 * 64 + 64) + 64 * 16 + 52
    assert glsl.hardcoded_floats(spec64, 3) == 3 * glsl.hardcoded_floats(spec64, 1)
    glsl.check_glsl_limit(NetworkSpec(4, 128, 4, 6, 0.01), 1, glsl.DEFAULT_WEIGHT_LIMIT)
    with pytest.raises(InvalidInputError) as info:
        glsl.check_glsl_limit(NetworkSpec(4, 256, 4, 6, 0.01), 1, glsl.DEFAULT_WEIGHT_LIMIT)
    message = str(info.value)
    assert "glsl_weight_limit=65,536" in message and "renderer=torch" in message
    assert "\n" not in message
    with pytest.raises(InvalidInputError, match="at most 16"):
        glsl.check_glsl_limit(NetworkSpec(4, 8, 1, 0, 0.01), 17, glsl.DEFAULT_WEIGHT_LIMIT)


def test_partition_tables():
    partition = Partition("grid", 2, np.zeros(3, np.float32), np.ones(3, np.float32),
                          np.array([2, 1, 2], np.int32), np.array([0, 1, 1, 0], np.int32),
                          np.zeros(3, np.int32))
    source = glsl.partition_source(partition)
    assert "#define LEARNT_PARTITION 1" in source
    assert "const int LEARNT_GROUP_OF_CELL[4] = int[](\n  0,\n  1,\n  1,\n  0);" in source
    assert "ivec3(2, 1, 2)" in source
