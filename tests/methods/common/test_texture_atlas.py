"""Transfer textures, texel side: G-buffer coverage, dilation, seams, storage, normal maps."""

from __future__ import annotations

import math

import numpy as np
import pytest

import methods.texture  # noqa: F401 - registers texture-tp / texture-tpfl
from methods.common.atlas.atlas import AtlasMesh, render_gbuffer
from methods.common.atlas.shading import ShadingInputs, apply_normal_map, vertex_tangents
from methods.common.atlas.texels import (
    dilate,
    footprint_texels,
    layer_count,
    rgba_layers,
    texel_lookup,
    to_storage,
)
from prtbench.api.errors import InvalidInputError
from prtbench.api.method import METHODS, load_or_precompute
from prtbench.scene.geometry import grid_plane
from prtbench.scene.model import Material, Scene, SceneObject, Texture, Trajectory, View
from prtbench.scene.registry import get_scene
from prtbench.transport.lights import get_light


def _artifact(scene, method="texture-tpfl", **overrides):
    cls = METHODS.get(method)
    config = cls.make_config(overrides, profile="quick")
    return cls, config, load_or_precompute(cls, scene, config, progress=False)


def _render(scene, view, light, *, width=64, height=48, method="texture-tpfl", **overrides):
    cls, config, artifact = _artifact(scene, method, **overrides)
    renderer = cls.renderer(scene, artifact, config, width=width, height=height)
    try:
        return renderer.render(view, get_light(light))
    finally:
        renderer.release()


def _sphere_scene(kd=0.5):
    base = get_scene("sphere-over-plane", radius=0.5, height=1.0)
    sphere = max(base.objects, key=lambda o: o.mesh.n_vertices)
    view = View(eye=(0.0, 1.0, 3.0), target=(0.0, 1.0, 0.0), fov_y=40.0)
    return Scene("furnace-sphere", [SceneObject("sphere", sphere.mesh, Material(kd=(kd,) * 3))],
                 trajectory=Trajectory((view,)))


# --- texel arrays ------------------------------------------------------------------------------

def test_dilation_fills_rings_without_mixing_charts():
    values = np.zeros((1, 9, 9, 1))
    filled = np.zeros((1, 9, 9), bool)
    chart = np.full((1, 9, 9), -1)
    values[0, 4, 2], filled[0, 4, 2], chart[0, 4, 2] = 1.0, True, 0  # chart 0
    values[0, 4, 5], filled[0, 4, 5], chart[0, 4, 5] = 5.0, True, 1  # chart 1, 3 texels away
    out, grown, out_chart = dilate(values, filled, chart, rings=1)
    assert grown.sum() == 2 + 2 * 8  # each texel gained its 8 neighbours
    assert out[0, 4, 3, 0] == 1.0 and out[0, 4, 4, 0] == 5.0  # the gap texels took one chart each
    out, grown, out_chart = dilate(values, filled, chart, rings=2)
    # Ring 2 reaches texels next to both charts: they take the lower chart's values only.
    assert set(np.unique(out[0][grown[0], 0])) == {1.0, 5.0}
    assert np.all(out[0][out_chart[0] == 0, 0] == 1.0) and np.all(out[0][out_chart[0] == 1, 0] == 5.0)
    assert dilate(values, filled, chart, rings=0)[1].sum() == 2


def test_texel_lookup_is_gl_bilinear_with_clamp():
    tex = np.arange(16, dtype=np.float64).reshape(1, 4, 4, 1)  # value = 4·row + column
    uv = np.array([[0.125, 0.125], [0.25, 0.125], [0.0, 0.0], [0.375, 0.625]])
    got = texel_lookup(tex, np.zeros(4, int), uv)[:, 0]
    # Texel centres at (i+0.5)/4: (0.25, 0.125) is halfway between columns 0 and 1 of row 0.
    assert np.allclose(got, [0.0, 0.5, 0.0, 4 * 2 + 1])
    assert np.allclose(texel_lookup(tex, np.zeros(1, int), np.array([[0.99, 0.3]]),
                                    filtering="nearest")[:, 0], [4 * 1 + 3])
    # The footprint lists all four texels, also those of weight 0 (row 1 here): a stricter check.
    assert footprint_texels(np.zeros(1, int), np.array([[0.25, 0.125]]), 4).tolist() == [[0, 1, 4, 5]]


def test_storage_float16_range_is_checked_never_inf():
    assert to_storage(np.array([1.0, -65504.0]), "float16", what="t").dtype == np.float16
    with pytest.raises(InvalidInputError, match="float16"):
        to_storage(np.array([1.0, 7.0e4]), "float16", what="bounce textures")
    with pytest.raises(InvalidInputError, match="NaN/Inf"):
        to_storage(np.array([np.inf]), "float32", what="t")
    assert to_storage(np.array([7.0e4]), "float32", what="t").dtype == np.float32


