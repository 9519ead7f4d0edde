"""Large scenes: partitions, δ overlap, variance merging, and no seams along sub-scene borders."""

from __future__ import annotations

import numpy as np
import pytest

import methods.learnt  # noqa: F401 - registers "learnt"
import scenes.living_room  # noqa: F401 - registers "living-room" until its entry point exists
from methods.learnt.data import TransferSamples, training_samples
from methods.learnt.subdivide import (
    _Stats,
    build_partition,
    merge_by_variance,
    object_prefix_groups,
    training_rows,
)
from prtbench.scene.registry import get_scene


@pytest.fixture(scope="module", autouse=True)
def _one_torch_thread():
    # The 2 cores are shared with other jobs: one torch thread trains these small networks
    # faster than two threads contending for them.
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


def _samples(points, transfer=None, object_ids=None):
    points = np.asarray(points, np.float32)
    n = len(points)
    if transfer is None:
        transfer = np.zeros((n, 4), np.float32)
    return TransferSamples(points, np.tile(np.float32([0, 1, 0]), (n, 1)), transfer,
                           np.zeros(n, np.int32) if object_ids is None else object_ids)


def test_merging_joins_similar_neighbours_only():
    rng = np.random.default_rng(0)
    flat = [rng.normal(0.5, 0.01, (200, 4)) for _ in range(2)]  # two similar, simple regions
    busy = [rng.normal(m, 0.3, (200, 4)) for m in (0.0, 1.0)]  # two varied ones
    stats = [_Stats(t) for t in (*flat, *busy)]
    chain = {(0, 1), (1, 2), (2, 3)}
    assert merge_by_variance(stats, chain, threshold=0.0).tolist() == [0, 1, 2, 3]
    # The flat pair's union has ~the variance of its parts (well under the mean), the busy pairs
    # do not: only the flat pair merges.
    assert merge_by_variance(stats, chain, threshold=0.5).tolist() == [0, 0, 1, 2]
    # Non-neighbours never merge, however similar.
    assert merge_by_variance(stats, {(1, 2), (2, 3)}, threshold=0.5).tolist() == [0, 1, 2, 3]
    # The union statistics are exact (parallel variance formula).
    both = _Stats.merged(stats[2], stats[3])
    assert both.variance == pytest.approx(np.concatenate(busy).var(axis=0).sum(), rel=1e-9)


def test_grid_cells_and_overlap_rows():
    scene = get_scene("plane")
    points = [[-0.45, 0, 0.1], [-0.01, 0, 0.1], [0.01, 0, 0.1], [0.45, 0, 0.1]]
    samples = _samples(points)
    partition = build_partition(scene, samples, kind="grid", grid_cells=(2, 1, 1))
    assert partition.n_groups == 2
    assert partition.group_of_points(samples.points, samples.object_ids).tolist() == [0, 0, 1, 1]
    tight = training_rows(partition, samples, overlap=0.0)
    assert [r.tolist() for r in tight] == [[0, 1], [2, 3]]
    # δ = 0.1 × cell width (0.05 on a unit plane) reaches the points 0.01 past the border.
    wide = training_rows(partition, samples, overlap=0.1)
    assert [r.tolist() for r in wide] == [[0, 1, 2], [1, 2, 3]]


def test_semantic_groups_follow_name_prefixes():
    assert object_prefix_groups(["floor", "sofa.frame", "sofa.cushions", "wall", "sofa"]).tolist() \
        == [0, 1, 1, 2, 1]
    scene = get_scene("living-room")
    samples = training_samples(scene, samples=4000, rays_per_point=8, bands=2, seed=0,
                               vertex_margin=1e-3, progress=False)
    partition = build_partition(scene, samples, kind="objects")
    names = [o.name for o in scene.objects]
    groups = dict(zip(names, partition.group_of_object.tolist()))
    assert partition.n_groups == 5  # floor, wall, sofa, right shelves, front+top shelves
    assert groups["sofa.frame"] == groups["sofa.cushions"] != groups["floor"]
    assert groups["front_top_shelves.boards"] == groups["front_top_shelves.items"]


def test_living_room_is_large_and_semantic():
    scene = get_scene("living-room", variant="glossy")
    lo, hi = scene.bounds()
    assert hi[0] - lo[0] >= 7.0 and hi[2] - lo[2] >= 5.0
    glossy = {o.name for o in scene.objects if o.material.is_glossy}
    assert glossy == {"right_shelves.frame", "front_top_shelves.boards",
                      "front_top_shelves.items"}
    assert len(scene.trajectory) == 30 and scene.substitution


@pytest.mark.slow
def test_no_seams_at_sub_scene_borders():
    # Two grid cells split the living room at x = 0, through the sofa and the floor in front of
    # it. With δ overlap both networks were trained across the border, so (1) the error on the
    # border is no larger than inside the cells (no error band along it) and (2) the jump
    # between the two networks at the same border point — the seam a viewer would see — is
    # within the networks' own interior error.
    from methods.learnt.model import LearntModel
    from methods.learnt.network import predict
    from prtbench.api.method import METHODS, load_or_precompute
    from prtbench.transport.transfer import compute_transfer

    scene = get_scene("living-room")
    cls = METHODS.get("learnt")
    config = cls.make_config({"partition": "grid", "grid_cells": (2, 1, 1), "overlap": 0.15,
                              "samples": 30_000, "rays_per_point": 128, "hidden": 32,
                              "layers": 3, "epochs": 20, "batch_size": 1024,
                              "learning_rate": 5e-3, "heldout_vertices": 200,
                              "heldout_rays": 64}, profile="smoke")
    model = LearntModel.from_arrays(load_or_precompute(cls, scene, config, progress=False).arrays)
    assert model.partition.n_groups == 2
    assert abs(model.partition.grid_lo[0] + model.partition.cell_size[0]) < 1e-3  # border x = 0
    rng = np.random.default_rng(1)
    n = 3000
    z = rng.uniform(-1.3, 1.5, n)
    side = rng.choice([-1.0, 1.0], n)
    border = np.stack([side * rng.uniform(0.0, 0.02, n), np.zeros(n), z], 1).astype(np.float32)
    inside = np.stack([side * rng.uniform(0.3, 1.5, n), np.zeros(n), z], 1).astype(np.float32)
    normals = np.tile(np.float32([0, 1, 0]), (n, 1))
    ids = np.zeros(n, int)
    errors = {}
    for name, points, seed in (("border", border, 3), ("inside", inside, 4)):
        truth = compute_transfer(scene, points, normals, bands=4, rays_per_point=2048, seed=seed,
                                 progress=False)
        errors[name] = np.abs(model.predict(points, normals, ids) - truth).sum(axis=1).mean()
    # The network of the cell across the border, evaluated at the same border points.
    across = model.partition.group_of_points(border * np.float32([-1, 1, 1]), ids)
    assert np.all(across != model.partition.group_of_points(border, ids))
    other = np.zeros((n, 16), np.float32)
    for g, net in enumerate(model.networks):
        rows = across == g
        other[rows] = predict(net, model.spec, border[rows], normals[rows])
    jump = np.abs(model.predict(border, normals, ids) - other).sum(axis=1).mean()
    assert errors["border"] < 1.3 * errors["inside"], errors
    assert jump < 1.5 * errors["inside"], (jump, errors)
