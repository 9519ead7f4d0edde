"""Fitting a neural SDF to a mesh (SIREN, Sitzmann et al. 2020): training samples of the exact
distance, the training loop under a Lipschitz bound, and the fit's report.

The network node itself (its NumPy and GLSL evaluation) is :class:`prtbench.transport.neural_sdf.NeuralSdf`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from tqdm import tqdm

from prtbench.api.cache import cached_arrays, content_key
from prtbench.api.errors import InvalidInputError
from prtbench.scene.geometry import sample_surface
from prtbench.scene.model import TriangleMesh
from prtbench.transport.neural_sdf import (
    LIPSCHITZ_MARGIN,
    NEURAL_SDF_VERSION,
    PADDING,
    SIZES,
    MeshDistance,
    NeuralSdf,
)

# --- fitting --------------------------------------------------------------------------------------

@dataclass(frozen=True)
class FitSettings:
    """Training settings of :func:`fit_neural_sdf` (all part of the cache key)."""

    steps: int = 3000
    batch: int = 8192
    learning_rate: float = 1e-3
    near_samples: int = 160_000
    uniform_samples: int = 60_000
    #: Jitter scales of the near-surface samples, in normalised units (box half size 1).
    jitter: tuple[float, float] = (0.01, 0.06)
    #: SIREN frequency of the first layer (inputs in [−1, 1]); later layers use 1 (see the
    #: initialisation), which suits networks this small better than SIREN's 30 everywhere.
    omega_first: float = 20.0
    #: Weight of the eikonal term mean (|∇f| − 1)² on uniform box points (0: off).
    eikonal: float = 0.0


def training_data(mesh: TriangleMesh, *, center: np.ndarray, scale: float,
                  settings: FitSettings, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Normalised points (M, 3) in [−1, 1]³ and their normalised signed distances (M,)."""

    rng = np.random.default_rng([seed, 0x4E53])
    near = sample_surface(mesh, settings.near_samples, seed=seed).points
    x_near = (near - center) / scale
    half = len(x_near) // 2
    x_near[:half] += rng.normal(0.0, settings.jitter[0], (half, 3))
    x_near[half:] += rng.normal(0.0, settings.jitter[1], (len(x_near) - half, 3))
    x_uniform = rng.uniform(-1.0, 1.0, (settings.uniform_samples, 3))
    x = np.clip(np.concatenate([x_near, x_uniform]), -1.0, 1.0)
    distance = MeshDistance(mesh, seed=seed)
    return x, distance(x * scale + center) / scale


def _siren(width: int, layers: int, seed: int, omega_first: float):
    import torch

    torch.manual_seed(seed)
    modules = []
    fan_in = 3
    for i in range(layers):
        lin = torch.nn.Linear(fan_in, width)
        with torch.no_grad():
            if i == 0:  # SIREN: first layer U(−1/n, 1/n)·ω₀ (ω₀ folded into the weights)
                lin.weight.uniform_(-omega_first / fan_in, omega_first / fan_in)
                lin.bias.uniform_(-1.0, 1.0)
            else:  # later layers U(−√(6/n), √(6/n)): unit-variance pre-activations
                bound = math.sqrt(6.0 / fan_in)
                lin.weight.uniform_(-bound, bound)
                lin.bias.uniform_(-0.5, 0.5)
        modules.append(lin)
        fan_in = width
    modules.append(torch.nn.Linear(width, 1))

    class Siren(torch.nn.Module):
        def __init__(self):
            super().__init__()
            self.layers = torch.nn.ModuleList(modules)

        def forward(self, x):
            for lin in self.layers[:-1]:
                x = torch.sin(lin(x))
            return self.layers[-1](x)[:, 0]

    return Siren()


def _lipschitz(model, x: np.ndarray) -> float:
    """Max gradient norm of the model over points ``x`` (normalised units: distance/unit)."""
    import torch

    worst = 0.0
    for s in range(0, len(x), 32768):
        xt = torch.tensor(x[s:s + 32768], dtype=torch.float32, requires_grad=True)
        (g,) = torch.autograd.grad(model(xt).sum(), xt)
        worst = max(worst, float(g.norm(dim=1).max()))
    return worst