def test_rgba_layers_pack_coefficients_in_order():
    tex = np.random.default_rng(0).random((2, 3, 3, 9)).astype(np.float32)
    layers = rgba_layers(tex)
    assert layer_count(9) == 3 and layers.shape == (6, 3, 3, 4)
    assert np.array_equal(layers[3 * 1 + 2, :, :, 0], tex[1, :, :, 8])  # set 1, coefficient 8
    assert np.all(layers[3 * 1 + 2, :, :, 1:] == 0)


# --- G-buffer and seams -----------------------------------------------------------------------

def test_gbuffer_texels_lie_on_the_surface_with_its_normals():
    scene = get_scene("plane", size=2.0, subdivisions=3)
    atlas = AtlasMesh.from_scene(scene, resolution=32, padding=1, texture_sets=False)
    g = render_gbuffer(scene, atlas, ShadingInputs.from_scene(scene))
    pos, nrm = g.positions[g.covered], g.normals[g.covered]
    assert np.allclose(pos[:, 1], 0.0, atol=1e-6) and np.all(np.abs(pos[:, [0, 2]]) <= 1.0 + 1e-6)
    assert np.allclose(nrm, [0.0, 1.0, 0.0], atol=1e-6)
    # Conservative: at least every texel the UV triangles' area covers (plus their borders).
    uv = atlas.uvs[atlas.faces].astype(np.float64) * 32
    ab, ac = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    area = 0.5 * np.abs(ab[:, 0] * ac[:, 1] - ab[:, 1] * ac[:, 0]).sum()
    assert g.covered.sum() >= area


def _lattice(triangles: np.ndarray, step: float = 0.25) -> tuple[np.ndarray, np.ndarray]:
    """Points at most ``step`` texels apart over each triangle (F, 3, 2), edges and corners included."""
    edge = np.max(np.linalg.norm(triangles - np.roll(triangles, 1, axis=1), axis=2), axis=1)
    per_face = np.maximum(1, np.ceil(edge / step)).astype(int)
    faces, points = [], []
    for n in np.unique(per_face):
        i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1))
        keep = i + j <= n
        w = np.stack([i[keep], j[keep], n - i[keep] - j[keep]], 1) / n
        sel = np.flatnonzero(per_face == n)
        points.append(np.einsum("pk,fkj->fpj", w, triangles[sel]).reshape(-1, 2))
        faces.append(np.repeat(sel, len(w)))
    return np.concatenate(faces), np.concatenate(points)


@pytest.mark.parametrize("overrides", [
    {"texture_resolution": 128, "padding": 1, "rays_per_point": 16, "sh_bands": 2},
    {"texture_resolution": 128, "padding": 1, "rays_per_point": 16, "sh_bands": 2,
     "texture_sets": True},
])
def test_every_texel_a_lookup_reads_is_covered_or_dilated_and_of_its_chart(overrides):
    # Lookups anywhere inside any triangle (a 1/4-texel lattice over every atlas triangle):
    # each bilinear footprint texel must hold data, and data of that triangle's own chart.
    scene = get_scene("plants")  # 786 charts at 256², thin padding at 128²
    _, _, artifact = _artifact(scene, **overrides)
    res, sets = artifact.meta["texture_resolution"], artifact.meta["texture_sets"]
    atlas = AtlasMesh.from_arrays(artifact.arrays, resolution=res, sets=sets)
    face, uv = _lattice(atlas.uvs[atlas.faces].astype(np.float64) * res)
    texels = footprint_texels(atlas.face_texture_set[face], uv / res, res)
    filled = artifact.arrays["filled"].reshape(-1)[texels].astype(bool)
    chart = artifact.arrays["texel_chart"].reshape(-1)[texels]
    assert len(uv) > 100_000
    assert filled.all(), f"{(~filled).sum()} footprint texels hold no data"
    assert np.all(chart == atlas.chart[atlas.faces[face, 0]][:, None])
    # Without dilation the same lookups do read empty texels: the check can fail.
    _, _, bare = _artifact(scene, **overrides, dilation=0)
    assert not bare.arrays["filled"].reshape(-1)[texels].astype(bool).all()


def test_seams_are_invisible_in_a_furnace_and_visible_without_dilation():
    # A closed convex sphere (6 atlas charts) under white light is exactly kd everywhere: any
    # seam texel without data would darken pixels along the chart borders.
    scene = _sphere_scene(0.5)
    view = scene.trajectory.views[0]
    for dilation in (1, 3):
        image = _render(scene, view, "white", width=192, height=144, texture_resolution=64,
                        rays_per_point=32, sh_bands=2, dilation=dilation)
        geometry = image[..., 0] > 0
        assert geometry.sum() > 3000 and np.all(np.isfinite(image))
        assert np.allclose(image[geometry], 0.5, atol=2e-3)
    image = _render(scene, view, "white", width=192, height=144, texture_resolution=64,
                    rays_per_point=32, sh_bands=2, dilation=0)
    assert (np.abs(image[image[..., 0] > 0] - 0.5) > 0.02).any()


# --- normal maps (PRTT §6.2) -------------------------------------------------------------------

