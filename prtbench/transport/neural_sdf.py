"""Neural SDFs: a small sine MLP fitted to a triangle mesh's signed distance (torch, CPU).

The thesis renders the Stanford bunny as the weight-encoded neural SDF of Davies et al. 2021 in
two network sizes (table 4.3: k = 32, l = 2 and k = 64, l = 2). We fit our own: an MLP
3 → k → … → k → 1 with l hidden layers of width k and sine activations (SIREN, Sitzmann et al.
2020, whose ω₀ is folded into the stored weights), on coordinates normalised to [−1, 1]³ over
the mesh's padded bounding box.

Training data: signed distances of the mesh at points near its surface (area-uniform samples
jittered by two Gaussian scales) and uniform in the box. The unsigned distance is exact: the
nearest of the faces owning the k nearest of dense surface samples (scipy cKDTree), by an exact
point–triangle distance. The sign comes from embree: a point is inside when most of a few
rays from it first hit a triangle from behind (robust to small holes and to the fans that
close them). Loss: L1 on the distance, Adam with cosine decay, a fixed number of steps.

The fitted network is a :class:`NeuralSdf` node of the SDF tree (:mod:`prtbench.transport.sdf`): NumPy
evaluation for precompute and marching cubes, GLSL emission (weights as ``const mat4`` /
``vec4`` blocks) for sphere tracing. Its output is divided by an empirical Lipschitz bound
(max gradient norm over the box, times a margin) so sphere tracing never oversteps, and outside
the padded box it is the distance to the box plus the padding (a lower bound of the distance to
the mesh), since the network is only trained inside.

Weights are cached (prtbench.api.cache, kind ``neural-sdf``) by mesh content, size, seed and
training settings.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from prtbench.api.cache import content_key
from prtbench.api.errors import InvalidInputError
from prtbench.scene.geometry import sample_surface
from prtbench.scene.model import TriangleMesh
from prtbench.transport.raytrace import Tracer
from prtbench.transport.sdf.nodes import (
    Codegen,
    Points,
    Primitive,
    _box_distance,
    glsl_float,
    glsl_vec3,
)

#: Network sizes (hidden width k, hidden layers l) of thesis table 4.3.
SIZES = {"small": (32, 2), "large": (64, 2)}

#: Bump when the data, the architecture or the training change (part of the cache key).
NEURAL_SDF_VERSION = 2  # 2: trained under MKL strict reproducibility (prtbench/__init__.py)

#: Box padding around the mesh, as a fraction of its largest half extent.
PADDING = 0.1

#: Safety factor on the measured Lipschitz bound.
LIPSCHITZ_MARGIN = 1.05


# --- exact unsigned distance and robust sign ------------------------------------------------------

def closest_points_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray,
                                ) -> np.ndarray:
    """Closest points (N, 3) of triangles (a, b, c) (each (N, 3)) to points ``p`` (N, 3).

    Voronoi-region classification of the point against the triangle's vertices, edges and face
    (barycentric projections with the edge dot products), vectorised.
    """
    ab, ac, ap = b - a, c - a, p - a
    bp, cp = p - b, p - c

    def dot(u: np.ndarray, v: np.ndarray) -> np.ndarray:
        return np.einsum("ij,ij->i", u, v)

    d1, d2 = dot(ab, ap), dot(ac, ap)
    d3, d4 = dot(ab, bp), dot(ac, bp)
    d5, d6 = dot(ab, cp), dot(ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        t_ab = d1 / (d1 - d3)
        t_ac = d2 / (d2 - d6)
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        denom = 1.0 / (va + vb + vc)
        v, w = vb * denom, vc * denom
    conditions = [
        (d1 <= 0) & (d2 <= 0),                              # vertex a
        (d3 >= 0) & (d4 <= d3),                             # vertex b
        (vc <= 0) & (d1 >= 0) & (d3 <= 0),                  # edge ab
        (d6 >= 0) & (d5 <= d6),                             # vertex c
        (vb <= 0) & (d2 >= 0) & (d6 <= 0),                  # edge ac
        (va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0),    # edge bc
    ]
    with np.errstate(invalid="ignore"):
        choices = [a, b, a + t_ab[:, None] * ab, c, a + t_ac[:, None] * ac,
                   b + t_bc[:, None] * (c - b)]
        face = a + v[:, None] * ab + w[:, None] * ac
    out = face.copy()
    # np.select semantics, applied row-wise to (N, 3) choices: the first true condition wins.
    done = np.zeros(len(p), dtype=bool)
    for cond, choice in zip(conditions, choices):
        sel = cond & ~done
        out[sel] = choice[sel]
        done |= sel
    # Degenerate (collinear) triangles break the region tests: the nearest of their edges.
    area2 = np.einsum("ij,ij->i", np.cross(ab, ac), np.cross(ab, ac))
    scale2 = np.maximum(np.einsum("ij,ij->i", ab, ab), np.einsum("ij,ij->i", ac, ac))
    bad = ~(area2 > 1e-20 * scale2 * scale2) | ~np.all(np.isfinite(out), axis=1)
    if bad.any():
        pb, best, best_d = p[bad], None, None
        for s0, s1 in ((a, b), (b, c), (c, a)):
            e = s1[bad] - s0[bad]
            ee = np.einsum("ij,ij->i", e, e)
            with np.errstate(divide="ignore", invalid="ignore"):
                t = np.where(ee > 0, np.einsum("ij,ij->i", pb - s0[bad], e) / ee, 0.0)
            q = s0[bad] + np.clip(t, 0.0, 1.0)[:, None] * e
            dq = np.einsum("ij,ij->i", pb - q, pb - q)
            if best is None:
                best, best_d = q, dq
            else:
                closer = dq < best_d
                best[closer], best_d[closer] = q[closer], dq[closer]
        out[bad] = best
    return out


class MeshDistance:
    """Signed distance to a closed triangle mesh (negative inside).

    Points within ``band`` of the surface get the exact distance to the nearest of the faces
    owning their ``candidates`` nearest dense samples; farther points get the distance to the
    nearest of a coarse sample set (an overestimate by at most about its spacing, under 1 % of
    the diagonal by default). A k-d tree query is slow for points nearly equidistant from many
    samples (deep inside a round shape), so the dense tree is only asked within ``band``.

    Parameters
    ----------
    mesh : TriangleMesh
    samples : int
        Dense surface samples whose faces are the exact-distance candidates.
    coarse_samples : int
        Samples for the distance of points beyond ``band``.
    band : float
        Exact-distance band, as a fraction of the mesh's bounding-box diagonal.
    candidates : int
        Nearest dense samples (hence candidate faces) per query point.
    seed : int
    """

    def __init__(self, mesh: TriangleMesh, *, samples: int = 300_000,
                 coarse_samples: int = 20_000, band: float = 0.05, candidates: int = 12,
                 seed: int = 0):
        from scipy.spatial import cKDTree

        self.mesh = mesh
        self.positions = mesh.positions.astype(np.float64)
        self.faces = mesh.faces.astype(np.int64)
        self.diagonal = float(np.linalg.norm(self.positions.max(axis=0)
                                             - self.positions.min(axis=0)))
        s = sample_surface(mesh, samples, seed=seed, min_barycentric=0.0)
        # Face centroids too, so that every face near a query has a candidate sample nearby.
        self._sample_points = np.concatenate([s.points, self.positions[self.faces].mean(axis=1)])
        self._sample_faces = np.concatenate([s.face_ids, np.arange(len(self.faces))])
        self._tree = cKDTree(self._sample_points)
        coarse = sample_surface(mesh, coarse_samples, seed=seed + 1, min_barycentric=0.0)
        self._coarse_tree = cKDTree(coarse.points)
        self.band = float(band) * self.diagonal
        self.candidates = int(candidates)
        self._tracer = Tracer(mesh.positions, mesh.faces)
        p = self.positions[self.faces]
        self._face_normals = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])

    def unsigned(self, points: np.ndarray) -> np.ndarray:
        """(N,) distance to the mesh (exact within the band), float64."""
        q = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        out = np.empty(len(q))
        step = 1 << 15
        n_samples = len(self._sample_points)
        for s in range(0, len(q), step):
            block = q[s:s + step]
            dist, idx = self._tree.query(block, k=self.candidates,
                                         distance_upper_bound=self.band)
            near = np.isfinite(dist[:, 0])
            result = np.empty(len(block))
            if near.any():
                idx_near = idx[near]
                valid = idx_near < n_samples  # fewer than k samples within the band
                # Pad missing candidates with the nearest one (always present for near points).
                idx_near = np.where(valid, idx_near, idx_near[:, :1])
                faces = self._sample_faces[idx_near].reshape(-1)
                tri = self.positions[self.faces[faces]]
                rep = np.repeat(block[near], self.candidates, axis=0)
                closest = closest_points_on_triangles(rep, tri[:, 0], tri[:, 1], tri[:, 2])
                exact = np.sqrt(np.einsum("ij,ij->i", rep - closest, rep - closest))
                result[near] = exact.reshape(-1, self.candidates).min(axis=1)
            if (~near).any():
                result[~near] = self._coarse_tree.query(block[~near], k=1)[0]
            out[s:s + step] = result
        return out

    def inside(self, points: np.ndarray, *, rays: int = 5) -> np.ndarray:
        """(N,) bool: most of ``rays`` fixed directions first hit a triangle from behind."""
        q = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        golden = math.pi * (3.0 - math.sqrt(5.0))
        k = np.arange(rays) + 0.5
        z = 1.0 - 2.0 * k / rays
        r = np.sqrt(1.0 - z * z)
        directions = np.stack([r * np.cos(golden * k), r * np.sin(golden * k), z], axis=1)
        votes = np.zeros(len(q), dtype=np.int32)
        for d in directions:
            hits = self._tracer.first_hit(q.astype(np.float32),
                                          np.tile(d.astype(np.float32), (len(q), 1)))
            hit = hits.face >= 0
            back = np.zeros(len(q), dtype=bool)
            back[hit] = self._face_normals[hits.face[hit]] @ d > 0
            votes += back
        return votes * 2 > rays

    def __call__(self, points: np.ndarray) -> np.ndarray:
        """(N,) signed distance, negative inside."""
        d = self.unsigned(points)
        return np.where(self.inside(points), -d, d)


# --- the network node ---------------------------------------------------------------------------

#: Loop bounds of the GLSL network: constant (unrolled by the compiler) only when the program
#: defines NEURAL_SDF_UNROLL. By default a never-set uniform (GL initialises uniforms to 0) is
#: added to the trip count, so compilers keep the loops rolled: every scene_sdf call site is
#: inlined (sphere tracing, 4 normal taps, the material), and unrolled copies of the 64-wide
#: network took llvmpipe 31 s to compile against 2 s rolled.
_LOOP_ZERO_GLSL = """#ifdef NEURAL_SDF_UNROLL
#define NEURAL_SDF_LOOP_ZERO 0
#else
uniform int neural_sdf_loop_zero;  // never set: 0, unknown to the compiler
#define NEURAL_SDF_LOOP_ZERO neural_sdf_loop_zero
#endif"""

