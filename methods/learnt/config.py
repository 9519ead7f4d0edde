"""Knobs of the ``learnt`` method (thesis ch. 4: learnt transfer).

The defaults are the thesis's: 16 SH coefficients (4 bands), l = 4 layers of k = 64 neurons
with leaky-ReLU and a tanh output, positional encoding of position and normal, ℓ1 loss, batch
8192, Adam, 200 epochs on 1M Turk samples (``paper`` profile; ``quick`` and ``smoke`` shrink
the data and the epochs, see :data:`PROFILE_OVERRIDES`).
"""

from __future__ import annotations

from dataclasses import dataclass

from prtbench.api.config import check_memory, knob, seed_knob

#: What changes the trained network. Everything else (renderer, product, GLSL limit) only
#: changes how the same weights are evaluated, so it is left out of the training cache key.
TRAINING_KNOBS = (
    "sh_bands", "samples", "rays_per_point", "vertex_margin", "object_balance", "heldout_vertices",
    "heldout_rays", "hidden", "layers", "pe_frequencies", "leaky_slope", "loss",
    "projection_canvas", "batch_size", "epochs", "learning_rate", "target_margin", "seed",
    "partition", "grid_cells", "overlap", "merge_variance", "visibility",
)


@dataclass(frozen=True)
class LearntConfig:
    """Knobs of the ``learnt`` method."""

    # --- training data (thesis §4.1.2–4.1.3) --------------------------------------------------
    sh_bands: int = knob(4, "SH bands n of the learnt transfer (n² outputs; thesis: 16 "
                         "coefficients = 4 bands).", low=1, high=8)
    samples: int = knob(1_000_000, "Training points drawn area-uniformly by Turk's method "
                        "(thesis: 800k-1M).", low=64, high=1 << 26)
    rays_per_point: int = knob(1024, "Visibility rays per training point (cosine-weighted, "
                               "stratified).", low=1, high=1 << 20)
    vertex_margin: float = knob(
        1e-3, "Smallest barycentric coordinate of a training point: keeps samples off vertices "
              "and edges so the held-out vertices are never in the training set.",
        low=1e-6, high=0.3)
    object_balance: float = knob(
        0.0, "0: points area-uniform over the whole scene (thesis). b > 0: each object gets a "
             "share of the points ∝ area^(1−b) (area-uniform within it), so small objects in "
             "large scenes are not starved; 1 gives every object the same count.",
        low=0.0, high=1.0)
    heldout_vertices: int = knob(20_000, "Mesh vertices (a seeded subset when the scene has "
                                 "more) whose transfer measures the held-out error.",
                                 low=1, high=1 << 24)
    heldout_rays: int = knob(1024, "Rays per held-out vertex.", low=1, high=1 << 20)
    visibility: bool = knob(True, "Trace occlusion in the training (and held-out) transfer. "
                                  "False: the network learns the unshadowed transfer (V = 1), "
                                  "the trivial image the regression gate must beat.")
    # --- network (thesis §4.1.1, fig. 4.2) ----------------------------------------------------
    hidden: int = knob(64, "Neurons per layer k (a multiple of 4: the GLSL path packs mat4s).",
                       low=4, high=4096)
    layers: int = knob(4, "Hidden layers l of k neurons, each followed by leaky-ReLU; a linear "
                       "output layer with tanh follows them.", low=1, high=16)
    pe_frequencies: int = knob(6, "Positional-encoding frequencies F: x -> (x, sin 2^f πx, "
                               "cos 2^f πx for f < F) for position and normal; 0 turns it off.",
                               low=0, high=16)
    leaky_slope: float = knob(0.01, "Negative slope of the leaky-ReLU.", low=0.0, high=1.0)
    # --- training (thesis §4.1.2, §4.3.2) -----------------------------------------------------
    loss: str = knob("l1", "Training loss: l1 (thesis), l2, or projection (L2 of the two SH "
                     "functions sampled on a lat-long canvas, thesis §4.3.2).",
                     choices=("l1", "l2", "projection"))
    projection_canvas: int = knob(16, "Rows of the lat-long canvas of the projection loss "
                                  "(columns = 2 × rows).", low=2, high=256)
    batch_size: int = knob(8192, "Mini-batch size (thesis: 8192).", low=1, high=1 << 22)
    epochs: int = knob(200, "Training epochs (thesis: ~200).", low=1, high=100_000)
    learning_rate: float = knob(2e-3, "Adam learning rate at the start; cosine-annealed to 1% "
                                "of it over the run.", low=1e-7, high=1.0)
    target_margin: float = knob(
        0.9, "Each transfer coefficient is mapped affinely so the training targets span "
             "[-margin, margin] of tanh's range: tanh never has to saturate to reach a target.",
        low=0.1, high=0.999)
    seed: int = seed_knob("Seed of sampling, ray patterns, initialisation and batch order.")
    device: str = knob("auto", "Torch device for training and the torch renderer: auto (CUDA "
                       "when available), cpu or cuda.", choices=("auto", "cpu", "cuda"))
    # --- large scenes (thesis §4.1.5) ---------------------------------------------------------
    partition: str = knob(
        "none", "Sub-scenes with one small MLP each: none, grid (bounding-box cells, "
                "grid_cells) or objects (semantic: objects grouped by name prefix before '.').",
        choices=("none", "grid", "objects"))
    grid_cells: tuple[int, ...] = knob((2, 1, 2), "Cells along x, y, z of the grid partition.",
                                         low=1, high=64)
    overlap: float = knob(0.1, "δ: each sub-scene also trains on the points within δ × its "
                          "box size beyond its border (thesis fig. 4.5).", low=0.0, high=1.0)
    merge_variance: float = knob(
        0.0, "Merge neighbouring sub-scenes while the merged transfer variance stays below "
             "this multiple of the mean sub-scene variance (0: no merging).", low=0.0,
        high=100.0)
    # --- rendering (thesis §4.1.4) ------------------------------------------------------------
    renderer: str = knob("glsl", "glsl: weights hard-coded as mat4 blocks in the fragment "
                         "shader (thesis §4.1.4.1); torch: GL G-buffer, then the network in "
                         "torch on covered pixels (thesis §4.1.4.2, CUDA on GPUs).",
                         choices=("glsl", "torch"))
    product: str = knob("tpfl", "Transfer x light: tpfl (fixed-light matrix, the thesis's "
                        "'global light matrix') or tp (sparse triple product per fragment).",
                        choices=("tpfl", "tp"))
    glsl_weight_limit: int = knob(
        65_536, "Most hard-coded weights and biases the GLSL path accepts in one fragment "
                "shader (see methods/learnt/glsl.py for the measurement behind it).",
        low=1, high=1 << 26)


