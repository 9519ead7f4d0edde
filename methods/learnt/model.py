"""A trained learnt-transfer model: networks, their spec and the sub-scene partition.

:func:`train_model` runs the whole precompute (training data, partition, one MLP per
sub-scene, held-out evaluation) and caches it by a hash of the scene *geometry* and the
training knobs only, so the diffuse and glossy variants and both renderers share one trained
model (the renderers must agree on the same weights).
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass

import numpy as np

from methods.learnt.config import TRAINING_KNOBS, LearntConfig
from methods.learnt.data import geometry_key, heldout_samples, training_samples
from methods.learnt.network import (
    Network,
    NetworkSpec,
    TorchNetwork,
    box_normalisation,
    heldout_error,
    predict,
    resolve_device,
    train_network,
)
from methods.learnt.subdivide import Partition, build_partition, training_rows
from prtbench.api.cache import cached_arrays, content_key

#: Bump when training or evaluation changes for the same knobs (invalidates cached models).
MODEL_VERSION = 2  # 2: trained under MKL strict reproducibility (prtbench/__init__.py)


@dataclass
class LearntModel:
    """Everything the renderers need."""

    spec: NetworkSpec
    networks: list[Network]
    partition: Partition

    def to_arrays(self) -> dict[str, np.ndarray]:
        s = self.spec
        out = {"spec": np.array([s.bands, s.hidden, s.layers, s.frequencies], np.int32),
               "leaky_slope": np.array(s.leaky_slope, np.float32)}
        for g, net in enumerate(self.networks):
            out.update(net.to_arrays(f"g{g}_"))
        out.update(self.partition.to_arrays())
        return out

    @classmethod
    def from_arrays(cls, arrays) -> "LearntModel":
        bands, hidden, layers, frequencies = (int(v) for v in arrays["spec"])
        spec = NetworkSpec(bands, hidden, layers, frequencies, float(arrays["leaky_slope"]))
        partition = Partition.from_arrays(arrays)
        networks = [Network.from_arrays(arrays, f"g{g}_", spec) for g in range(partition.n_groups)]
        return cls(spec, networks, partition)

    def predict(self, points: np.ndarray, normals: np.ndarray, object_ids: np.ndarray, *,
                device: str = "cpu") -> np.ndarray:
        """Transfer (N, n²) at world points, each evaluated by the network a fragment would use."""
        group = self.partition.group_of_points(points, object_ids)
        out = np.zeros((len(points), self.spec.n_outputs), np.float32)
        for g, net in enumerate(self.networks):
            rows = np.nonzero(group == g)[0]
            if len(rows):
                out[rows] = predict(net, self.spec, points[rows], normals[rows], device=device)
        return out


def spec_of(config: LearntConfig) -> NetworkSpec:
    return NetworkSpec(config.sh_bands, config.hidden, config.layers, config.pe_frequencies,
                       config.leaky_slope)


def training_key(scene, config: LearntConfig) -> str:
    knobs = {k: getattr(config, k) for k in TRAINING_KNOBS}
    if not config.object_balance:  # added later: area-uniform models keep their cache keys
        del knobs["object_balance"]
    if config.visibility:  # likewise: shadowed models keep their cache keys
        del knobs["visibility"]
    return content_key("learnt-model", MODEL_VERSION, geometry_key(scene), knobs)


def _constant_network(spec: NetworkSpec, value: np.ndarray) -> Network:
    """A network whose output is ``value`` everywhere (a sub-scene without training points)."""
    weights = [np.zeros((o, i), np.float32) for i, o in spec.layer_dims()]
    biases = [np.zeros(o, np.float32) for _, o in spec.layer_dims()]
    return Network(weights, biases, np.zeros(3, np.float32), 1.0, value.astype(np.float32),
                   np.full(spec.n_outputs, 1e-6, np.float32), {"train_points": 0})


def _range_check(model: LearntModel, points, normals, object_ids, truth) -> dict[str, float]:
    """How close tanh comes to saturating on held-out points, and targets it cannot reach."""
    import torch

    group = model.partition.group_of_points(points, object_ids)
    max_raw, unreachable = 0.0, 0
    for g, net in enumerate(model.networks):
        rows = np.nonzero(group == g)[0]
        if not len(rows):
            continue
        tn = TorchNetwork(net, model.spec, "cpu")
        with torch.no_grad():
            raw = tn.raw(torch.as_tensor(points[rows]), torch.as_tensor(normals[rows])).numpy()
        max_raw = max(max_raw, float(np.max(np.abs(raw))))
        mapped = (truth[rows] - net.out_center) / net.out_half
        unreachable += int(np.sum(np.abs(mapped) >= 1.0))
    return {"heldout_max_abs_tanh": max_raw,
            "heldout_unreachable_fraction": unreachable / max(truth.size, 1)}


def train_model(scene, config: LearntConfig, *, progress: bool = True
                ) -> tuple[LearntModel, dict]:
    """Train (or load) the model of ``scene`` for ``config``; returns it and its statistics."""

    def compute() -> dict[str, np.ndarray]:
        start = time.perf_counter()
        samples = training_samples(scene, samples=config.samples,
                                   rays_per_point=config.rays_per_point, bands=config.sh_bands,
                                   seed=config.seed, vertex_margin=config.vertex_margin,
                                   object_balance=config.object_balance, progress=progress,
                                   visibility=config.visibility)
        data_s = time.perf_counter() - start
        spec = spec_of(config)
        partition = build_partition(scene, samples, kind=config.partition,
                                    grid_cells=config.grid_cells,
                                    merge_variance=config.merge_variance)
        device = resolve_device(config.device)
        networks = []
        train_start = time.perf_counter()
        for g, rows in enumerate(training_rows(partition, samples, overlap=config.overlap)):
            if len(rows) == 0:
                networks.append(_constant_network(spec, samples.transfer.mean(axis=0)))
                continue
            pts = samples.points[rows]
            networks.append(train_network(
                pts, samples.normals[rows], samples.transfer[rows], spec=spec, loss=config.loss,
                canvas_rows=config.projection_canvas, batch_size=config.batch_size,
                epochs=config.epochs, learning_rate=config.learning_rate,
                margin=config.target_margin, seed=config.seed + g, device=device,
                box=box_normalisation(pts), progress=progress,
                desc=f"learnt {scene.name} k={config.hidden} net {g + 1}/{partition.n_groups}"))
        train_s = time.perf_counter() - train_start
        model = LearntModel(spec, networks, partition)
        heldout = heldout_samples(scene, max_vertices=config.heldout_vertices,
                                  rays_per_point=config.heldout_rays, bands=config.sh_bands,
                                  seed=config.seed + 1, progress=progress,
                                  visibility=config.visibility)
        surface = training_samples(scene, samples=config.heldout_vertices,
                                   rays_per_point=config.heldout_rays, bands=config.sh_bands,
                                   seed=config.seed + 1000, vertex_margin=config.vertex_margin,
                                   progress=progress, visibility=config.visibility)
        stats = {
            "data_s": data_s, "train_s": train_s, "device": device,
            "train_points": int(len(samples)), "groups": partition.n_groups,
            "group_train_points": [int(n.stats.get("train_points", 0)) for n in networks],
            "train_loss": [n.stats.get("train_loss") for n in networks],
            "target_max_abs_mapped": max(n.stats.get("target_max_abs_mapped", 0.0)
                                         for n in networks),
            "parameters": spec.n_parameters() * partition.n_groups,
            "heldout_vertices": heldout_error(
                model.predict(heldout.points, heldout.normals, heldout.object_ids, device=device),
                heldout.transfer),
            "heldout_surface": heldout_error(
                model.predict(surface.points, surface.normals, surface.object_ids, device=device),
                surface.transfer),
            **_range_check(model, heldout.points, heldout.normals, heldout.object_ids,
                           heldout.transfer),
        }
        return {**model.to_arrays(), "stats": np.array(json.dumps(stats))}

    arrays = cached_arrays("learnt-model", training_key(scene, config), compute)
    stats = json.loads(str(arrays.pop("stats")))
    return LearntModel.from_arrays(arrays), stats
