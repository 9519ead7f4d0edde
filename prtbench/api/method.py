"""The contract every PRT method fulfils (DESIGN.md §2) and the method registry.

A method is a :class:`Method` subclass registered with ``@register_method("name")`` and
declared lazily in ``pyproject.toml`` (entry-point group ``prtbench.methods``). It has

* a ``Config`` dataclass of documented knobs (:func:`prtbench.api.config.knob`), built strictly;
* :meth:`Method.precompute`: everything light-independent, returned as an :class:`Artifact`
  and cached by a content hash of (scene, config, ``precompute_version``) through
  :func:`load_or_precompute`;
* :meth:`Method.renderer`: a :class:`Renderer` on a GL (or torch) context with
  ``render(view, light)``, ``frame_time(view, light)`` and ``memory_bytes()``.

Every method approximates the one radiance model of DESIGN.md §4, so with enough bands and
samples each converges to the same path-traced reference.
"""

from __future__ import annotations

import json
import math
import statistics
import time
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from prtbench.api import config as config_mod
from prtbench.api.cache import (
    atomic_path,
    cache_root,
    content_key,
    credit_cached_compute,
    entry_lock,
    load_arrays,
    save_arrays,
)
from prtbench.api.plugins import method_specs
from prtbench.api.profiles import get_profile
from prtbench.api.registry import Registry
from prtbench.api.residency import resident_parts

if TYPE_CHECKING:
    from prtbench.scene.model import Scene, View
    from prtbench.transport.lights import EnvironmentLight


@dataclass
class Artifact:
    """The light-independent result of a precompute.

    Attributes
    ----------
    method : str
    arrays : dict of str to ndarray
        Everything the renderer needs (transfer vectors, textures, weights, ...).
    meta : dict
        JSON-able facts (counts, timings of sub-steps, versions).
    precompute_s : float
        Wall time of the precompute that produced it (0 is never reported for a cache hit:
        the original time is stored with the artifact; a rebuild reports the original
        time too when it was recorded, see ``rebuilt``).
    cache_hit : bool
    rebuilt : bool
        The cached file was corrupt (or removed after a record of its build was kept) and
        the artifact was computed again, usually much faster than the first time because
        the sub-steps (transfer, projections) are still cached.
    rebuild_s : float or None
        Wall time of that rebuild; ``precompute_s`` stays the original build's time when it
        is known (``original_time_known``), else it is the rebuild's time.
    original_time_known : bool
        False only for a rebuild whose first build left no record of its time.
    """

    method: str
    arrays: dict[str, np.ndarray]
    meta: dict[str, Any] = field(default_factory=dict)
    precompute_s: float = 0.0
    cache_hit: bool = False
    rebuilt: bool = False
    rebuild_s: float | None = None
    original_time_known: bool = True

    @property
    def nbytes(self) -> int:
        return int(sum(a.nbytes for a in self.arrays.values()))


@dataclass(frozen=True)
class FrameTimes:
    """Frame times in milliseconds (median / p95 / mean of the timed frames).

    ``source`` is ``"timer-query"`` or ``"wall+finish"`` (software rasterisers), see
    :class:`prtbench.render.gl.FrameTimes`.
    """

    median_ms: float
    p95_ms: float
    mean_ms: float
    frames: int
    renderer: str
    source: str = "timer-query"


def wall_frame_times(frame: Callable[[], object], *, warmup: int, frames: int, renderer: str,
                     source: str) -> FrameTimes:
    """Host clock around ``frames`` whole calls of ``frame`` after ``warmup`` untimed ones.

    For renderers whose frame is not one GL draw (CPU relighting, torch networks): ``frame``
    must end with whatever makes the work complete (glFinish, a CUDA synchronisation), and
    ``source`` names that (``"wall+finish"``, ``"wall+sync"``, ``"cpu-wall"``). Callers check
    their own ``warmup``/``frames`` bounds.
    """
    for _ in range(int(warmup)):
        frame()
    samples = []
    for _ in range(int(frames)):
        start = time.perf_counter()
        frame()
        samples.append((time.perf_counter() - start) * 1e3)
    return FrameTimes(float(statistics.median(samples)), float(np.percentile(samples, 95)),
                      float(statistics.fmean(samples)), int(frames), renderer, source)