def _tilted_plane(angle_degrees: float, *, variant_ks=0.0) -> Scene:
    a = math.radians(angle_degrees)
    tangent_normal = np.array([0.0, math.sin(a), math.cos(a)])  # tilted towards the bitangent
    normal_map = Texture(np.tile(tangent_normal * 0.5 + 0.5, (4, 4, 1)), name="tilt")
    material = Material(kd=(0.5, 0.5, 0.5), ks=(variant_ks,) * 3, shininess=16.0,
                        normal_map=normal_map)
    view = View(eye=(0.0, 2.0, 0.0), target=(0.0, 0.0, 0.0), up=(0.0, 0.0, -1.0), fov_y=30.0)
    return Scene("tilted-plane", [SceneObject("ground", grid_plane(4.0, 1), material)],
                 trajectory=Trajectory((view,)))


def test_tangent_frame_and_mapped_normal_of_a_grid_plane():
    mesh = grid_plane(2.0, 2)
    tangents = vertex_tangents(mesh)
    assert np.allclose(tangents, [1.0, 0.0, 0.0, 1.0], atol=1e-6)  # T = +x, B = cross(n, T) = −z
    a = math.radians(30.0)
    texel = np.array([[0.0, math.sin(a), math.cos(a)]]) * 0.5 + 0.5
    n = apply_normal_map(np.array([[0.0, 1.0, 0.0]]), tangents[:1].astype(np.float64), texel)
    assert np.allclose(n, [[0.0, math.cos(a), -math.sin(a)]], atol=1e-12)


def test_normal_mapped_transfer_matches_the_tilted_sky_view_factor():
    # A shading normal tilted by α on a plane sees the part of its cosine lobe above the plane:
    # ∫_{ω·y>0} max(n·ω, 0) dω = π(1 + cos α)/2, so under L = 1, B = kd (1 + cos α)/2.
    alpha = 50.0
    scene = _tilted_plane(alpha)
    image = _render(scene, scene.trajectory.views[0], "white", width=48, height=48,
                    texture_resolution=32, padding=1, rays_per_point=1024, sh_bands=2)
    centre = image[12:36, 12:36]
    expected = 0.5 * (1 + math.cos(math.radians(alpha))) / 2
    assert np.allclose(centre, expected, rtol=5e-3), (centre.min(), centre.max(), expected)
    flat = _render(_tilted_plane(0.0), scene.trajectory.views[0], "white", width=48, height=48,
                   texture_resolution=32, padding=1, rays_per_point=1024, sh_bands=2)
    assert np.allclose(flat[12:36, 12:36], 0.5, rtol=2e-3)


def test_normal_map_scenes_validate():
    scene = _tilted_plane(20.0)
    other = Texture(np.full((2, 2, 3), 0.5), name="other")
    second = SceneObject("second", grid_plane(1.0, 1), Material(normal_map=other))
    two_maps = Scene("two-maps", [*scene.objects, second], trajectory=scene.trajectory)
    cls = METHODS.get("texture-tpfl")
    config = cls.make_config({}, profile="quick")
    with pytest.raises(InvalidInputError, match="normal maps"):
        cls.validate(two_maps, config)
    textured = Scene("textured", [SceneObject("g", grid_plane(1.0, 1), Material(
        kd=Texture(np.full((2, 2, 3), 0.5))))])
    with pytest.raises(InvalidInputError, match="textured kd"):
        cls.validate(textured, config)


def test_room_normal_map_changes_only_the_floor_transfer_along_the_tiles():
    # PRTT §6.2 / Fig. 6: the G-buffer's shading normal carries the normal map into the transfer.
    # The Mitsuba reference has no normal maps, so this checks the transfer texture directly.
    config = {"texture_resolution": 128, "padding": 1, "rays_per_point": 16, "sh_bands": 2,
              "texture_sets": True}
    plain = get_scene("room")
    mapped = get_scene("room", normal_mapped_floor=True)
    _, _, a = _artifact(plain, **config)
    _, _, b = _artifact(mapped, **config)
    floor = plain.objects.index(next(o for o in plain.objects if o.name == "floor"))
    diff = np.abs(a.arrays["transfer"] - b.arrays["transfer"]).max(-1)  # (sets, R, R)
    covered = a.arrays["covered"].astype(bool)
    others = np.delete(np.arange(len(plain.objects)), floor)
    assert np.all(diff[others] == 0)
    changed = (diff[floor] > 1e-3)[covered[floor]].mean()
    # Bevels cover 1 − (1 − 2·0.08)² ≈ 29 % of each tile (texel sampling blurs the edges).
    assert 0.15 < changed < 0.5, changed
    # l = 1 coefficients follow the normal: on bevel texels its y part (n_y = cos tilt) drops.
    y_coefficient = 1  # flat index of (l=1, m=−1), ∝ y
    bevel = covered[floor] & (diff[floor] > 1e-3)
    drop = (a.arrays["transfer"][floor, ..., y_coefficient] - b.arrays["transfer"][floor, ..., y_coefficient])
    assert np.median(drop[bevel]) > 0.02
