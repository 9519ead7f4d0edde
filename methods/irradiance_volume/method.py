"""Irradiance volume (Greger, Shirley, Hubbard and Greenberg 1998): a regular grid of SH probes.

Precompute (light-independent). An N×N×N grid of probes spans the scene bounds, padded on every
side by ``padding`` × the bounding-box diagonal. A probe is a point in space, not on a surface,
so it stores the SH projection of its binary visibility over the whole sphere, without cosine::

    V_i(x) = ∫ Y_i(ω) V(x, ω) dω            (V_0 = √(4π) when every ray escapes)

estimated with ``rays_per_probe`` uniform sphere directions (a Cranley–Patterson shifted
Fibonacci lattice) turned by a random rotation per probe; the SH are evaluated once in the
pattern's frame and each probe's coefficients are rotated (prtbench.transport.ray_pattern.ShRotation).

Invalid probes. A probe inside a closed object, or under a one-sided ground, sees the back of
the surfaces around it. A probe whose fraction of back-face hits exceeds
``invalid_backface_fraction`` is flagged invalid and left out of the interpolation (the
trilinear weights are renormalised over the valid corners; if all eight are invalid, the plain
trilinear weights are used). This is the classical fix and it is partial: a valid probe on the
far side of a thin wall or above a table top still bleeds into surfaces it cannot see, which
``prtbench table volume`` measures as a leak error rather than hiding it.

Render (per light). The incident radiance at a probe is the triple product
R_k = Σ_ij Γ_ijk V_i L_j (n², RGB), computed on the CPU once per light (TPFL matrix) and cached;
it lives on the GPU as one RGB 3D texture. The fragment shader looks the grid up at
p + ``normal_bias``·n in grid units (cells), interpolates the probe SH trilinearly, and shades
B = kd/π · Σ_l √(4π/(2l+1)) g_l Σ_m R_lm Y_lm(n) with g_l the clamped-cosine zonal
coefficients (DESIGN.md §5). Back faces are black. Diffuse materials only.

Resident memory: the radiance texture, N³·n²·3 values of 4 (float32) or 2 (float16) bytes, plus
the validity texture, N³ bytes: :func:`memory_closed_form`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from tqdm import tqdm

from methods.common.materials import check_diffuse_constant_kd
from methods.common.sphere_rays import random_rotations, sphere_pattern
from methods.irradiance_volume import SHADER_DIR
from prtbench.api.config import knob, seed_knob
from prtbench.api.errors import InvalidInputError
from prtbench.api.method import Artifact, Method, register_method
from prtbench.render import gl, ops
from prtbench.render.raster import RasterRenderer, clip_planes, draw_after_depth_prepass
from prtbench.transport.parallel import map_chunks, parallel_chunks
from prtbench.transport.ray_pattern import ShRotation
from prtbench.transport.raytrace import Tracer
from prtbench.transport.sh import clamped_cosine_zonal, eval_sh, tpfl_matrix

#: Rays per embree call while tracing probes (bounds the temporary arrays to ~100 MB).
_RAYS_PER_CHUNK = 1 << 19

#: Bytes per stored value of each precision.
PRECISION_BYTES = {"float32": 4, "float16": 2}


@dataclass(frozen=True)
class IrradianceVolumeConfig:
    """Knobs of the ``irradiance-volume`` method."""

    resolution: int = knob(8, "Probes per axis N (N³ probes over the padded scene bounds).",
                           low=2, high=64)
    sh_bands: int = knob(3, "SH bands n of each probe's incident radiance (n² RGB coefficients).",
                         low=1, high=8)
    rays_per_probe: int = knob(256, "Uniform sphere rays per probe (stratified, randomly rotated).",
                               low=1, high=1 << 16)
    normal_bias: float = knob(0.5, "Lookup offset along the surface normal, in grid cells.",
                              low=0.0, high=4.0)
    padding: float = knob(0.02, "Grid padding on each side, as a fraction of the scene diagonal.",
                          low=0.0, high=1.0)
    invalid_backface_fraction: float = knob(
        0.25, "Probes with more back-face hits than this fraction of their rays are invalid.",
        low=0.0, high=1.0)
    precision: str = knob("float32", "Storage of the probe radiance texture.",
                          choices=tuple(PRECISION_BYTES))
    seed: int = seed_knob("Seed of the ray pattern's shift and the per-probe rotations.")
    visibility: bool = knob(True, "Trace occlusion at the probes. False: every ray escapes "
                                  "(V_0 = √(4π) at every probe, all probes valid), i.e. "
                                  "unshadowed environment lighting, the trivial image the "
                                  "regression gate must beat.")


def memory_closed_form(*, resolution: int, sh_bands: int, precision: str) -> int:
    """Resident bytes: N³·n²·3 radiance values plus N³ validity bytes."""
    probes = resolution**3
    return probes * sh_bands**2 * 3 * PRECISION_BYTES[precision] + probes


def probe_grid(scene, *, resolution: int, padding: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The probe lattice over the scene bounds, padded by ``padding`` × diagonal on each side.

    Returns
    -------
    origin : ndarray, shape (3,)
        Position of probe (0, 0, 0).
    cell : ndarray, shape (3,)
        Probe spacing per axis; probe (i, j, k) sits at origin + (i, j, k)·cell.
    positions : ndarray, shape (N³, 3), float64
        Probe positions, index ((i·N) + j)·N + k (x slowest).
    """
    lo, hi = scene.bounds()
    pad = padding * max(float(np.linalg.norm(hi - lo)), 1e-6)
    lo, hi = lo - pad, hi + pad
    cell = (hi - lo) / (resolution - 1)
    idx = np.stack(np.meshgrid(*(np.arange(resolution),) * 3, indexing="ij"), axis=-1)
    return lo, cell, lo + idx.reshape(-1, 3) * cell