class Renderer(ABC):
    """Renders one method's artifact; owns its GL/torch resources."""

    #: GL_RENDERER (+ version) or torch device string, recorded with every timing.
    renderer_string: str = "unknown"

    @abstractmethod
    def render(self, view: "View", light: "EnvironmentLight") -> np.ndarray:
        """Linear HDR image, float32 (H, W, 3), row 0 at the top; background 0."""

    @abstractmethod
    def frame_time(self, view: "View", light: "EnvironmentLight", *, warmup: int,
                   frames: int) -> FrameTimes:
        """GPU time of one frame (timer queries; never the first frame or readback)."""

    @abstractmethod
    def memory_bytes(self) -> int:
        """Bytes the method must keep resident to render (transfer data, textures, weights)."""

    #: Milliseconds of each part of the last timed frames (medians), filled by
    #: :meth:`frame_time` where a frame has parts (CPU relighting, upload, draw, readback,
    #: network, ...); empty: the whole frame is one part.
    frame_components: dict[str, float] = {}
    #: True when the renderer draws the one light its precompute baked and refuses any other
    #: (a lightmap baked with ``bake_light``): a new light is a new precompute, not work of the
    #: renderer's, so the runner times no ``light_change_ms`` for it.
    bakes_its_light: bool = False

    def light_change(self, light: "EnvironmentLight") -> bool:
        """Do, from scratch, the work a new ``light`` costs before its first frame (an SH
        projection, per-light matrices, a cubemap resampling, median cut), so that the runner
        can time it (``light_change_ms``). Returns False when the method has none to do."""
        return False

    def memory_breakdown(self) -> dict[str, int]:
        """Every resident part, ``{"gpu: transfer_buffer": bytes, "cpu: model.weights": ...}``.

        Everything the renderer holds to draw the next frame -- buffers, textures, weights,
        atlases, G-buffers, render targets, cached images -- found on the renderer by
        :func:`prtbench.api.residency.resident_parts` (a test checks the GL parts against
        what the renderer really allocated). Its sum is what rankings count as memory;
        :meth:`memory_bytes` stays the method's own data, as its paper counts it.
        """
        return resident_parts(self)

    def release(self) -> None:
        """Free GPU resources."""