def fit_neural_sdf(mesh: TriangleMesh, *, size: str = "small", seed: int = 0,
                   settings: FitSettings | None = None, material: int = 0,
                   use_cache: bool = True, progress: bool = False) -> NeuralSdf:
    """Fit (or load from the cache) a sine-MLP SDF of a closed triangle mesh.

    Parameters
    ----------
    mesh : TriangleMesh
        World-space mesh, closed (holes make the sign ambiguous near them).
    size : {"small", "large"}
        (k, l) = (32, 2) or (64, 2), the two networks of thesis table 4.3.
    seed : int
        Seeds the data, the initialisation and the batches.
    settings : FitSettings, optional
    material : int
        Material id of the node.
    use_cache, progress : bool

    Returns
    -------
    NeuralSdf
    """
    if size not in SIZES:
        raise InvalidInputError(f"neural SDF size '{size}'; accepted: {', '.join(SIZES)}")
    settings = settings or FitSettings()
    width, layers = SIZES[size]
    p = mesh.positions.astype(np.float64)
    lo, hi = p.min(axis=0), p.max(axis=0)
    center = (lo + hi) / 2
    scale = float((hi - lo).max() / 2 * (1.0 + PADDING))
    key = content_key("neural-sdf", NEURAL_SDF_VERSION, mesh.positions, mesh.faces, size,
                      int(seed), settings, PADDING)

    def compute() -> dict[str, np.ndarray]:
        import torch

        x, target = training_data(mesh, center=center, scale=scale, settings=settings, seed=seed)
        previous_threads = torch.get_num_threads()
        # One thread: these matrices are tiny, and on shared cores more threads ran 18× slower.
        torch.set_num_threads(1)
        try:
            model = _siren(width, layers, seed, settings.omega_first)
            optimiser = torch.optim.Adam(model.parameters(), lr=settings.learning_rate)
            schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimiser, settings.steps)
            xt = torch.tensor(x, dtype=torch.float32)
            yt = torch.tensor(target, dtype=torch.float32)
            generator = torch.Generator().manual_seed(seed)
            for _ in tqdm(range(settings.steps), desc=f"neural sdf {size}", disable=not progress):
                idx = torch.randint(0, len(xt), (settings.batch,), generator=generator)
                loss = (model(xt[idx]) - yt[idx]).abs().mean()
                if settings.eikonal > 0:
                    # Unit gradients everywhere keep the Lipschitz bound (and the tracing
                    # slowdown it causes) near 1 far from the surface too.
                    free = (torch.rand((settings.batch // 4, 3), generator=generator) * 2 - 1)
                    free.requires_grad_(True)
                    (grad,) = torch.autograd.grad(model(free).sum(), free, create_graph=True)
                    loss = loss + settings.eikonal * ((grad.norm(dim=1) - 1) ** 2).mean()
                optimiser.zero_grad()
                loss.backward()
                optimiser.step()
                schedule.step()
            lipschitz = max(1.0, _lipschitz(model, x) * LIPSCHITZ_MARGIN)
        finally:
            torch.set_num_threads(previous_threads)
        arrays = {"center": center, "scale": np.array(scale), "lipschitz": np.array(lipschitz)}
        for i, lin in enumerate(model.layers):
            arrays[f"w{i}"] = lin.weight.detach().numpy().astype(np.float32)
            arrays[f"b{i}"] = lin.bias.detach().numpy().astype(np.float32)
        return arrays

    arrays = cached_arrays("neural-sdf", key, compute, use_cache=use_cache)
    n_layers = layers + 1
    return NeuralSdf(layers=tuple((arrays[f"w{i}"], arrays[f"b{i}"]) for i in range(n_layers)),
                     center=tuple(arrays["center"]), scale=float(arrays["scale"]),
                     lipschitz=float(arrays["lipschitz"]), padding=PADDING * float(arrays["scale"])
                     / (1.0 + PADDING), material=material, name=f"neural-{size}")


def fit_report(node: NeuralSdf, mesh: TriangleMesh, *, samples: int = 20_000, seed: int = 1,
               band: tuple[float, float] = (0.005, 0.02)) -> dict[str, float]:
    """Fit error of a neural SDF against its mesh.

    Returns
    -------
    dict
        ``mean_abs_surface``: mean |d_net| at area-uniform surface samples (world units);
        ``mean_abs_surface_rel``: the same over the mesh's bounding-box diagonal;
        ``sign_accuracy``: fraction of points whose true distance is in ``band`` (fractions
        of the diagonal, both sides of the surface) with the right sign of d_net;
        ``lipschitz``: the bound the network output is divided by.
    """

    p = mesh.positions.astype(np.float64)
    diagonal = float(np.linalg.norm(p.max(axis=0) - p.min(axis=0)))
    s = sample_surface(mesh, samples, seed=seed)
    on_surface = node.evaluate(s.points)
    rng = np.random.default_rng(seed)
    magnitude = rng.uniform(band[0], band[1], samples) * diagonal
    side = rng.choice([-1.0, 1.0], samples)
    # Offsetting along the normal overshoots the band near thin parts: use the true distance.
    q = s.points + (side * magnitude)[:, None] * s.normals
    truth = MeshDistance(mesh, seed=seed)(q)
    in_band = (np.abs(truth) >= band[0] * diagonal) & (np.abs(truth) <= band[1] * diagonal)
    net = node.evaluate(q[in_band])
    return {"mean_abs_surface": float(np.abs(on_surface).mean()),
            "mean_abs_surface_rel": float(np.abs(on_surface).mean() / diagonal),
            "sign_accuracy": float(np.mean(np.sign(net) == np.sign(truth[in_band]))),
            "band_points": int(in_band.sum()), "lipschitz": float(node.lipschitz)}
