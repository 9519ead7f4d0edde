"""Thesis table 3.2 (PRTT Table 2): memory of vertex transfer versus transfer textures.

Four ways to store glossy transfer, per scene:

* Sloan et al. 2002 at vertices (``sloan-matrix``): an n² × n² matrix per vertex, V·n⁴·4 bytes;
* Ng et al. 2004 triple products at vertices (``vertex-tp``): an n²-vector per vertex,
  V·n²·4 bytes, plus the sparse Γ list its shader reads (8 bytes per non-zero);
* McKenzie (Sloan's matrices in a texture): R²·n⁴·4 bytes per texture — closed form only, no
  method of ours stores it (PRTT §6.3 argues it is infeasible, and at R = 1024 it is 2.4 GiB);
* ours, transfer textures (``texture-tpfl``): S textures of R² texels holding the n² transfer
  coefficients in ⌈n²/4⌉ RGBA layers (float32 or float16), plus the TPFL matrix (n² × n² RGB
  entries, each padded to a vec4 in its uniform block).

Measured values are the renderers' ``memory_bytes()`` (the resident GL buffers and textures)
as stored by the runner: each method runs through the ordinary runner on one view (its image
and error against the path reference are stored too, but this table shows only memory). Every
measured value is checked against its closed form; configurations that cannot run here
(``sloan-matrix`` above its ``max_bytes`` knob or this GL's shader-storage block limit) are
given in closed form only, with the reason. The closed forms need the vertex count, which the
formatter recomputes from the stored scene name, variant and parameters (a deterministic
function of the stored row, not a measurement).
"""

from __future__ import annotations

import inspect
import json

import numpy as np

from prtbench.api import config as config_mod
from prtbench.api.errors import AssetMissingError, InvalidInputError
from prtbench.api.method import METHODS
from prtbench.bench.job import Job
from prtbench.bench.reproduction import Reproduction
from prtbench.render import gl
from prtbench.render.prt_shading import gamma_buffer_data, tpfl_buffer_data
from prtbench.scene.registry import SCENES, get_scene
from reproductions.table_3_1 import (
    PAPER_SCENES,
    VARIANT,
    choice_notes,
    ensure_texture_methods,
    scene_choices,
    substitution_lines,
)

#: Row order of the storage schemes: (key, label, method or None for closed form only).
SCHEMES = (("sloan", "Sloan et al. (vertex matrices)", "sloan-matrix"),
           ("ng", "Ng et al. (vertex vectors, TP)", "vertex-tp"),
           ("mckenzie", "McKenzie (Sloan matrices in a texture)", None),
           ("ours", "ours (transfer textures, TPFL)", "texture-tpfl"))

#: PRTT Table 2 / thesis table 3.2 as printed (1024² textures, 5 SH bands).
PAPER_MEMORY = {
    "Room": {"sloan": "64MB", "ng": "2.5MB", "mckenzie": "2.5GB", "ours": "100MB"},
    "Dragon": {"sloan": "5.2GB", "ng": "215.8MB", "mckenzie": "2.5GB", "ours": "100MB"},
    "TRM": {"sloan": "2.3GB", "ng": "139.3MB", "mckenzie": "2.5GB", "ours": "100MB"},
    "Plants": {"sloan": "64MB", "ng": "2.5MB", "mckenzie": "2.5GB", "ours": "100MB"},
}

FLOAT_BYTES = {"float32": 4, "float16": 2}
#: Texels of the paper's texture budget (one 1024² texture, or TRM's four 512² texture sets).
PAPER_TEXELS = 1024 * 1024


# --- closed forms -------------------------------------------------------------------------------

def gamma_bytes(bands: int) -> int:
    """Bytes of the sparse Γ list the TP shaders read (8 per non-zero: index word + float),
    as :mod:`prtbench.render.prt_shading` uploads it."""

    return len(gamma_buffer_data(bands))


def tpfl_bytes(bands: int) -> int:
    """Bytes of the fixed-light matrix M (n² × n² RGB entries) as :mod:`prtbench.render.prt_shading`
    uploads it (its std140 layout pads each entry to a vec4: n⁴·16 bytes)."""

    return len(tpfl_buffer_data(np.zeros((bands * bands, 3)), bands))


def sloan_vertex_bytes(vertices: int, bands: int) -> int:
    """V · n⁴ · 4: one float32 n² × n² matrix per vertex."""
    return int(vertices) * bands**4 * 4