class Method(ABC):
    """Base class of a PRT method plug-in."""

    name: ClassVar[str]
    Config: ClassVar[type]
    #: Bump when the precompute's output changes for the same inputs (invalidates caches).
    precompute_version: ClassVar[str] = "1"
    #: Per-profile config overrides, e.g. ``{"smoke": {"rays_per_point": 64}}``.
    profile_overrides: ClassVar[Mapping[str, Mapping[str, Any]]] = {}
    #: One line for ``prtbench list methods``.
    summary: ClassVar[str] = ""
    #: The publication the method implements (authors, year, section), for ``prtbench describe``.
    paper: ClassVar[str] = ""
    #: How rendering depends on the light, which ``prtbench analyze`` rules methods out by:
    #: ``"none"`` (any light at render time), ``"fixed-light"`` (one light is folded into
    #: per-light state before rendering, so a light that changes pays a re-fold outside the
    #: measured frame time) or ``"family"`` (the precompute is learnt from a family of lights;
    #: a light outside the family is extrapolated). See :data:`LIGHT_DEPENDENCES`.
    light_dependence: ClassVar[str] = "none"
    #: Why, in one line, for ``analyze``/``advise`` reports.
    light_dependence_why: ClassVar[str] = ""
    #: True for a method whose precompute belongs to the scene's views (per-pixel transport of
    #: one fixed view): the views then enter the artifact's cache key.
    fixed_view: ClassVar[bool] = False
    #: True for a method whose precompute reads the scene's cameras without being tied to one
    #: view (a network trained on renders around the trajectory): the views enter the
    #: artifact's cache key too, so another trajectory is a different artifact.
    views_in_key: ClassVar[bool] = False
    #: Knob settings that tie an otherwise light-free method to a light:
    #: ``{knob: (dependence, light-free value, why)}``.
    light_baking_knobs: ClassVar[Mapping[str, tuple[str, Any, str]]] = {}
    #: The light class of the protocol (docs/PROTOCOL.md), one of :data:`LIGHT_CLASSES`:
    #: ``relight`` (renders any light; per-light work such as an SH projection or a TPFL
    #: matrix is measured as ``light_change_ms``), ``family`` (fitted or learnt from a family
    #: of lights, e.g. rotations of one map) or ``fixed`` (one light baked into the
    #: precompute). A knob of :attr:`baked_light_knobs` away from its light-free value makes
    #: a config ``fixed`` (:meth:`light_class_of`).
    light_class: ClassVar[str] = "relight"
    #: Knobs that bake a light into the precompute: ``{knob: light-free value}``.
    baked_light_knobs: ClassVar[Mapping[str, Any]] = {}
    #: Where the method keeps what it precomputes, which is what its cost grows with; one of
    #: :data:`STORAGES`: ``"per-vertex"`` (the mesh's tessellation limits it), ``"per-texel"``
    #: (of a UV atlas), ``"per-probe"`` (of a volume), ``"per-pixel"`` (of one fixed view),
    #: ``"network"`` (weights of a learnt model). Drivers ask
    #: this (e.g. the stability matrix's large-mesh case) instead of listing method names.
    #: Every method must declare it (a test checks).
    storage: ClassVar[str] = ""
    #: The family ``prtbench verdict`` compares at equal budgets (its best configuration
    #: stands for the family): ``"SH PRT"``, ``"wavelet PRT"``, ``"probe volume"``, ... Every
    #: method must declare it (a test checks).
    family: ClassVar[str] = ""
    #: True for what engines ship today (probe volumes, lightmaps, AO with bent normals): the
    #: baselines a PRT method has to beat at the same bytes and work (``prtbench verdict``).
    engine_baseline: ClassVar[bool] = False
    #: The configurations ``prtbench verdict`` measures where the store lacks them (None: the
    #: method is not in the verdict): knob -> values, ``{}`` for the profile's defaults. A
    #: ``texture_resolution`` of ``"auto"`` is the smallest atlas that packs the scene,
    #: ``"auto2"`` that and twice it (:func:`prtbench.tradeoff.verdict.auto_texture_resolutions`);
    #: ``"@light"`` is the verdict's light (a baked light, as engines ship it).
    verdict_grid: ClassVar[Mapping[str, Any] | None] = None
    #: Knobs along which accuracy and cost both grow, in the order ``prtbench advise``
    #: searches them (e.g. ``("sh_bands",)``); none: the advisor measures the defaults only.
    main_knobs: ClassVar[tuple[str, ...]] = ()
    #: True when the method adds nothing but glossy transfer to a cheaper diffuse one, so the
    #: advisor drops it for a scene without glossy materials.
    glossy_only: ClassVar[bool] = False
    #: The case ``prtbench regress`` measures the method on (smoke profile): ``scene``,
    #: ``variant``, ``light``, and optionally ``scene_params`` and config ``overrides``, on top
    #: of ``plants`` diffuse under ``sky`` (prtbench.bench.regress.DEFAULT_CASE). A method
    #: overrides it where the default case is too small to beat the trivial images.
    regression_case: ClassVar[Mapping[str, Any]] = {}
    #: Further regression cases ``method:variant`` -> config overrides (e.g. a compressed form).
    regression_variants: ClassVar[Mapping[str, Mapping[str, Any]]] = {}
    #: Why the method has no ``visibility`` knob (so no unshadowed trivial image exists for the
    #: regression gate); None: it has one, or the gate says it lacks one.
    no_visibility_reason: ClassVar[str | None] = None

    @classmethod
    def make_config(cls, overrides: Mapping[str, Any] | None = None, *, profile: str = "quick"):
        """Strict config: defaults, then the profile's overrides, then the user's.

        An unknown ``profile`` raises :class:`prtbench.api.errors.UnknownNameError` (a silent
        fallback to the defaults would label a default-sized run with the wrong profile).
        """

        get_profile(profile)
        values = dict(cls.profile_overrides.get(profile, {}))
        values.update(overrides or {})
        return config_mod.from_dict(cls.Config, values)

    @classmethod
    def cache_identity(cls, config: Any) -> dict[str, Any]:
        """The config as it enters the artifact's cache key: every knob by default. A method may
        leave out knobs at a value that cannot change its artifact, so that adding a knob keeps
        the existing cache entries valid (e.g. ``compress='none'``, prtbench.transport.compress.knobs)."""
        return config_mod.to_dict(config)

    @classmethod
    def validate(cls, scene: "Scene", config: Any) -> None:
        """Raise a PrtbenchError if this method cannot handle ``scene`` with ``config``."""

    @classmethod
    def validate_resolution(cls, config: Any, *, width: int, height: int) -> None:
        """Raise a PrtbenchError if this method cannot render ``width`` × ``height`` pixels
        with ``config`` (a fixed-view method's transport is per pixel); any by default."""

    @classmethod
    def light_class_of(cls, config: Any) -> str:
        """The light class of ``config``: :attr:`light_class`, or ``fixed`` where a knob of
        :attr:`baked_light_knobs` bakes a light into the precompute."""
        for knob, free_value in cls.baked_light_knobs.items():
            if getattr(config, knob, free_value) != free_value:
                return "fixed"
        return cls.light_class

    @classmethod
    def diagnostic_reason(cls, config: Any) -> str | None:
        """Why ``config`` is a diagnostic that no ranking may show (e.g. it takes pixels from
        the reference renderer); None for a configuration that meets the protocol."""
        return None

    @classmethod
    def training_lights(cls, config: Any) -> tuple[str, ...]:
        """Names of the registered lights the precompute trains or fits on (rotations of them
        included); a run under one of them is ``trained``, not held out. None by default."""
        return ()

    @classmethod
    def training_cameras(cls, scene: "Scene", config: Any) -> list["View"]:
        """The cameras whose images the precompute trains or fits on; an evaluated view that
        coincides with one is ``trained``, not held out (docs/PROTOCOL.md). None by default."""
        return []

    @classmethod
    def compress_dimension(cls, config: Any) -> int | None:
        """Values per signal of the transfer its ``compress`` knobs compress, where the stored
        artifact does not show it (the stability matrix derives ``pca_vectors = d`` from it);
        None: read it from the uncompressed artifact."""
        return None

    @classmethod
    @abstractmethod
    def precompute(cls, scene: "Scene", config: Any, *, progress: bool = True) -> Artifact:
        """Compute everything light-independent."""

    @classmethod
    @abstractmethod
    def renderer(cls, scene: "Scene", artifact: Artifact, config: Any, *, width: int,
                 height: int) -> Renderer:
        """A renderer for ``artifact`` at ``width`` × ``height``."""

    @classmethod
    def op_counts(cls, config: Any, *, scene_vertices: int, scene_triangles: int,
                  covered_pixels: int, width: int, height: int, memory_bytes: int):
        """Device-independent work of one frame: the ``ops`` cost model (prtbench.tradeoff.cost).

        Each method declares it beside its code, from what its shaders do per vertex, per
        covered pixel and per frame; it may use only these stored facts of a result row, so
        fronts can be drawn from the results store alone.

        Parameters
        ----------
        config
            The method's Config, as stored with the row.
        scene_vertices, scene_triangles : int
            Of the rendered scene.
        covered_pixels : int
            Pixels of the view covered by geometry.
        width, height : int
            Render resolution.
        memory_bytes : int
            What the renderer keeps resident.

        Returns
        -------
        dict or NotImplemented
            ``madds``, ``fetches`` and ``bytes`` (floats) per frame; NotImplemented (the
            default) when the method has no model, so its ``ops`` cost is reported unavailable.
        """
        return NotImplemented


