"""The neural wavelet transport T(x, j, ωo) of Raghavan et al. 2023 (§3–4), in torch.

    F(x, j) = Mᵀ (H(x) ⊙ W(j))                         (CP factorisation, rank R)
    T(x, j, ωo) = f_θ(F(x, j), SH_ℓ(ωr), n, kd, ks, φ(s))   ωr = reflect(ωo, n)
    indirect(x, ωo) = Σ_{j ∈ top-k(L)} L_j ⊙ T(x, j, ωo)      (RGB: T has 3 channels)

* H: the spatial feature field, R features per point: the multiresolution hash grid
  (:class:`~methods.neural_wavelet.hashgrid.HashGrid`, R = levels × features per level), or
  (the paper's Table 6 baseline, ``features="vertex"``) R learnt features per mesh vertex,
  interpolated barycentrically on the triangle a pixel sees and passed through softplus (the
  paper's nonlinearity for that variant).
* W: a learnable 2-D grid over the cubemap wavelet index, 6 × N_w × N_w × R. Wavelet ``j`` is
  the coefficient at (face f, row r, column c) of the Haar layout of the 6×N×N cubemap
  (:mod:`prtbench.transport.wavelet.haar`: ``j = f·N² + r·N + c``); its position on the face is
  ((c + ½)/N, (r + ½)/N), and W is sampled there bilinearly at texel centres, clamped at the
  face's edges (faces do not blend). With N_w = N (the paper's "same resolution as the
  cubemap", the default) the sample is exactly one texel: one R-vector per wavelet.
* M: an R × D matrix without bias.
* f_θ: a ReLU MLP (``hidden`` wide, ``layers`` hidden layers; the paper: 128 and 2) whose
  input is [F (D), SH of ωr up to degree ℓ ((ℓ+1)² values; ℓ = −1 leaves ωr out), n, kd, ks,
  φ(s) = log(1 + s)/log(1 + 10⁴)] and whose output is the RGB transport (linear: Haar
  transport coefficients are signed). φ stands in for the paper's log(25r + 1)/log 26 of GGX
  roughness: it spreads the glossy end of the Phong range [1, 10⁴].

The first layer is applied in two parts: its per-pixel half (SH, n, kd, ks, φ) once per pixel,
its per-wavelet half on F, then summed, so a frame costs P·k evaluations of the rest only.
Targets are scaled by ``target_scale`` (mean training indirect radiance) so the network's
outputs are O(1); the renderer multiplies it back.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass

import numpy as np
import torch

from methods.neural_wavelet.hashgrid import HashGrid
from prtbench.api.errors import InvalidInputError
from prtbench.transport.sh import eval_sh

#: Phong exponent at which φ(s) reaches 1.
PHONG_MAX = 1e4
FEATURE_KINDS = ("hashgrid", "vertex")


@dataclass(frozen=True)
class ModelSpec:
    """Shape of a neural wavelet model (everything needed to rebuild it from its arrays)."""

    features: str
    levels: int
    features_per_level: int
    base_resolution: int
    per_level_scale: float
    log2_table: int
    vertex_features: int
    feature_dim: int
    hidden: int
    layers: int
    reflect_degree: int
    cubemap: int
    wavelet_grid: int
    bounds: tuple[float, ...]
    vertices: int

    @property
    def rank(self) -> int:
        """R: CP terms (hash-grid output, or features per vertex)."""
        if self.features == "hashgrid":
            return self.levels * self.features_per_level
        return self.vertex_features

    @property
    def pixel_inputs(self) -> int:
        """Per-pixel MLP inputs: SH of ωr, n, kd, ks, φ(s)."""
        sh = (self.reflect_degree + 1) ** 2 if self.reflect_degree >= 0 else 0
        return sh + 3 + 3 + 3 + 1

    @property
    def wavelets(self) -> int:
        return 6 * self.cubemap ** 2


@dataclass
class PixelInputs:
    """G-buffer rows of the pixels to shade (torch tensors on one device).

    Attributes
    ----------
    positions, normals, wo : (P, 3) float32
        World position, unit normal, unit direction towards the eye.
    kd, ks : (P, 3) float32
    shininess : (P,) float32
    triangles : (P,) int64
        Merged triangle index (used by the vertex-feature variant only).
    """

    positions: torch.Tensor
    normals: torch.Tensor
    wo: torch.Tensor
    kd: torch.Tensor
    ks: torch.Tensor
    shininess: torch.Tensor
    triangles: torch.Tensor

    def rows(self, index) -> "PixelInputs":
        return PixelInputs(*(getattr(self, f)[index] for f in self.__dataclass_fields__))

    def __len__(self) -> int:
        return len(self.positions)


def sh_encoding(dirs: torch.Tensor, degree: int) -> torch.Tensor:
    """Real SH (prtbench.transport.sh convention) up to ``degree`` of unit ``dirs`` (P, 3): (P, (ℓ+1)²).

    Evaluated with :func:`prtbench.transport.sh.eval_sh` in float64 on the host (the encoding is an
    input, not a parameter: no gradient is needed).
    """

    values = eval_sh(dirs.detach().cpu().double().numpy(), degree + 1)
    return torch.as_tensor(values, dtype=torch.float32, device=dirs.device)


def pixel_encoding(inputs: PixelInputs, degree: int) -> torch.Tensor:
    """The per-pixel MLP inputs (P, pixel_inputs): [SH(ωr), n, kd, ks, φ(s)]."""
    n, wo = inputs.normals, inputs.wo
    parts = []
    if degree >= 0:
        reflect = 2.0 * (n * wo).sum(dim=1, keepdim=True) * n - wo
        reflect = reflect / reflect.norm(dim=1, keepdim=True).clamp_min(1e-12)
        parts.append(sh_encoding(reflect, degree))
    s = inputs.shininess.clamp(0.0, PHONG_MAX)
    phi = torch.log1p(s) / math.log1p(PHONG_MAX)
    parts += [n, inputs.kd, inputs.ks, phi[:, None]]
    return torch.cat(parts, dim=1)


class VertexFeatures(torch.nn.Module):
    """R learnt features per mesh vertex, barycentric on the seen triangle, then softplus."""

    def __init__(self, positions: np.ndarray, faces: np.ndarray, features: int, *,
                 generator: torch.Generator | None = None):
        super().__init__()
        self.register_buffer("positions", torch.as_tensor(np.asarray(positions, np.float32)))
        self.register_buffer("faces", torch.as_tensor(np.asarray(faces, np.int64)))
        init = torch.randn(len(positions), int(features), generator=generator) * 0.1
        self.table = torch.nn.Parameter(init)

    def nbytes(self) -> int:
        """Resident bytes: the features and the mesh they live on (positions, faces)."""
        return int(self.table.numel() * 4 + self.positions.numel() * 4 + self.faces.numel() * 4)

    def forward(self, points: torch.Tensor, triangles: torch.Tensor) -> torch.Tensor:
        tri = self.faces[triangles]  # (P, 3)
        a, b, c = (self.positions[tri[:, i]] for i in range(3))
        # Barycentrics of the point's projection onto the triangle's plane.
        e0, e1, ep = b - a, c - a, points - a
        d00, d01, d11 = (e0 * e0).sum(1), (e0 * e1).sum(1), (e1 * e1).sum(1)
        d20, d21 = (ep * e0).sum(1), (ep * e1).sum(1)
        denom = (d00 * d11 - d01 * d01).clamp_min(1e-20)
        v = ((d11 * d20 - d01 * d21) / denom).clamp(0.0, 1.0)
        w = ((d00 * d21 - d01 * d20) / denom).clamp(0.0, 1.0)
        u = (1.0 - v - w).clamp_min(0.0)
        bary = torch.stack([u, v, w], dim=1)
        bary = bary / bary.sum(dim=1, keepdim=True).clamp_min(1e-12)
        feats = (self.table[tri] * bary[..., None]).sum(dim=1)
        return torch.nn.functional.softplus(feats)


def wavelet_lookup(terms: np.ndarray, *, cubemap: int, grid: int):
    """Bilinear taps of W for wavelet indices: rows (K, 4) into a (6·G², R) table, weights (K, 4).

    Index ``j = f·N² + r·N + c`` sits at face position ((c + ½)/N, (r + ½)/N); W's texel
    centres are at (i + ½)/G; taps are clamped at the face's edges.
    """
    terms = np.asarray(terms, np.int64)
    n, g = int(cubemap), int(grid)
    face, rest = np.divmod(terms, n * n)
    row, col = np.divmod(rest, n)

    def taps(i):
        x = (i + 0.5) / n * g - 0.5
        x0 = np.clip(np.floor(x), 0, g - 1).astype(np.int64)
        x1 = np.minimum(x0 + 1, g - 1)
        t = np.clip(x - x0, 0.0, 1.0)
        return x0, x1, t

    r0, r1, tr = taps(row)
    c0, c1, tc = taps(col)
    base = face * g * g
    rows = np.stack([base + r0 * g + c0, base + r0 * g + c1, base + r1 * g + c0,
                     base + r1 * g + c1], axis=1)
    weights = np.stack([(1 - tr) * (1 - tc), (1 - tr) * tc, tr * (1 - tc), tr * tc], axis=1)
    return rows, weights.astype(np.float32)


class NeuralWaveletModel(torch.nn.Module):
    """T(x, j, ωo) and the k-term indirect radiance (module docstring)."""

    def __init__(self, spec: ModelSpec, *, mesh=None, seed: int = 0):
        super().__init__()
        if spec.features not in FEATURE_KINDS:
            raise InvalidInputError(f"features='{spec.features}'; accepted: "
                                    f"{', '.join(FEATURE_KINDS)}")
        self.spec = spec
        gen = torch.Generator().manual_seed(int(seed))
        if spec.features == "hashgrid":
            lo, hi = spec.bounds[:3], spec.bounds[3:]
            self.field = HashGrid(levels=spec.levels, features=spec.features_per_level,
                                  base_resolution=spec.base_resolution,
                                  per_level_scale=spec.per_level_scale,
                                  log2_table=spec.log2_table, bounds=(lo, hi), generator=gen)
        else:
            if mesh is None:
                positions = np.zeros((spec.vertices, 3), np.float32)
                faces = np.zeros((1, 3), np.int64)
            else:
                positions, faces = mesh
            self.field = VertexFeatures(positions, faces, spec.vertex_features, generator=gen)
        r, g = spec.rank, spec.wavelet_grid
        self.wavelet = torch.nn.Parameter(torch.rand(6 * g * g, r, generator=gen) * 2 - 1)
        self.mix = torch.nn.Parameter(torch.randn(r, spec.feature_dim, generator=gen)
                                      / math.sqrt(r))
        self.first_f = torch.nn.Linear(spec.feature_dim, spec.hidden, bias=False)
        self.first_p = torch.nn.Linear(spec.pixel_inputs, spec.hidden)
        self.hidden_layers = torch.nn.ModuleList(
            torch.nn.Linear(spec.hidden, spec.hidden) for _ in range(spec.layers - 1))
        self.out = torch.nn.Linear(spec.hidden, 3)
        with torch.no_grad():  # seeded init of the linear layers too
            for layer in [self.first_f, self.first_p, *self.hidden_layers, self.out]:
                bound = 1.0 / math.sqrt(layer.in_features)
                layer.weight.copy_(torch.rand(layer.weight.shape, generator=gen) * 2 * bound
                                   - bound)
                if layer.bias is not None:
                    layer.bias.copy_(torch.rand(layer.bias.shape, generator=gen) * 2 * bound
                                     - bound)
        self.register_buffer("target_scale", torch.ones(()))

    # -- evaluation ------------------------------------------------------------------------

    def spatial(self, inputs: PixelInputs) -> torch.Tensor:
        """H(x): (P, R)."""
        if self.spec.features == "hashgrid":
            return self.field(inputs.positions)
        return self.field(inputs.positions, inputs.triangles)

    def wavelet_features(self, terms: np.ndarray) -> torch.Tensor:
        """W(j): (K, R), bilinear in the index's face position."""
        rows, weights = wavelet_lookup(terms, cubemap=self.spec.cubemap,
                                       grid=self.spec.wavelet_grid)
        dev = self.wavelet.device
        w = torch.as_tensor(weights, device=dev)
        return (self.wavelet[torch.as_tensor(rows, device=dev)] * w[..., None]).sum(dim=1)

    def transport(self, inputs: PixelInputs, terms: np.ndarray) -> torch.Tensor:
        """T(x, j, ωo) for every pixel and term: (P, K, 3), in units of ``target_scale``."""
        h = self.spatial(inputs)  # (P, R)
        wj = self.wavelet_features(terms)  # (K, R)
        feature = (h[:, None, :] * wj[None]) @ self.mix  # (P, K, D)
        x = self.first_f(feature) + self.first_p(pixel_encoding(inputs, self.spec.reflect_degree)
                                                 )[:, None, :]
        x = torch.relu(x)
        for layer in self.hidden_layers:
            x = torch.relu(layer(x))
        return self.out(x)

    def radiance(self, inputs: PixelInputs, terms: np.ndarray, coeffs: torch.Tensor
                 ) -> torch.Tensor:
        """Σ_j L_j ⊙ T(x, j, ωo): (P, 3) indirect radiance; ``coeffs`` (K, 3) = L at ``terms``."""
        t = self.transport(inputs, terms)
        return torch.einsum("pkc,kc->pc", t, coeffs) * self.target_scale

    # -- bytes and storage -------------------------------------------------------------------

    def resident_bytes(self) -> dict[str, int]:
        """float32 bytes of the field (hash tables or vertex features + mesh), W, M and f_θ."""
        mlp = sum(p.numel() for m in [self.first_f, self.first_p, *self.hidden_layers, self.out]
                  for p in m.parameters()) * 4
        return {"field": self.field.nbytes(), "wavelet_grid": self.wavelet.numel() * 4,
                "matrix": self.mix.numel() * 4, "mlp": int(mlp)}

    def to_arrays(self) -> dict[str, np.ndarray]:
        out = {f"w_{k}": v.detach().cpu().numpy().copy() for k, v in self.state_dict().items()}
        out["spec"] = np.array(json.dumps(asdict(self.spec)))
        return out

    @classmethod
    def from_arrays(cls, arrays, *, device: str = "cpu") -> "NeuralWaveletModel":
        raw = json.loads(str(arrays["spec"]))
        raw["bounds"] = tuple(raw["bounds"])
        spec = ModelSpec(**raw)
        mesh = None
        if spec.features == "vertex":
            mesh = (arrays["w_field.positions"], arrays["w_field.faces"])
        model = cls(spec, mesh=mesh)
        state = {k[2:]: torch.as_tensor(np.asarray(v)) for k, v in arrays.items()
                 if k.startswith("w_")}
        model.load_state_dict(state)
        return model.to(device).eval()
