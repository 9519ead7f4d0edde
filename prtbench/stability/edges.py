"""Cases at a method's own edges (issue #15), beside the knob, light and scene cases.

* ``mesh=1e6-triangles``: the base scene's sphere tessellated to 10⁶ triangles, for the methods
  that store transfer per vertex (``storage = "per-vertex"``); precompute time and peak memory
  are what it records. The smoke profile uses 10⁵ triangles and says so in the case's name.
* CPCA at its extremes (per-vertex methods with the ``compress``/``clusters``/``pca_vectors``
  knobs that accept ``compress=cpca``; the per-texel methods' texel signals are not derived yet): one cluster per vertex (K = N), no PCA vectors (n′ = 0: vector
  quantisation) and as many as the transfer has values (n′ = d). N and d are derived from the
  case's scene and the method's uncompressed artifact when the case runs
  (:func:`prtbench.stability.run.derive_overrides`).
* Probes inside geometry (methods with an ``invalid_backface_fraction`` knob): a closed block
  on the ground holding a third of the probe grid, with the method's moderate validity test
  and with every probe kept valid.
* SDF sphere tracing with |∇d| ≪ 1 (SDF base scenes): the distance field multiplied by 0.01.
  The surface (its zero set, its mesh and the reference) is unchanged; only the steps shrink.

Wavelet ``light_terms`` k = 1 and k = all, and ``keep`` = 1, are knob rules
(:data:`prtbench.stability.cases.KNOB_RULES`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

from prtbench.stability.case import BASE_SCENE, Case, accepts

#: Sphere segments s of the large-mesh case per profile: 2·s·(s/2 − 1) sphere triangles.
LARGE_MESH_SEGMENTS = {"smoke": 320, "quick": 1002}
#: The large mesh may take this many times the profile's timeout (it is slow, not hung).
LARGE_MESH_TIMEOUT_FACTOR = 3.0
#: The distance field's factor in the |∇d| ≪ 1 case.
SDF_DISTANCE_FACTOR = 0.01
COMPRESS_KNOBS = ("compress", "clusters", "pca_vectors")


def sphere_triangles(segments: int) -> int:
    """Triangles of ``sphere-over-plane``'s sphere at ``segments`` (its builder's formula)."""
    return 2 * segments * (segments // 2 - 1)


def large_mesh_cases(method_cls, *, profile: str) -> list[Case]:
    """The 10⁶-triangle mesh (10⁵ in smoke) for methods that store their transfer per vertex
    (``storage == "per-vertex"``): their cost grows with the mesh."""
    if method_cls.storage != "per-vertex":
        return []
    segments = LARGE_MESH_SEGMENTS[profile]
    triangles = sphere_triangles(segments) + 2
    label = "1e6" if profile == "quick" else "1e5"
    name = f"mesh={label}-triangles" + ("-smoke-size" if profile == "smoke" else "")
    return [Case(name, "scene", scene=BASE_SCENE["scene"],
                 scene_params={**BASE_SCENE["scene_params"], "sphere_segments": segments},
                 timeout_factor=LARGE_MESH_TIMEOUT_FACTOR,
                 note=f"{triangles} triangles ({BASE_SCENE['scene']}, sphere_segments="
                      f"{segments}{', the smoke size: quick measures 1e6' if profile == 'smoke' else ''}"
                      "): per-vertex precompute time and memory",
                 advice="decimate the mesh for per-vertex transfer (time and memory grow with "
                        "the vertices), or use a per-texel method")]


def compress_cases(method_cls, *, base: Mapping[str, Any]) -> list[Case]:
    """CPCA with K = N, n′ = 0 and n′ = d, for methods that accept ``compress=cpca``."""
    names = {f.name for f in dataclasses.fields(method_cls.Config)}
    # N and d are derived per vertex (run.derive_overrides); the texture methods' signals are
    # texels, whose count the atlas decides, so their extremes wait for a per-texel derivation.
    if method_cls.storage != "per-vertex":
        return []
    if not set(COMPRESS_KNOBS) <= names or not accepts(
            method_cls, base["scene"], base["variant"], base["scene_params"],
            overrides={"compress": "cpca"}):
        return []
    cpca = {"compress": "cpca"}
    return [
        Case("compress=cpca clusters=signals", "storage", overrides=cpca,
             derived={"clusters": "signals"}, compare_image=True,
             note="CPCA with one cluster per vertex (K = N: every cluster holds one signal, "
                  "its PCA has nothing to describe)",
             advice="use K much smaller than the vertex count (16-256 clusters)"),
        Case("compress=cpca pca_vectors=0", "storage", overrides={**cpca, "pca_vectors": 0},
             compare_image=True,
             note="CPCA with no PCA vectors (cluster means only: vector quantisation)",
             advice="use 4-8 PCA vectors per cluster"),
        Case("compress=cpca pca_vectors=d", "storage", overrides=cpca,
             derived={"pca_vectors": "dimension"}, compare_image=True,
             note="CPCA with as many PCA vectors as the transfer has values per vertex (n′ = d: "
                  "exact, and larger than the uncompressed transfer)",
             advice="use n′ much smaller than d: n′ = d stores more than no compression"),
    ]


def probe_cases(method_cls) -> list[Case]:
    """Probes inside a closed block, for methods with an ``invalid_backface_fraction`` knob."""
    field = next((f for f in dataclasses.fields(method_cls.Config)
                  if f.name == "invalid_backface_fraction"), None)
    if field is None:
        return []
    note = ("a closed block on the ground filling a third of the scene's height: probes inside "
            "geometry see only back faces")
    advice = ("keep invalid_backface_fraction near 0.25 and enough resolution that valid "
              "probes neighbour every surface")
    keep_all = field.metadata.get("high", 1.0)
    return [Case("geometry=solid-block", "scene", geometry="solid-block", note=note,
                 advice=advice),
            Case(f"geometry=solid-block invalid_backface_fraction={keep_all:g}", "scene",
                 geometry="solid-block", overrides={"invalid_backface_fraction": keep_all},
                 note=note + ", every probe kept valid (their black radiance is interpolated)",
                 advice=advice)]


def sdf_cases() -> list[Case]:
    """The distance field scaled by :data:`SDF_DISTANCE_FACTOR` (SDF base scenes)."""
    f = SDF_DISTANCE_FACTOR
    return [Case(f"sdf-gradient={f:g}", "scene", distance_factor=f, compare_image=True,
                 timeout_factor=LARGE_MESH_TIMEOUT_FACTOR,  # its training data is retraced
                 note=f"the distance field multiplied by {f:g} (|∇d| = {f:g}, sphere tracing "
                      f"needs {1 / f:g}x the steps; the surface is unchanged)",
                 advice="keep the field Euclidean (|∇d| near 1), or raise max_steps and divide "
                        "the field by its Lipschitz bound")]


def method_edge_cases(method_cls, *, base: Mapping[str, Any], scene, profile: str) -> list[Case]:
    """Every edge case of this module that applies to ``method_cls`` on ``scene``."""
    if scene.sdf is not None:
        return sdf_cases()
    return [*compress_cases(method_cls, base=base), *probe_cases(method_cls),
            *large_mesh_cases(method_cls, profile=profile)]