#: Values of :attr:`Method.light_dependence`, from least to most tied to a light.
LIGHT_DEPENDENCES = ("none", "fixed-light", "family")
#: Values of :attr:`Method.light_class`.
LIGHT_CLASSES = ("relight", "family", "fixed")
#: Values of :attr:`Method.storage`.
STORAGES = ("per-vertex", "per-texel", "per-probe", "per-pixel", "network")

#: name -> Method subclass, lazily imported.
METHODS: Registry[type[Method]] = Registry("method", entry_point_group="prtbench.methods",
                                           discover=method_specs)


def register_method(name: str):
    """Class decorator registering a :class:`Method` under ``name``."""

    def decorator(cls: type[Method]) -> type[Method]:
        cls.name = name
        return METHODS.register(name)(cls)

    return decorator


def artifact_key(method_cls: type[Method], scene: "Scene", config: Any) -> str:
    """Content hash of what a precompute depends on."""
    # Duck-typed method classes (tests' stand-ins) need not derive from Method.
    identity = getattr(method_cls, "cache_identity", None)
    values = identity(config) if identity is not None else config_mod.to_dict(config)
    # A per-pixel precompute, or one trained from cameras around the views: the views are input.
    if getattr(method_cls, "fixed_view", False) or getattr(method_cls, "views_in_key", False):

        views = [asdict(v) for v in scene.trajectory.views]
        return content_key(method_cls.name, method_cls.precompute_version, scene.content_hash(),
                           values, views)
    return content_key(method_cls.name, method_cls.precompute_version, scene.content_hash(),
                       values)