def probe_visibility(tracer, positions: np.ndarray, *, bands: int, rays_per_probe: int,
                     seed: int = 0, progress: bool = False,
                     occlusion: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Visibility SH and back-face hit fraction of probes in space.

    Parameters
    ----------
    tracer : prtbench.transport.raytrace.Tracer
    positions : ndarray, shape (P, 3)
    bands : int
    rays_per_probe : int
    seed : int
    progress : bool
    occlusion : bool
        Trace rays (default); ``False`` counts every ray as escaping (no ray is traced).

    Returns
    -------
    visibility : ndarray, shape (P, n²), float64
        V_i = ∫ Y_i V dω ≈ 4π/M Σ_j Y_i(ω_j) V(ω_j) (any hit, either side, blocks).
    backface_fraction : ndarray, shape (P,), float64
        Fraction of rays whose first hit is the back of a triangle.
    """

    p = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    m = int(rays_per_probe)
    rng = np.random.default_rng([int(seed), 0x4952_5256])  # stream tag: "IRRV"
    local = sphere_pattern(m, rng)
    world_from_local = random_rotations(len(p), rng)
    y_local = eval_sh(local, bands) * (4.0 * np.pi / m)
    corners = tracer.positions.astype(np.float64)[tracer.faces]
    face_normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    rotate = ShRotation.for_bands(bands)
    visibility = np.zeros((len(p), bands * bands))
    backface = np.zeros(len(p))
    step = max(1, _RAYS_PER_CHUNK // m)

    def chunk(sl: slice) -> tuple[np.ndarray, np.ndarray]:
        """(visibility SH, back-face fraction) of the probes in ``sl``."""
        dirs = np.einsum("pij,mj->pmi", world_from_local[sl], local).reshape(-1, 3)
        if not occlusion:  # visibility off: every ray escapes, nothing is traced
            visible = np.ones((len(dirs) // m, m))
            return rotate(visible @ y_local, world_from_local[sl]), np.zeros(len(visible))
        hits = tracer.first_hit(np.repeat(p[sl], m, axis=0), dirs)
        hit = hits.face >= 0
        back = np.zeros_like(hit)
        back[hit] = np.einsum("hj,hj->h", dirs[hit], face_normal[hits.face[hit]]) > 0
        visible = (~hit).reshape(-1, m).astype(np.float64)
        return rotate(visible @ y_local, world_from_local[sl]), back.reshape(-1, m).mean(axis=1)

    # Probe chunks on the precompute threads (prtbench.transport.parallel); the rotations are drawn for
    # all probes up front, so every thread count gives the same bits.
    chunks = parallel_chunks(len(p), step)
    with tqdm(total=len(p), desc="irradiance-volume probes", unit="probe", disable=not progress) as bar:
        for (vis, back), sl in zip(map_chunks(chunk, chunks), chunks):
            visibility[sl] = vis
            backface[sl] = back
            bar.update(sl.stop - sl.start)
    return visibility, backface


def probe_radiance(visibility: np.ndarray, light_sh: np.ndarray, bands: int) -> np.ndarray:
    """Shadowed incident radiance SH R_k = Σ_ij Γ_ijk V_i L_j at every probe, (P, n², 3)."""
    return np.einsum("pi,ikc->pkc", np.asarray(visibility, np.float64),
                     tpfl_matrix(np.asarray(light_sh)[: bands * bands], bands))


@register_method("irradiance-volume")
class IrradianceVolume(Method):
    """Greger et al. 1998: SH probes on a grid, trilinearly interpolated per fragment."""

    storage = "per-probe"

    family = "probe volume"

    verdict_grid = {"resolution": [8, 16]}

    engine_baseline = True

    Config = IrradianceVolumeConfig
    precompute_version = "1"
    #: Knobs along which accuracy and cost both grow (searched by ``prtbench advise``).
    main_knobs = ("resolution", "sh_bands")
    paper = "Greger, Shirley, Hubbard and Greenberg 1998, The Irradiance Volume (IEEE CG&A)"
    light_dependence = "fixed-light"
    light_dependence_why = ("computes the probes' radiance R = Γ·V·L on the CPU once per light "
                            "(N³ triple products)")
    profile_overrides = {
        "smoke": {"rays_per_probe": 64},
        "quick": {"rays_per_probe": 256},
        "paper": {"rays_per_probe": 1024},
    }

    @classmethod
    def validate(cls, scene, config: IrradianceVolumeConfig) -> None:
        check_diffuse_constant_kd(
            "irradiance-volume", scene,
            renders="stores irradiance and renders diffuse materials only")

    @classmethod
    def precompute(cls, scene, config: IrradianceVolumeConfig, *, progress: bool = True) -> Artifact:
        origin, cell, positions = probe_grid(scene, resolution=config.resolution,
                                             padding=config.padding)
        visibility, backface = probe_visibility(
            Tracer.from_scene(scene), positions, bands=config.sh_bands,
            rays_per_probe=config.rays_per_probe, seed=config.seed, progress=progress,
            occlusion=config.visibility)
        valid = backface <= config.invalid_backface_fraction
        arrays = {"visibility": visibility.astype(np.float32), "valid": valid.astype(np.uint8),
                  "backface_fraction": backface.astype(np.float32),
                  "grid_origin": origin.astype(np.float64), "cell_size": cell.astype(np.float64)}
        return Artifact("irradiance-volume", arrays,
                        {"probes": int(len(positions)), "valid_probes": int(valid.sum()),
                         "sh_bands": config.sh_bands, "resolution": config.resolution})

    @classmethod
    def renderer(cls, scene, artifact: Artifact, config: IrradianceVolumeConfig, *, width: int,
                 height: int) -> "IrradianceVolumeRenderer":
        return IrradianceVolumeRenderer(scene, artifact, config, width=width, height=height)

    @classmethod
    def op_counts(cls, config: IrradianceVolumeConfig, *, scene_vertices: int,
                  scene_triangles: int, covered_pixels: int, width: int, height: int,
                  memory_bytes: int):
        """irradiance_volume.frag per covered pixel: the cell and its 8 trilinear weights with a
        validity fetch each, 8·n² RGB texel fetches weighted into n² coefficients, and the
        clamped-cosine zonal evaluation at the normal (sh_zonal_eval_rgb). The grid resolution
        N changes what is resident, not the per-pixel work: ``ops`` does not grow with N."""

        n2 = config.sh_bands**2
        texel = 12 if config.precision == "float32" else 6
        zonal_eval = ops.sh_eval_madds(config.sh_bands) + 3.0 * n2 + 6.0 * config.sh_bands
        per_pixel = {"madds": 20.0 + 8 * 6 + 8 * 3.0 * n2 + zonal_eval + 3 + ops.TRANSCENDENTAL_MADDS,
                     "fetches": 8.0 + 8.0 * n2, "bytes": 8.0 + 8.0 * n2 * texel}
        return ops.add_counts(
            ops.raster_counts(vertices=scene_vertices, triangles=scene_triangles,
                               pixels=covered_pixels, varyings=9, vertex_bytes=36),
            ops.scaled(per_pixel, covered_pixels))


def radiance_texture_layout(radiance: np.ndarray, resolution: int, bands: int) -> np.ndarray:
    """Probe radiance (N³, n², 3) → 3D texture data (depth n·N, height N, width n·N, 3).

    Coefficient i = a·n + b of probe (x, y, z) is texel (x + a·N, y, z + b·N), which keeps every
    side ≤ 8·64 = 512 (GL guarantees 3D textures of 256 and Mesa gives 2048).
    """
    n, res = bands, resolution
    r = np.asarray(radiance).reshape(res, res, res, n, n, 3)  # x, y, z, a, b, rgb
    return np.ascontiguousarray(r.transpose(4, 2, 1, 3, 0, 5).reshape(n * res, res, n * res, 3))


class IrradianceVolumeRenderer(RasterRenderer):
    """Trilinear probe lookup per fragment; the per-light radiance lives in a 3D texture.

    Each frame draws a depth-only pre-pass, then shades with GL_LEQUAL and no depth writes, so
    the (heavy) probe lookup runs once per visible pixel, not once per overlapping triangle.
    """

    shader_dirs = (SHADER_DIR,)

    def __init__(self, scene, artifact: Artifact, config: IrradianceVolumeConfig, *, width: int,
                 height: int):
        self.config = config
        res, n = config.resolution, config.sh_bands
        super().__init__(scene, width=width, height=height,
                         vertex_shader="irradiance_volume.vert",
                         fragment_shader="irradiance_volume.frag",
                         defines={"SH_BANDS": n, "GRID_N": res})
        self.depth_program = gl.load_program(
            self.ctx, "irradiance_volume.vert", "irradiance_volume.frag",
            defines={"SH_BANDS": n, "GRID_N": res, "DEPTH_ONLY": 1},
            search_path=[SHADER_DIR])
        positions, _, faces, _ = scene.merged()
        self.depth_vao = gl.upload_mesh(self.ctx, self.depth_program, positions, faces)
        self.visibility = artifact.arrays["visibility"]
        self.dtype = np.float32 if config.precision == "float32" else np.float16
        gl_dtype = "f4" if config.precision == "float32" else "f2"
        self.radiance_texture = self.ctx.texture3d((n * res, res, n * res), 3, dtype=gl_dtype,
                                                   alignment=1)
        valid = np.where(artifact.arrays["valid"].reshape(res, res, res) > 0, 255, 0).astype(np.uint8)
        valid = np.ascontiguousarray(valid.transpose(2, 1, 0))  # texel (x, y, z) at [z, y, x]
        self.valid_texture = self.ctx.texture3d((res, res, res), 1, valid.tobytes(), dtype="f1",
                                                alignment=1)
        for tex in (self.radiance_texture, self.valid_texture):
            tex.filter = (self.ctx.NEAREST, self.ctx.NEAREST)
        self._resident = [self.radiance_texture, self.valid_texture]
        # Bytes of the texels the textures hold (drivers may pad RGB texels to RGBA internally).
        self._resident_bytes = sum(
            t.width * t.height * t.depth * t.components * np.dtype(d).itemsize
            for t, d in ((self.radiance_texture, self.dtype), (self.valid_texture, np.uint8)))
        self._radiance_by_light: dict[str, np.ndarray] = {}
        self._uploaded: str | None = None
        self.program["zonal"].write(clamped_cosine_zonal(n).astype(np.float32).tobytes())
        self.program["grid_origin"].value = tuple(float(c) for c in artifact.arrays["grid_origin"])
        self.program["cell_size"].value = tuple(float(c) for c in artifact.arrays["cell_size"])
        self.program["normal_bias"].value = float(config.normal_bias)
        self.program["probe_radiance"].value = 0
        self.program["probe_valid"].value = 1

    def radiance(self, light) -> np.ndarray:
        """The probes' incident radiance SH for ``light``, (N³, n², 3) float64, cached per light."""
        key = light.content_hash()
        if key not in self._radiance_by_light:
            n = self.config.sh_bands
            self._radiance_by_light[key] = probe_radiance(self.visibility, light.sh(n), n)
        return self._radiance_by_light[key]

    def _upload(self, light) -> None:
        key = light.content_hash()
        if key == self._uploaded:
            return
        radiance = self.radiance(light)
        if self.dtype == np.float16 and np.abs(radiance).max() > np.finfo(np.float16).max:
            raise InvalidInputError(
                f"light '{light.name}' gives probe radiance {np.abs(radiance).max():.4g}, beyond "
                "float16; accepted: precision=float32 for this light")
        data = radiance_texture_layout(radiance.astype(self.dtype), self.config.resolution,
                                       self.config.sh_bands)
        self.radiance_texture.write(data.tobytes())
        self._uploaded = key

    def _bind(self, view, light) -> None:
        self._upload(light)  # once per light: later frames of the same light only bind
        self.radiance_texture.use(location=0)
        self.valid_texture.use(location=1)

    def _draw(self, view, light) -> None:
        near, far = clip_planes(self.scene, view)
        clip_from_world = (view.clip_from_camera(self.width / self.height, near, far)
                           @ view.camera_from_world()).T.astype(np.float32).tobytes()
        self.program["clip_from_world"].write(clip_from_world)
        self.depth_program["clip_from_world"].write(clip_from_world)
        self._bind(view, light)
        draw_after_depth_prepass(self.ctx, self.target, self.depth_vao, self.vao)

    def memory_bytes(self) -> int:
        return int(self._resident_bytes)

    def release(self) -> None:
        for obj in [self.depth_vao, *self.depth_vao.extra["buffers"], self.depth_program]:
            obj.release()
        super().release()