#: Per-profile overrides (merged by Method.make_config).
#: ``quick`` and ``smoke`` draw 5-60x fewer points than the thesis's 1M, which starves small
#: objects in scenes with a large ground (the teaset's teapot gets 0.9% of the area-uniform
#: points): there, each object gets a share ∝ √area (``object_balance`` 0.5). ``paper`` keeps
#: the thesis's area-uniform sampling. (``smoke`` is sized for plumbing tests; the regression
#: case trains more, see ``LearntTransfer.regression_case``.)
PROFILE_OVERRIDES = {
    "smoke": {"samples": 16_384, "rays_per_point": 64, "object_balance": 0.5,
              "heldout_vertices": 1000, "heldout_rays": 128, "hidden": 32, "epochs": 4,
              "learning_rate": 5e-3},
    "quick": {"samples": 200_000, "rays_per_point": 256, "object_balance": 0.5,
              "heldout_vertices": 10_000, "heldout_rays": 512, "epochs": 40,
              "learning_rate": 3e-3},
    "paper": {"samples": 1_000_000, "rays_per_point": 1024, "object_balance": 0.0,
              "epochs": 200},
}


def training_bytes(config: LearntConfig) -> float:
    """Estimated peak bytes of training: the float32 samples (points, normals, n² targets) held
    twice (numpy and torch), and per mini-batch row the activations, gradients and leaky-ReLU
    masks of every hidden layer (16 B per neuron)."""
    per_sample = 2 * (24 + 4 * config.sh_bands ** 2)
    return float(config.samples * per_sample
                 + config.batch_size * config.hidden * config.layers * 16)


def check_training_memory(method: str, config: LearntConfig) -> None:
    """One-line error when :func:`training_bytes` exceeds this machine's memory."""
    check_memory(f"method '{method}' samples={config.samples}, batch_size={config.batch_size}, "
                 f"hidden={config.hidden}, layers={config.layers}", training_bytes(config),
                 accepted="fewer samples or a smaller batch_size x hidden x layers")