def ng_vertex_bytes(vertices: int, bands: int, *, with_gamma: bool = True) -> int:
    """V · n² · 4 (+ the Γ list): one float32 n²-vector per vertex."""
    return int(vertices) * bands**2 * 4 + (gamma_bytes(bands) if with_gamma else 0)


def mckenzie_texture_bytes(resolution: int, bands: int, *, sets: int = 1) -> int:
    """S · R² · n⁴ · 4: Sloan's n² × n² float32 matrix in every texel."""
    return int(sets) * int(resolution) ** 2 * bands**4 * 4


def transfer_texture_bytes(resolution: int, bands: int, *, sets: int = 1,
                           storage: str = "float32", bounces: int = 0,
                           with_tpfl: bool = True) -> int:
    """Bytes of our transfer textures as uploaded, plus the TPFL matrix.

    S·R²·⌈n²/4⌉·4 texel values (RGBA layers: n² = 25 occupies 7 layers, 28 channels) at the
    storage precision, k·S·R²·⌈3n²/4⌉·4 more for k bounce textures (RGB transferred radiance),
    and the TPFL matrix (:func:`tpfl_bytes`).
    """
    per_value = FLOAT_BYTES[storage]
    layers = -(-bands * bands // 4)
    bounce_layers = -(-3 * bands * bands // 4)
    texels = int(sets) * int(resolution) ** 2
    size = texels * 4 * per_value * (layers + int(bounces) * bounce_layers)
    return size + (tpfl_bytes(bands) if with_tpfl else 0)


#: Measurement table holding the GL limit the sweep ran under (one row per report run).
GL_TABLE = "table-3.2-gl"
#: Measurement table of each run's scene size (``cell_run_id``, vertices, objects).
SCENE_TABLE = "table-3.2-scenes"


def gl_storage_block_limit() -> int:
    """GL_MAX_SHADER_STORAGE_BLOCK_SIZE of this machine's GL context (0 if unknown)."""

    return gl.storage_block_limit()


def stored_block_limit(frame) -> int:
    """The GL shader-storage block limit stored with the sweep (:data:`GL_TABLE`), 0 if unknown."""
    rows = frame.attrs.get(GL_TABLE)
    if rows is None or not len(rows):
        return 0
    value = rows["gl_max_shader_storage_block_size"].iloc[0]
    return int(value) if value == value else 0


def sloan_refusal(scene, config, *, limit: int | None = None) -> str | None:
    """Why ``sloan-matrix`` cannot run on ``scene`` here (None if it can).

    Checks the GL shader-storage block limit (``limit``; default this machine's), then the
    method's own validate (its ``max_bytes`` knob).
    """

    # The limit first: the method's validate checks the live GL too, and a report rebuilt
    # from the store must quote the limit its sweep ran under.
    size = sloan_vertex_bytes(scene.n_vertices, config.sh_bands)
    limit = gl_storage_block_limit() if limit is None else limit
    if limit and size > limit:
        return (f"{size / 2**20:.0f} MiB of matrices exceed this GL's shader storage block limit "
                f"(GL_MAX_SHADER_STORAGE_BLOCK_SIZE = {limit / 2**20:.0f} MiB)")
    try:
        METHODS.get("sloan-matrix").validate(scene, config)
    except InvalidInputError as exc:
        return f"refused by the method: {exc}"
    return None


def _default_config(method: str, profile: str, paper_scene: str) -> dict:
    """The config ``method`` would have had in this sweep, as a dict (for rows not run)."""

    choice = {c.paper: c for c in scene_choices(profile)}.get(paper_scene)
    overrides = choice.overrides(method) if choice is not None else {}
    return config_mod.to_dict(METHODS.get(method).make_config(overrides, profile=profile))


def _scene_of(row):
    """Rebuild a stored row's scene from its name, variant and recorded parameters.

    A scene may record parameters its builder does not take (``dragon-lo`` records its fixed
    ``resolution``); only the builder's keyword parameters are passed back.
    """

    accepted = inspect.signature(SCENES.get(row["scene"])).parameters
    params = {k: v for k, v in json.loads(row["scene_params"]).items() if k in accepted}
    return get_scene(row["scene"], variant=row["scene_variant"], **params)


def paper_scene_notes(profile: str, measured: set[str], *, limit: int) -> list[str]:
    """Closed forms of the vertex schemes on the paper profile's scenes, where this profile
    measured a lighter stand-in (e.g. ``dragon-lo`` for ``dragon`` in ``quick``); ``limit`` is
    the stored GL shader-storage block limit."""

    paper = {c.paper: c for c in scene_choices("paper")}
    notes = []
    for choice in scene_choices(profile):
        full = paper.get(choice.paper)
        if full is None or choice.scene not in measured or (
                (choice.scene, dict(choice.scene_params)) == (full.scene, dict(full.scene_params))):
            continue
        try:
            scene = get_scene(full.scene, variant=VARIANT, **full.scene_params)
        except AssetMissingError:
            continue
        v = scene.n_vertices
        sloan = sloan_vertex_bytes(v, 5)
        notes.append(
            f"{choice.paper} at the paper profile's scale (`{full.scene}`, {v} vertices, "
            f"{scene.n_triangles} triangles; closed form, not measured in this profile): Sloan "
            f"{_mib(sloan):.0f} MiB" + (" (over this GL's storage block limit)" if limit and
                                        sloan > limit else "")
            + f", Ng et al. {_mib(ng_vertex_bytes(v, 5, with_gamma=False)):.1f} MiB of "
            "transfer vectors (5 bands).")
    return notes


def _mib(size: float) -> float:
    return float(size) / 2**20


class Table32(Reproduction):
    name = "3.2"
    paper = ("Sirikonda, Aakash KT and Narayanan, PRTT: Precomputed Radiance Transfer Textures "
             "(2022), Table 2 = Sirikonda (2023) thesis, table 3.2: memory of vertex-based and "
             "texture-based transfer storage (1024² textures, 5 SH bands)")
    title = ("Table 3.2: memory of glossy transfer at vertices (Sloan, Ng et al.) and in "
             "textures (McKenzie, ours), measured and in closed form")

    def cells(self, profile: str) -> list[Job]:
        ensure_texture_methods()
        cells = []
        for choice in scene_choices(profile):
            for key, _, method in SCHEMES:
                if method is None:
                    continue
                if method == "sloan-matrix":
                    config = METHODS.get(method).make_config(profile=profile)
                    scene = get_scene(choice.scene, variant=VARIANT, **choice.scene_params)
                    if sloan_refusal(scene, config):
                        continue  # reported in closed form by format()
                cells.append(Job(method=method, scene=choice.scene, variant=VARIANT, views=1,
                                  scene_params=dict(choice.scene_params),
                                  overrides=choice.overrides(method),
                                  label={"paper_scene": choice.paper, "scheme": key}))
        return cells

    measurement_tables = (GL_TABLE, SCENE_TABLE)

    def measure_rows(self, frame, *, profile: str) -> dict[str, list[dict]]:
        """This GL's shader-storage block limit, which the notes and refusals quote, and the
        object count of each run's scene, which the closed forms use (the vertex count is a
        column of every result row)."""

        scenes = []
        for run_id, run in frame.groupby("run_id", sort=False):
            scene = _scene_of(run.iloc[0])
            scenes.append({"cell_run_id": run_id, "scene_objects": len(scene.objects)})
        return {GL_TABLE: [{"gl_max_shader_storage_block_size": gl_storage_block_limit(),
                            "gl_renderer": gl.renderer_string()}],
                SCENE_TABLE: scenes}

    def markdown(self, header, rows, *, profile: str, frame) -> str:
        measured = set(frame["scene"]) if len(frame) else set()
        self.substitutions = tuple(substitution_lines(profile, measured))
        self.notes = (
            "Columns headed \"paper\" are the paper's numbers (their scenes, 1024² textures); "
            "every \"measured\" value is a renderer's memory_bytes() read from the results "
            "store, runs of one view each.",
            "\"measured / closed form\" = 1 means the resident GL buffers are exactly the "
            "closed form named in the \"closed form\" column (V = the scene's vertices, n = SH "
            "bands, R = texture side, S = textures in the set, K_Γ = non-zeros of the "
            "triple-product tensor).",
            "Our texture row counts the RGBA layers GL really allocates: 25 coefficients take "
            "7 RGBA layers (28 channels), so a 1024² float32 texture is 112 MiB, where the "
            "paper counts 25 floats (100 MB). The vertex rows add the Γ list (TP) the shader "
            "needs; the paper's vertex numbers count the transfer only.",
            "McKenzie's texture of Sloan matrices is never materialised (2.4 GiB at 1024², "
            "5 bands): closed form only, at our texture's resolution.",
            "Rows without a measurement could not run on this machine; the reason is in the "
            f"\"status\" column (this GL's shader storage blocks hold at most "
            f"{stored_block_limit(frame) / 2**20:.0f} MiB, measured with the sweep).",
            *choice_notes(profile, measured),
            *paper_scene_notes(profile, measured, limit=stored_block_limit(frame)),
        )
        return super().markdown(header, rows, profile=profile, frame=frame)

    def format(self, frame, *, profile: str):
        ensure_texture_methods()
        header = ["scene", "our scene", "our vertices", "our tris", "scheme", "method",
                  "measured bytes", "measured MiB", "closed form bytes", "closed form MiB",
                  "measured / closed form", "closed form", "status",
                  "paper tris", "paper"]
        if len(frame) == 0:
            return header, []
        paper_tris = dict(PAPER_SCENES)
        order = [p for p, _ in PAPER_SCENES]
        rows = []
        for paper_scene in sorted(set(frame["label_paper_scene"]),
                                  key=lambda p: order.index(p) if p in order else 99):
            part = frame[frame["label_paper_scene"] == paper_scene]
            first = part.iloc[0]
            scene = _scene_of(first)  # for the Sloan refusal (the method's validate)
            vertices = int(first["scene_vertices"])
            by_scheme = {k: p for k, p in part.groupby("label_scheme")}
            texture = by_scheme.get("ours")
            tex_cfg = (json.loads(texture["config"].iloc[0]) if texture is not None
                       else _default_config("texture-tpfl", profile, paper_scene))
            resolution = int(tex_cfg["texture_resolution"])
            sets = int(first["scene_objects"]) if tex_cfg.get("texture_sets") else 1
            for key, label, method in SCHEMES:
                run = by_scheme.get(key)
                cfg = (json.loads(run["config"].iloc[0]) if run is not None
                       else _default_config(method or "texture-tpfl", profile, paper_scene))
                measured, status = float("nan"), "measured"
                if run is not None:
                    measured = float(run["memory_bytes"].iloc[0])
                if key == "sloan":
                    bands = int(cfg["sh_bands"])
                    closed = sloan_vertex_bytes(vertices, bands)
                    formula = f"V·n⁴·4 (V={vertices}, n={bands})"
                    if run is None:
                        config = METHODS.get(method).make_config(profile=profile)
                        status = "closed form only: " + (sloan_refusal(
                            scene, config, limit=stored_block_limit(frame)) or "not run")
                elif key == "ng":
                    bands = int(cfg["sh_bands"])
                    closed = ng_vertex_bytes(vertices, bands)
                    formula = (f"V·n²·4 + 8·K_Γ (V={vertices}, n={bands}, "
                               f"Γ list {gamma_bytes(bands)} B)")
                elif key == "mckenzie":
                    bands = int(tex_cfg["sh_bands"])
                    closed = mckenzie_texture_bytes(resolution, bands, sets=sets)
                    formula = f"S·R²·n⁴·4 (S={sets}, R={resolution}, n={bands})" + (
                        "" if sets * resolution**2 == PAPER_TEXELS else
                        f"; {_mib(mckenzie_texture_bytes(1024, bands)):.0f} MiB at the paper's "
                        "1024² texels")
                    status = "closed form only: no method stores it (not materialised)"
                else:
                    bands, storage = int(cfg["sh_bands"]), str(cfg["storage"])
                    bounces = int(cfg.get("bounces", 0))
                    closed = transfer_texture_bytes(resolution, bands, sets=sets, storage=storage,
                                                    bounces=bounces)
                    formula = (f"S·R²·⌈n²/4⌉·4·{FLOAT_BYTES[storage]} + M (S={sets}, "
                               f"R={resolution}, n={bands}, {storage}, TPFL matrix M "
                               f"{tpfl_bytes(bands)} B"
                               + (f", +{bounces} bounce textures" if bounces else "") + ")"
                               + ("" if sets * resolution**2 == PAPER_TEXELS else
                                  "; {:.1f} MiB at the paper's 1024² texels".format(_mib(
                                      transfer_texture_bytes(1024, bands, storage=storage,
                                                             bounces=bounces)))))
                if run is None and key in ("ng", "ours"):
                    status = "closed form only: not run"
                rows.append([
                    paper_scene, str(first["scene"]), int(vertices), int(first["scene_triangles"]),
                    label, method or "—", int(measured) if np.isfinite(measured) else "—",
                    _mib(measured), int(closed), _mib(closed),
                    measured / closed if np.isfinite(measured) else float("nan"), formula,
                    status, paper_tris.get(paper_scene, "—"),
                    PAPER_MEMORY.get(paper_scene, {}).get(key, "—"),
                ])
        return header, rows


TABLE = Table32()
