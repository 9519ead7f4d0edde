"""The transfer MLP σ: (p, n) -> T (thesis §4.1.1, fig. 4.2), its losses and training loop.

Architecture: inputs (p̂, n) with p̂ = (p − c)·s the position mapped into [−1, 1]³ by the
sub-scene's bounding box, positional encoding γ(x) = (x, sin 2^f πx, cos 2^f πx for f < F),
``layers`` hidden layers of ``hidden`` neurons with leaky-ReLU, a linear output layer with
tanh. The tanh output y is mapped to transfer by a per-coefficient affine map
T = t_c + t_h·y chosen so the training targets span [−margin, margin]: tanh never has to
saturate to reach a target (the check is recorded with the training statistics).

Losses (thesis §4.3.2): ℓ1 (the thesis's choice), ℓ2, and the projection loss (ℓ2 between the
two SH functions sampled on a coarse lat-long canvas), all on the transfer itself.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from tqdm.auto import tqdm

from methods.learnt.data import check_finite
from prtbench.api.errors import InvalidInputError
from prtbench.transport.sh import eval_sh


@dataclass(frozen=True)
class NetworkSpec:
    """Shape and encoding shared by every network of one artifact."""

    bands: int
    hidden: int
    layers: int
    frequencies: int
    leaky_slope: float

    @property
    def n_inputs(self) -> int:
        """Encoded input width: (p̂, n) and a sin/cos pair per frequency."""
        return 6 + 12 * self.frequencies

    @property
    def n_outputs(self) -> int:
        return self.bands * self.bands

    def layer_dims(self) -> list[tuple[int, int]]:
        """(in, out) of each linear layer."""
        dims = [self.n_inputs] + [self.hidden] * self.layers + [self.n_outputs]
        return list(zip(dims[:-1], dims[1:]))

    def n_parameters(self) -> int:
        return sum(i * o + o for i, o in self.layer_dims())


@dataclass
class Network:
    """One trained MLP in plain arrays (what the renderers upload or hard-code).

    Attributes
    ----------
    weights : list of ndarray, shape (out, in), float32
    biases : list of ndarray, shape (out,), float32
    pos_center : ndarray, shape (3,), float32
    pos_scale : float
        p̂ = (p − pos_center)·pos_scale.
    out_center, out_half : ndarray, shape (n²,), float32
        T = out_center + out_half·tanh(z).
    """

    weights: list[np.ndarray]
    biases: list[np.ndarray]
    pos_center: np.ndarray
    pos_scale: float
    out_center: np.ndarray
    out_half: np.ndarray
    stats: dict = field(default_factory=dict)

    def to_arrays(self, prefix: str) -> dict[str, np.ndarray]:
        out = {f"{prefix}w{i}": w for i, w in enumerate(self.weights)}
        out.update({f"{prefix}b{i}": b for i, b in enumerate(self.biases)})
        out[f"{prefix}pos"] = np.append(self.pos_center, self.pos_scale).astype(np.float32)
        out[f"{prefix}out_center"] = self.out_center
        out[f"{prefix}out_half"] = self.out_half
        return out

    @classmethod
    def from_arrays(cls, arrays, prefix: str, spec: NetworkSpec) -> "Network":
        n_linear = spec.layers + 1
        pos = np.asarray(arrays[f"{prefix}pos"], np.float32)
        return cls([np.asarray(arrays[f"{prefix}w{i}"], np.float32) for i in range(n_linear)],
                   [np.asarray(arrays[f"{prefix}b{i}"], np.float32) for i in range(n_linear)],
                   pos[:3], float(pos[3]), np.asarray(arrays[f"{prefix}out_center"], np.float32),
                   np.asarray(arrays[f"{prefix}out_half"], np.float32))


def box_normalisation(points: np.ndarray) -> tuple[np.ndarray, float]:
    """Centre and uniform scale mapping the bounding box of ``points`` (N, 3) into [−1, 1]³."""
    lo, hi = points.min(axis=0).astype(np.float64), points.max(axis=0).astype(np.float64)
    half = max(float(np.max(hi - lo)) / 2, 1e-6)
    return ((lo + hi) / 2).astype(np.float32), float(1.0 / half)


def _torch():
    import torch

    return torch


def resolve_device(name: str) -> str:
    """``auto`` -> ``cuda`` when available else ``cpu``; ``cuda`` without CUDA is an error."""
    torch = _torch()
    if name == "auto":
        return "cuda" if torch.cuda.is_available() else "cpu"
    if name == "cuda" and not torch.cuda.is_available():
        raise InvalidInputError("device=cuda but torch sees no CUDA device; accepted: auto, cpu")
    return name


def encode(torch, points_hat, normals, frequencies: int):
    """γ(p̂, n): (B, 6) -> (B, 6 + 12F), per frequency sin of all six then cos of all six."""
    x = torch.cat([points_hat, normals], dim=1)
    parts = [x]
    for f in range(frequencies):
        wx = x * (math.pi * 2.0**f)
        parts += [torch.sin(wx), torch.cos(wx)]
    return torch.cat(parts, dim=1)


def build_module(spec: NetworkSpec):
    """The torch ``Sequential`` of fig. 4.2 (without encoding and output map)."""
    torch = _torch()
    modules = []
    for index, (n_in, n_out) in enumerate(spec.layer_dims()):
        modules.append(torch.nn.Linear(n_in, n_out))
        last = index == spec.layers
        modules.append(torch.nn.Tanh() if last else torch.nn.LeakyReLU(spec.leaky_slope))
    return torch.nn.Sequential(*modules)


class TorchNetwork:
    """A :class:`Network` on a torch device: ``transfer(points, normals)`` in world space."""

    def __init__(self, network: Network, spec: NetworkSpec, device: str):
        torch = _torch()
        self.torch, self.spec, self.device = torch, spec, device
        self.module = build_module(spec).to(device)
        linears = [m for m in self.module if isinstance(m, torch.nn.Linear)]
        with torch.no_grad():
            for lin, w, b in zip(linears, network.weights, network.biases):
                lin.weight.copy_(torch.from_numpy(np.asarray(w, np.float32)))
                lin.bias.copy_(torch.from_numpy(np.asarray(b, np.float32)))
        self.module.eval()
        self.pos_center = torch.as_tensor(network.pos_center, device=device)
        self.pos_scale = float(network.pos_scale)
        self.out_center = torch.as_tensor(network.out_center, device=device)
        self.out_half = torch.as_tensor(network.out_half, device=device)

    def raw(self, points, normals):
        """tanh outputs y (B, n²) for torch tensors ``points``, ``normals`` (B, 3)."""
        hat = (points - self.pos_center) * self.pos_scale
        return self.module(encode(self.torch, hat, normals, self.spec.frequencies))

    def transfer(self, points, normals):
        """Transfer (B, n²) for torch tensors (B, 3) on this device."""
        return self.out_center + self.out_half * self.raw(points, normals)


def predict(network: Network, spec: NetworkSpec, points: np.ndarray, normals: np.ndarray, *,
            device: str = "cpu", batch: int = 65536) -> np.ndarray:
    """Transfer (N, n²) float32 predicted at world ``points`` with unit ``normals`` (N, 3)."""
    torch = _torch()
    net = TorchNetwork(network, spec, device)
    out = []
    with torch.no_grad():
        for start in range(0, len(points), batch):
            p = torch.as_tensor(np.asarray(points[start:start + batch], np.float32), device=device)
            n = torch.as_tensor(np.asarray(normals[start:start + batch], np.float32), device=device)
            out.append(net.transfer(p, n).cpu().numpy())
    return np.concatenate(out) if out else np.zeros((0, spec.n_outputs), np.float32)


def projection_canvas(rows: int, bands: int) -> np.ndarray:
    """(rows·2rows, n²) SH values at the cell centres of a lat-long canvas (unweighted, as a
    naive canvas projection is: the loss of thesis §4.3.2)."""

    theta = (np.arange(rows) + 0.5) / rows * np.pi
    phi = (np.arange(2 * rows) + 0.5) / (2 * rows) * 2 * np.pi
    t, p = np.meshgrid(theta, phi, indexing="ij")
    dirs = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1).reshape(-1, 3)
    return eval_sh(dirs, bands).astype(np.float32)


def _loss_fn(torch, kind: str, *, canvas_rows: int, bands: int, device: str):
    if kind == "l1":
        return lambda pred, target: (pred - target).abs().mean()
    if kind == "l2":
        return lambda pred, target: ((pred - target) ** 2).mean()
    if kind == "projection":
        basis = torch.as_tensor(projection_canvas(canvas_rows, bands), device=device)
        return lambda pred, target: (((pred - target) @ basis.T) ** 2).mean()
    raise InvalidInputError(f"loss '{kind}'; accepted: l1, l2, projection")


def output_map(targets: np.ndarray, margin: float) -> tuple[np.ndarray, np.ndarray]:
    """Per-coefficient (centre, half) with targets spanning [−margin, margin] after mapping."""
    lo, hi = targets.min(axis=0).astype(np.float64), targets.max(axis=0).astype(np.float64)
    half = np.maximum((hi - lo) / 2 / margin, 1e-6)
    return ((lo + hi) / 2).astype(np.float32), half.astype(np.float32)


def train_network(points: np.ndarray, normals: np.ndarray, targets: np.ndarray, *,
                  spec: NetworkSpec, loss: str = "l1", canvas_rows: int = 16,
                  batch_size: int = 8192, epochs: int = 200, learning_rate: float = 2e-3,
                  margin: float = 0.9, seed: int = 0, device: str = "cpu",
                  box: tuple[np.ndarray, float] | None = None, progress: bool = True,
                  desc: str = "train") -> Network:
    """Fit one MLP to (points, normals) -> targets with Adam and a cosine learning-rate decay.

    Parameters
    ----------
    points, normals : ndarray, shape (N, 3)
    targets : ndarray, shape (N, n²)
        Transfer vectors; NaN/Inf anywhere is rejected before training starts.
    spec : NetworkSpec
    loss : {"l1", "l2", "projection"}
    canvas_rows : int
        Canvas rows of the projection loss.
    batch_size, epochs : int
    learning_rate : float
        Adam's initial rate; cosine-annealed to 1% of it by the last step.
    margin : float
        Targets are mapped into [−margin, margin] of tanh's range.
    seed : int
        Seeds the initialisation and the batch order (training is reproducible on a device).
    device : str
    box : (centre (3,), scale), optional
        Position normalisation; default: the bounding box of ``points``.
    progress : bool
        A tqdm bar over epochs on stderr.

    Returns
    -------
    Network
        With ``stats``: final loss, steps, seconds, the target range check.
    """
    check_finite("learnt training data (points, normals, transfer)", points, normals, targets)
    if len(points) == 0:
        raise InvalidInputError("learnt training data is empty; accepted: at least one point")
    targets = np.asarray(targets, np.float32)
    if targets.shape != (len(points), spec.n_outputs):
        raise InvalidInputError(f"training targets shape {targets.shape}; expected "
                                f"({len(points)}, {spec.n_outputs}) for {spec.bands} SH bands")
    torch = _torch()

    start = time.perf_counter()
    torch.manual_seed(seed)
    centre, scale = box if box is not None else box_normalisation(points)
    out_center, out_half = output_map(targets, margin)
    network = network_like_init(spec, seed)
    network.pos_center, network.pos_scale = np.asarray(centre, np.float32), float(scale)
    network.out_center, network.out_half = out_center, out_half
    net = TorchNetwork(network, spec, device)
    net.module.train()
    p = torch.as_tensor(np.asarray(points, np.float32), device=device)
    n = torch.as_tensor(np.asarray(normals, np.float32), device=device)
    t = torch.as_tensor(targets, device=device)
    loss_fn = _loss_fn(torch, loss, canvas_rows=canvas_rows, bands=spec.bands, device=device)
    optimiser = torch.optim.Adam(net.module.parameters(), lr=learning_rate)
    batches = math.ceil(len(points) / batch_size)
    total_steps = max(epochs * batches, 1)

    def cosine(step: int) -> float:  # 1 -> 0.01 over the run
        return 0.01 + 0.99 * 0.5 * (1 + math.cos(math.pi * min(step, total_steps) / total_steps))

    schedule = torch.optim.lr_scheduler.LambdaLR(optimiser, cosine)
    order = torch.Generator(device="cpu").manual_seed(seed + 1)
    bar = tqdm(range(epochs), desc=desc, disable=not progress, leave=False, unit="epoch")
    epoch_loss = float("nan")
    for _ in bar:
        perm = torch.randperm(len(points), generator=order).to(device)
        running = 0.0
        for b in range(batches):
            rows = perm[b * batch_size:(b + 1) * batch_size]
            value = loss_fn(net.transfer(p[rows], n[rows]), t[rows])
            optimiser.zero_grad(set_to_none=True)
            value.backward()
            optimiser.step()
            schedule.step()
            running += float(value.detach()) * len(rows)
        epoch_loss = running / len(points)
        if not math.isfinite(epoch_loss):
            raise InvalidInputError(f"{desc}: training diverged (loss {epoch_loss}); accepted: a "
                                    "smaller learning_rate")
        bar.set_postfix(loss=f"{epoch_loss:.4g}")
    bar.close()
    linears = [m for m in net.module if isinstance(m, torch.nn.Linear)]
    network.weights = [lin.weight.detach().cpu().numpy().astype(np.float32) for lin in linears]
    network.biases = [lin.bias.detach().cpu().numpy().astype(np.float32) for lin in linears]
    network.stats = {"train_loss": epoch_loss, "loss": loss, "epochs": epochs,
                     "steps": epochs * batches, "train_points": int(len(points)),
                     "train_s": time.perf_counter() - start, "device": device,
                     "target_max_abs_mapped":
                         float(np.max(np.abs((targets - out_center) / out_half)))}
    return network


def network_like_init(spec: NetworkSpec, seed: int) -> Network:
    """A :class:`Network` holding torch's default initialisation for ``spec`` (seeded)."""
    torch = _torch()
    torch.manual_seed(seed)
    module = build_module(spec)
    linears = [m for m in module if isinstance(m, torch.nn.Linear)]
    return Network([l.weight.detach().numpy().copy() for l in linears],
                   [l.bias.detach().numpy().copy() for l in linears],
                   np.zeros(3, np.float32), 1.0, np.zeros(spec.n_outputs, np.float32),
                   np.ones(spec.n_outputs, np.float32))


def heldout_error(predicted: np.ndarray, truth: np.ndarray) -> dict[str, float]:
    """Errors of predicted transfer against ground truth, both (N, n²).

    ``mae``: mean |ΔT_i| over points and coefficients; ``relative_rms``: ‖ΔT‖_F / ‖T‖_F;
    ``dc_relative``: mean |ΔT_0| / mean |T_0| (the diffuse-irradiance term under white light).
    """
    diff = np.asarray(predicted, np.float64) - np.asarray(truth, np.float64)
    truth = np.asarray(truth, np.float64)
    return {"mae": float(np.mean(np.abs(diff))),
            "relative_rms": float(np.linalg.norm(diff) / max(np.linalg.norm(truth), 1e-30)),
            "dc_relative": float(np.mean(np.abs(diff[:, 0]))
                                 / max(np.mean(np.abs(truth[:, 0])), 1e-30)),
            "points": int(len(truth))}