def load_or_precompute(method_cls: type[Method], scene: "Scene", config: Any, *,
                       progress: bool = True, use_cache: bool = True) -> Artifact:
    """The cached artifact for (method, scene, config), computing it if absent.

    The artifact's arrays and meta are stored together in one checksummed ``.npz`` written
    atomically, so an interrupted precompute leaves nothing usable behind. A small JSON
    record of the build time sits beside it (``<key>.json``): when the ``.npz`` is found
    corrupt and rebuilt — often in a fraction of the time, from cached sub-steps — the
    artifact reports the original time and ``rebuilt=True`` rather than the rebuild's time.
    """
    path = cache_root() / "artifacts" / method_cls.name / f"{artifact_key(method_cls, scene, config)}.npz"
    if not use_cache:
        return _build_artifact(method_cls, scene, config, progress=progress, path=None,
                               existed=False)
    existed = path.exists()
    artifact = _load_artifact(method_cls, path)  # removes a corrupt file
    if artifact is not None:
        return artifact
    with entry_lock(path):  # another process may be building it: wait, then look again
        artifact = _load_artifact(method_cls, path)
        if artifact is not None:
            return artifact
        return _build_artifact(method_cls, scene, config, progress=progress, path=path,
                               existed=existed)


def _load_artifact(method_cls: type[Method], path) -> Artifact | None:
    stored = load_arrays(path)
    if stored is None or "__meta__" not in stored:
        return None
    meta = json.loads(str(stored.pop("__meta__")))
    _repair_build_record(path.with_suffix(".json"), meta)
    return Artifact(method_cls.name, stored, meta["meta"], meta["precompute_s"], True)


def _build_artifact(method_cls: type[Method], scene: "Scene", config: Any, *, progress: bool,
                    path, existed: bool) -> Artifact:
    """Precompute; with a cache ``path``, store the artifact and its first build's time."""
    record_path = path.with_suffix(".json") if path is not None else None
    record = _read_build_record(record_path) if path is not None else None
    with credit_cached_compute() as reused:
        start = time.perf_counter()
        artifact = method_cls.precompute(scene, config, progress=progress)
        wall_s = time.perf_counter() - start
    # Cached sub-steps (transfer, texels, bounces, …) count at their recorded compute time:
    # precompute_s is the cost from scratch, not the assembly of cached parts.
    artifact.precompute_s = wall_s + reused.credited_s
    if reused.unknown:  # a reused part from an older cache has no recorded time
        artifact.original_time_known = False
    if path is not None:
        if existed or record is not None:  # built before: this is a rebuild
            artifact.rebuilt, artifact.rebuild_s = True, wall_s
            if record is not None:
                artifact.precompute_s, artifact.original_time_known = record, True
        # A rebuild's time is not the build's: the first build's time is known only from a
        # first build or from a sound record. The .npz keeps it too, so that a cache hit can
        # restore a record lost or damaged since (_repair_build_record).
        first_build_s = record if artifact.rebuilt else artifact.precompute_s
        meta = json.dumps({"meta": artifact.meta, "precompute_s": artifact.precompute_s,
                           "first_build_s": first_build_s})
        save_arrays(path, {**artifact.arrays, "__meta__": np.array(meta)})
        if first_build_s is not None:
            _write_build_record(record_path, first_build_s)
    return artifact


def _read_build_record(path) -> float | None:
    """The first build's time recorded beside an artifact (``<key>.json``); None if absent.

    A damaged record (truncated, edited: not a JSON object whose ``precompute_s`` is a finite,
    non-negative number) is never trusted: it is removed and read as absent, so the build in
    progress or the next cache hit writes a sound one where the first build's time is known.
    """
    try:
        value = json.loads(path.read_text())["precompute_s"]
        seconds = math.nan if isinstance(value, (bool, str)) else float(value)
    except FileNotFoundError:
        return None
    except (OSError, ValueError, TypeError, KeyError, IndexError, OverflowError):
        seconds = math.nan  # unreadable, not JSON, not an object, no number: damaged
    if math.isfinite(seconds) and seconds >= 0.0:
        return seconds
    try:
        path.unlink(missing_ok=True)
    except OSError:  # a read-only cache: read as absent all the same
        pass
    return None


def _write_build_record(path, seconds: float) -> None:
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps({"precompute_s": float(seconds)}))


def _repair_build_record(path, meta: Mapping[str, Any]) -> None:
    """On a cache hit, the record beside the artifact says the first build's time its meta
    keeps (``first_build_s``; absent from older artifacts and from rebuilds that never knew
    it). Best effort: a hit in a read-only cache still returns its artifact."""
    first_build_s = meta.get("first_build_s")
    if _read_build_record(path) != first_build_s and first_build_s is not None:
        try:
            _write_build_record(path, first_build_s)
        except OSError:
            pass