@dataclass(frozen=True, eq=False)
class NeuralSdf(Primitive):
    """A fitted sine-MLP SDF as a node of the SDF tree (one material id).

    d(p) = net((p − center)/scale)·scale / lipschitz inside the padded box, and the distance to
    the box plus the padding outside it. ``layers`` holds (W (out, in), b (out,)) float32 pairs;
    hidden layers apply sin (first-layer ω₀ folded into W, b), the last one is linear.
    """

    layers: tuple[tuple[np.ndarray, np.ndarray], ...] = ()
    center: tuple[float, float, float] = (0.0, 0.0, 0.0)
    scale: float = 1.0
    lipschitz: float = 1.0
    padding: float = 0.1
    name: str = "neural"

    def __post_init__(self) -> None:
        super().__post_init__()
        layers = tuple((np.asarray(w, dtype=np.float32), np.asarray(b, dtype=np.float32))
                       for w, b in self.layers)
        if len(layers) < 2 or layers[0][0].shape[1] != 3 or layers[-1][0].shape[0] != 1:
            raise InvalidInputError("neural SDF layers must map 3 inputs through hidden layers "
                                    "to 1 output")
        width = layers[0][0].shape[0]
        if width % 4 or any(w.shape != (width, width) for w, _ in layers[1:-1]) \
                or layers[-1][0].shape != (1, width):
            raise InvalidInputError(f"neural SDF hidden widths must all equal one multiple of 4; "
                                    f"got {[w.shape for w, _ in layers]}")
        object.__setattr__(self, "layers", layers)
        object.__setattr__(self, "center", tuple(float(c) for c in self.center))
        for attr in ("scale", "lipschitz", "padding"):
            value = float(getattr(self, attr))
            if not value > 0:
                raise InvalidInputError(f"neural SDF {attr}={value}; accepted: > 0")
            object.__setattr__(self, attr, value)

    @property
    def width(self) -> int:
        return int(self.layers[0][0].shape[0])

    @property
    def hidden_layers(self) -> int:
        return len(self.layers) - 1

    @property
    def n_parameters(self) -> int:
        return int(sum(w.size + b.size for w, b in self.layers))

    def box_half(self) -> np.ndarray:
        """Half extents of the padded box the network is trained in (world units)."""
        return np.full(3, self.scale)

    def network(self, x: np.ndarray) -> np.ndarray:
        """Raw network output (N,) at normalised coordinates ``x`` (N, 3), float64."""
        h = np.asarray(x, dtype=np.float64)
        for w, b in self.layers[:-1]:
            h = np.sin(h @ w.T.astype(np.float64) + b.astype(np.float64))
        w, b = self.layers[-1]
        return (h @ w.T.astype(np.float64) + b.astype(np.float64))[:, 0]

    def _distance(self, p: Points) -> np.ndarray:
        box = _box_distance(tuple(c - o for c, o in zip(p, self.center)), self.box_half())
        out = box + self.padding
        inside = box <= 0
        if inside.any():
            x = np.stack([(c[inside] - o) / self.scale for c, o in zip(p, self.center)], axis=1)
            out[inside] = self.network(x) * (self.scale / self.lipschitz)
        return out

    def _call(self) -> str:
        return f"{self._function_name()}({{p}})"

    def _function_name(self) -> str:
        return "neural_sdf_" + content_key(self._weights_spec())[:10]

    def _weights_spec(self) -> list:
        return [[w, b] for w, b in self.layers]

    def _emit(self, cg: Codegen, p: str) -> tuple[str, str]:
        name = self._function_name()
        cg.function("neural_sdf_loop_zero", _LOOP_ZERO_GLSL)
        cg.function(name, self._glsl_function(name))
        return super()._emit(cg, p)

    def _glsl_function(self, name: str) -> str:
        """GLSL evaluation: weights as const mat4 blocks (4 outputs × 4 inputs) and vec4s."""
        k4 = self.width // 4
        lines = [f"// Neural SDF: sine MLP 3 -> {self.width} x {self.hidden_layers} -> 1 "
                 f"({self.n_parameters} parameters).", ""]

        def mat4(block: np.ndarray) -> str:
            # GLSL fills mat4 column by column: column j holds the weights of input j.
            return "mat4(" + ", ".join(glsl_float(v) for v in block.T.reshape(-1)) + ")"

        def vec4(values: np.ndarray) -> str:
            return "vec4(" + ", ".join(glsl_float(v) for v in values) + ")"

        w0, b0 = self.layers[0]
        # First layer: input vec4(x, y, z, 1), the bias in the fourth column.
        first = np.concatenate([w0, b0[:, None]], axis=1)
        lines.append(f"const mat4 {name}_w0[{k4}] = mat4[](")
        lines.append(",\n".join("    " + mat4(first[4 * o:4 * o + 4]) for o in range(k4)))
        lines.append(");")
        for li, (w, b) in enumerate(self.layers[1:-1], start=1):
            blocks = [mat4(w[4 * o:4 * o + 4, 4 * i:4 * i + 4]) for o in range(k4)
                      for i in range(k4)]
            lines.append(f"const mat4 {name}_w{li}[{k4 * k4}] = mat4[](")
            lines.append(",\n".join("    " + m for m in blocks))
            lines.append(");")
            lines.append(f"const vec4 {name}_b{li}[{k4}] = vec4[](")
            lines.append(",\n".join("    " + vec4(b[4 * o:4 * o + 4]) for o in range(k4)))
            lines.append(");")
        w_out, b_out = self.layers[-1]
        lines.append(f"const vec4 {name}_wout[{k4}] = vec4[](")
        lines.append(",\n".join("    " + vec4(w_out[0, 4 * i:4 * i + 4]) for i in range(k4)))
        lines.append(");")
        lines += [
            "",
            f"float {name}(vec3 p) {{",
            f"    vec3 q = p - {glsl_vec3(self.center)};",
            f"    float box = sdf_box(q, vec3({glsl_float(self.scale)}));",
            f"    if (box > 0.0) return box + {glsl_float(self.padding)};",
            f"    vec4 x = vec4(q / {glsl_float(self.scale)}, 1.0);",
            f"    int n = {k4} + NEURAL_SDF_LOOP_ZERO;",
            f"    vec4 h[{k4}];",
            "    for (int o = 0; o < n; ++o) h[o] = sin(" + f"{name}_w0[o] * x);",
        ]
        for li in range(1, self.hidden_layers):
            lines += [
                f"    vec4 h{li}[{k4}];",
                "    for (int o = 0; o < n; ++o) {",
                f"        vec4 acc = {name}_b{li}[o];",
                f"        for (int i = 0; i < n; ++i) acc += {name}_w{li}[o * {k4} + i] * h[i];",
                f"        h{li}[o] = sin(acc);",
                "    }",
                f"    h = h{li};",
            ]
        lines += [
            f"    float d = {glsl_float(float(b_out[0]))};",
            "    for (int i = 0; i < n; ++i) d += dot(" + f"{name}_wout[i], h[i]);",
            f"    return d * {glsl_float(self.scale / self.lipschitz)};",
            "}",
        ]
        return "\n".join(lines)

    def _spec(self) -> dict[str, Any]:
        return {"name": self.name, "weights": content_key(self._weights_spec()),
                "shape": [list(w.shape) for w, _ in self.layers], "center": list(self.center),
                "scale": self.scale, "lipschitz": self.lipschitz, "padding": self.padding,
                "material": self.material}


