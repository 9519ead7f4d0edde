"""Scenes from asset files (DESIGN.md §16): the files are built here with trimesh, at test time."""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pytest

trimesh = pytest.importorskip("trimesh")
from PIL import Image  # noqa: E402

from prtbench.api.errors import InvalidInputError  # noqa: E402
from prtbench.cli import main  # noqa: E402
from prtbench.scene.files import phong_exponent, read_scene_file  # noqa: E402
from prtbench.scene.model import Texture  # noqa: E402
from prtbench.scene.registry import (
    SCENES,
    get_scene,  # noqa: E402
)

# Two unit cubes, one per material; face 13 repeats an index (degenerate), face 14 repeats
# face 1 (duplicate).
MTL = """newmtl shiny
Kd 0.6 0.2 0.1
Ks 0.3 0.25 0.2
Ns 80
newmtl matte
Kd 0.1 0.5 0.2
Ks 0 0 0
Ns 10
"""


def _cube_obj(offset: float, first: int) -> str:
    box = trimesh.creation.box()
    lines = [f"v {x + offset} {y} {z}" for x, y, z in box.vertices]
    lines += [f"f {a + first} {b + first} {c + first}" for a, b, c in box.faces]
    return "\n".join(lines)


def _write_obj(folder: Path, *, extra: str = "") -> Path:
    (folder / "parts.mtl").write_text(MTL)
    text = ("mtllib parts.mtl\no shiny_cube\nusemtl shiny\n" + _cube_obj(-1.0, 1)
            + "\no matte_cube\nusemtl matte\n" + _cube_obj(1.0, 9) + "\n" + extra)
    path = folder / "parts.obj"
    path.write_text(text)
    return path


def _own_cache(monkeypatch, tmp_path) -> None:
    """A cache of the test's own: it checks the cache is untouched, and under pytest-xdist the
    run's shared cache changes under the other worker."""
    monkeypatch.setenv("PRTBENCH_CACHE", str(tmp_path / "own-cache"))


def _cache_files() -> set[str]:
    root = Path(os.environ["PRTBENCH_CACHE"])
    return {str(p) for p in root.rglob("*")} if root.exists() else set()


def _by_kd(scene):
    return {o.material.name: o.material for o in scene.objects}


def _world(scene, points) -> np.ndarray:
    """``points`` of ``scene``'s canonical frame in the file's world (float64)."""
    return scene.world_from_canonical.apply(points)


def test_obj_mtl_materials_map_kd_ks_ns(tmp_path):
    path = _write_obj(tmp_path)
    glossy, report = read_scene_file(str(path), variant="glossy")
    mats = _by_kd(glossy)
    assert set(mats) == {"shiny", "matte"}
    np.testing.assert_allclose(mats["shiny"].kd, (0.6, 0.2, 0.1), atol=1e-6)
    np.testing.assert_allclose(mats["shiny"].ks, (0.3, 0.25, 0.2), atol=1e-6)
    assert mats["shiny"].shininess == pytest.approx(80.0)
    np.testing.assert_allclose(mats["matte"].kd, (0.1, 0.5, 0.2), atol=1e-6)
    assert not mats["matte"].is_glossy
    # The diffuse variant keeps kd and drops every specular lobe, as built-in scenes do.
    diffuse = get_scene(str(path), variant="diffuse")
    assert all(not o.material.is_glossy for o in diffuse.objects)
    np.testing.assert_allclose(_by_kd(diffuse)["shiny"].kd, (0.6, 0.2, 0.1), atol=1e-6)
    assert glossy.n_triangles == 24 and report.degenerate_faces == report.duplicate_faces == 0
    assert [str(tmp_path / "parts.mtl")] == report.sidecars
    # Identity: the name carries the stem and a hash of the file, its .mtl and the params.
    assert glossy.name.startswith("parts-") and glossy.name == diffuse.name
    (tmp_path / "parts.mtl").write_text(MTL.replace("Ns 80", "Ns 81"))
    changed = get_scene(str(path), variant="glossy")
    assert changed.name != glossy.name and changed.content_hash() != glossy.content_hash()
    assert get_scene(str(path), scale="2").name != diffuse.name


def test_obj_map_kd_is_a_linear_kd_texture_times_kd(tmp_path):
    pixels = np.array([[[255, 128, 0], [10, 200, 30]]], np.uint8)  # 1×2
    Image.fromarray(pixels).save(tmp_path / "albedo.png")
    (tmp_path / "quad.mtl").write_text("newmtl painted\nKd 0.5 1 1\nmap_Kd albedo.png\n")
    (tmp_path / "quad.obj").write_text(
        "mtllib quad.mtl\nv 0 0 0\nv 1 0 0\nv 1 0 -1\nv 0 0 -1\n"
        "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl painted\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n")
    scene, report = read_scene_file(str(tmp_path / "quad.obj"))
    kd = scene.objects[0].material.kd
    assert isinstance(kd, Texture) and kd.image.shape == (1, 2, 3)
    c = pixels.astype(np.float64) / 255
    linear = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    np.testing.assert_allclose(kd.image, linear * [0.5, 1, 1], atol=2e-6)
    assert scene.objects[0].mesh.uvs is not None
    assert sorted(Path(p).name for p in report.sidecars) == ["albedo.png", "quad.mtl"]
    # The texture is part of the identity: new pixels, new scene name.
    Image.fromarray(pixels[:, ::-1].copy()).save(tmp_path / "albedo.png")
    assert get_scene(str(tmp_path / "quad.obj")).name != scene.name


def test_repairs_are_counted(tmp_path):
    a, b, c = trimesh.creation.box().faces[0] + 9  # OBJ indices of the matte cube's vertices
    # A degenerate face (repeated index), then a copy of the matte cube's first face.
    path = _write_obj(tmp_path, extra=f"f 9 9 10\nf {a} {b} {c}\n")
    scene, report = read_scene_file(str(path))
    assert (report.degenerate_faces, report.duplicate_faces) == (1, 1)
    assert scene.n_triangles == 24
    assert report.non_manifold_edges == 0
    # A fin (a face with its reversed copy) has no outward side: both copies are dropped.
    path = _write_obj(tmp_path, extra=f"f {a} {c} {b}\n")
    scene, report = read_scene_file(str(path))
    assert report.duplicate_faces == 2 and scene.n_triangles == 23
    # A third face on one edge of the closed cube makes that one edge non-manifold (kept).
    path = _write_obj(tmp_path, extra=f"v 5 5 5\nf {a} {b} 17\n")
    scene, report = read_scene_file(str(path))
    assert report.non_manifold_edges == 1 and scene.n_triangles == 25


def _pbr_box(*, texture: Image.Image | None = None, normals: Image.Image | None = None):
    material = trimesh.visual.material.PBRMaterial(
        baseColorFactor=[204, 102, 51, 255], metallicFactor=0.25, roughnessFactor=0.5,
        baseColorTexture=texture, normalTexture=normals, name="clay")
    box = trimesh.creation.box()
    uv = np.random.default_rng(0).uniform(0, 1, (len(box.vertices), 2))
    box.visual = trimesh.visual.TextureVisuals(uv=uv, material=material)
    return box


def _two_node_gltf(path: Path, *, texture: Image.Image | None = None,
                   normals: Image.Image | None = None) -> Path:
    scene = trimesh.Scene()
    box = _pbr_box(texture=texture, normals=normals)
    for node, x in (("left", -2.0), ("right", 3.0)):
        scene.add_geometry(box, node_name=node, geom_name="box",
                           transform=trimesh.transformations.translation_matrix([x, 0.5, 0]))
    if path.suffix == ".glb":
        scene.export(str(path))
    else:
        for name, data in scene.export(file_type="gltf").items():
            (path.parent / (path.name if name.endswith(".gltf") else name)).write_bytes(data)
    return path


def test_gltf_metallic_roughness_mapping_and_node_transforms(tmp_path):
    path = _two_node_gltf(tmp_path / "two.glb")
    scene = get_scene(str(path), variant="glossy")
    base, metallic = np.array([0.8, 0.4, 0.2]), 0.25
    by_name = {o.name: o for o in scene.objects}
    assert set(by_name) == {"left", "right"}
    for o in scene.objects:
        np.testing.assert_allclose(o.material.kd, base * (1 - metallic), atol=1e-6)
        np.testing.assert_allclose(o.material.ks, 0.04 * (1 - metallic) + base * metallic,
                                   atol=1e-6)
        assert o.material.shininess == pytest.approx(2 / 0.25 ** 2 - 2)  # α = 0.5² → s = 30
    # Nodes moved their shared unit cube by (-2, .5, 0) and (3, .5, 0) (in the file's world;
    # the scene itself is stored centred, diagonal 2).
    left, right = (_world(scene, by_name[n].mesh.positions).mean(0) for n in ("left", "right"))
    np.testing.assert_allclose(left, [-2, 0.5, 0], atol=1e-6)
    np.testing.assert_allclose(right, [3, 0.5, 0], atol=1e-6)
    lo, hi = scene.world_bounds()
    np.testing.assert_allclose(lo, [-2.5, 0, -0.5], atol=1e-6)
    np.testing.assert_allclose(hi, [3.5, 1, 0.5], atol=1e-6)
    assert scene.diagonal() == pytest.approx(2.0, rel=1e-6)
    np.testing.assert_allclose(np.add(*scene.bounds()), 0.0, atol=1e-6)
    assert len(scene.trajectory) == 30 and scene.default_light == "sky"
    # Every orbit camera sees the bounds' centre and stands outside the bounding sphere.
    centre, radius = (lo + hi) / 2, np.linalg.norm(hi - lo) / 2
    for view in map(scene.world_from_canonical.view, scene.trajectory.views):
        np.testing.assert_allclose(view.target, centre, atol=1e-9)
        assert np.linalg.norm(np.subtract(view.eye, centre)) > radius
    # ground=true: two triangles facing +Y at the lowest point, wider than the bounds.
    grounded = get_scene(str(path), ground="true")
    ground = [o for o in grounded.objects if o.name == "ground"][0]
    assert ground.mesh.n_triangles == 2
    ground_world = _world(grounded, ground.mesh.positions)
    np.testing.assert_allclose(ground_world[:, 1], 0.0, atol=1e-6)
    np.testing.assert_allclose(ground.mesh.normals, [[0, 1, 0]] * 4, atol=1e-7)
    assert np.ptp(ground_world[:, 0]) > hi[0] - lo[0]


def test_gltf_base_color_texture_is_linearised_kd(tmp_path):
    pixels = np.array([[[255, 0, 0], [0, 128, 0]], [[0, 0, 64], [255, 255, 255]]], np.uint8)
    bumps = np.array([[[128, 128, 255], [200, 128, 220]]], np.uint8)
    path = _two_node_gltf(tmp_path / "tex.gltf", texture=Image.fromarray(pixels),
                          normals=Image.fromarray(bumps))
    assert any(p.suffix == ".bin" for p in tmp_path.iterdir())  # external buffer really used
    scene, report = read_scene_file(str(path), variant="glossy")
    kd = scene.objects[0].material.kd
    assert isinstance(kd, Texture) and kd.image.shape == (2, 2, 3)
    c = pixels[::-1].astype(np.float64) / 255  # row 0 of a Texture is v = 0, the image bottom
    linear = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    np.testing.assert_allclose(kd.image, linear * np.array([0.8, 0.4, 0.2]) * 0.75, atol=2e-6)
    assert len(report.sidecars) >= 1
    # normalTexture → the normal map, kept linear (no sRGB decoding of vectors).
    normal_map = scene.objects[0].material.normal_map
    assert isinstance(normal_map, Texture)
    np.testing.assert_allclose(normal_map.image, bumps[::-1] / 255.0, atol=1e-6)


def test_gltf_perspective_camera_becomes_the_view(tmp_path):
    scene = trimesh.Scene()
    scene.add_geometry(trimesh.creation.box(), node_name="box", geom_name="box")
    scene.camera = trimesh.scene.Camera(resolution=(640, 480), fov=(64.0, 50.0))
    # Camera at (0, 1, 5), turned 90° about +Y: it looks down world −X.
    scene.camera_transform = (trimesh.transformations.translation_matrix([0, 1, 5])
                              @ trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]))
    path = tmp_path / "cam.glb"
    scene.export(str(path))
    built, report = read_scene_file(str(path), scale="2")
    assert report.cameras == 1 and len(built.trajectory) == 1
    view = built.world_from_canonical.view(built.trajectory.views[0])  # in the file's world
    np.testing.assert_allclose(view.eye, [0, 2, 10], atol=1e-6)  # moved by scale=2 too
    np.testing.assert_allclose(np.subtract(view.target, view.eye), [-1, 0, 0], atol=1e-6)
    np.testing.assert_allclose(view.up, [0, 1, 0], atol=1e-6)
    assert view.fov_y == pytest.approx(50.0, abs=1e-4)


def test_phong_exponent_from_roughness():
    assert phong_exponent(0.5) == pytest.approx(30.0)
    assert phong_exponent(1.0) == 1.0  # 2/1 − 2 = 0, clamped to 1
    assert phong_exponent(0.05) == 1e4  # clamped at the top
    assert phong_exponent(0.3) == pytest.approx(2 / 0.09 ** 2 - 2)


@pytest.mark.parametrize("suffix", [".ply", ".off"])
def test_ply_gets_default_materials_and_angle_weighted_normals(tmp_path, suffix):
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=0.5)
    path = tmp_path / f"ball{suffix}"
    sphere.export(str(path))
    scene, report = read_scene_file(str(path))
    assert scene.n_triangles == 320 and len(scene.objects) == 1
    assert scene.objects[0].material.kd == (0.7, 0.7, 0.7)
    assert not scene.objects[0].material.is_glossy
    mesh = scene.objects[0].mesh
    radial = mesh.positions / np.linalg.norm(mesh.positions, axis=1, keepdims=True)
    assert np.min(np.sum(radial * mesh.normals, axis=1)) > 0.99  # outward, nearly radial
    glossy = get_scene(str(path), variant="glossy").objects[0].material
    assert (glossy.kd, glossy.ks, glossy.shininess) == ((0.7,) * 3, (0.3,) * 3, 64.0)


def test_up_z_and_scale(tmp_path):
    box = trimesh.creation.box(extents=[1, 2, 4])
    box.apply_translation([0, 0, 2])  # standing on z = 0, +Z up
    path = tmp_path / "tower.stl"
    box.export(str(path))
    lo, hi = get_scene(str(path), up="z", scale="0.5").world_bounds()
    # (x, y, z) → (x, z, −y), then halved: the 4-unit height becomes y in [0, 2].
    np.testing.assert_allclose(lo, [-0.25, 0.0, -0.5], atol=1e-6)
    np.testing.assert_allclose(hi, [0.25, 2.0, 0.5], atol=1e-6)


def test_several_files_joined_with_plus_are_one_scene(tmp_path):
    box = trimesh.creation.box(extents=[1, 1, 1])
    ball = trimesh.creation.icosphere(subdivisions=2, radius=0.5)
    ball.apply_translation([3, 0, 0])
    box.export(str(tmp_path / "box.stl"))
    ball.export(str(tmp_path / "ball.glb"))
    a, b = str(tmp_path / "box.stl"), str(tmp_path / "ball.glb")
    both, report = read_scene_file(f"{a}+{b}", scale="2")
    alone = [get_scene(f, scale="2") for f in (a, b)]
    assert len(both.objects) == 2 and all(o.name.split("/")[0] in ("box", "ball")
                                          for o in both.objects)
    assert both.n_triangles == sum(s.n_triangles for s in alone)
    np.testing.assert_allclose(both.world_bounds()[0], [-1, -1, -1], atol=1e-6)  # box, scaled
    np.testing.assert_allclose(both.world_bounds()[1], [7, 1, 1], atol=1e-2)  # ball at x = 6 ± 1
    for combined, single in zip(both.objects, alone):  # each in its own canonical frame
        np.testing.assert_allclose(_world(both, combined.mesh.positions),
                                   _world(single, single.objects[0].mesh.positions), atol=2e-6)
    assert both.params["file"] == "box.stl+ball.glb" and both.name.startswith("box+ball-")
    # identity follows every file, in order
    assert get_scene(f"{b}+{a}", scale="2").name != both.name
    assert report.sha256 not in {get_scene(f).params["file_sha256"] for f in (a, b)}
    # a missing member is named on its own
    with pytest.raises(InvalidInputError, match=r"scene file '.*nothere\.obj': no such file"):
        get_scene(f"{a}+{tmp_path / 'nothere.obj'}")
    # a real file whose name has a '+' is that one file
    plus = tmp_path / "a+b.stl"
    box.export(str(plus))
    assert get_scene(str(plus)).n_triangles == alone[0].n_triangles


def test_pareto_of_a_file_scene_hints_with_the_path(tmp_path, capsys):
    path = tmp_path / "box.stl"
    trimesh.creation.box().export(str(path))
    store = tmp_path / "r.sqlite"  # absent: pareto says which sweep fills it
    argv = ["pareto", "--scene", str(path), "--scene-param", "ground=true", "--profile", "smoke",
            "--results", str(store), "--reports", str(tmp_path / "rep")]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert f"`prtbench sweep --scene {path} --method METHOD,... --profile smoke` fills it" in err
    assert len(err.splitlines()) == 1 and not (tmp_path / "rep").exists()


def test_paths_pass_the_registry_check_and_names_still_do(tmp_path):
    assert SCENES.check("anything/model.glb") == "anything/model.glb"
    assert SCENES.check("plants") == "plants"
    with pytest.raises(Exception, match="unknown scene"):
        SCENES.check("no-such-scene")


def _glb_with_a_broken_embedded_texture(path: Path) -> None:
    """A textured GLB whose embedded PNG bytes are zeroed in place (lengths kept)."""
    import json
    import struct

    _pbr_box(texture=Image.new("RGB", (8, 8), (200, 50, 50))).export(str(path))
    raw = bytearray(path.read_bytes())
    json_length = struct.unpack_from("<I", raw, 12)[0]
    tree = json.loads(raw[20:20 + json_length])
    bin_start = 20 + json_length + 8
    view = tree["bufferViews"][tree["images"][0]["bufferView"]]
    start = bin_start + view.get("byteOffset", 0)
    raw[start:start + view["byteLength"]] = bytes(view["byteLength"])
    path.write_bytes(bytes(raw))


def _bad_inputs(tmp_path: Path) -> list[tuple[str, dict, str]]:
    (tmp_path / "model.fbx").write_bytes(b"fbx")
    (tmp_path / "garbage.glb").write_bytes(b"glTF" + os.urandom(64))
    cloud = tmp_path / "cloud.ply"
    trimesh.PointCloud(np.random.default_rng(1).normal(size=(50, 3))).export(str(cloud))
    nan_obj = tmp_path / "nan.obj"
    nan_obj.write_text("v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n")
    gltf = _two_node_gltf(tmp_path / "nobuf.gltf")
    for p in tmp_path.glob("*.bin"):
        p.unlink()
    (tmp_path / "broken.png").write_bytes(b"\x89PNG\r\n\x1a\n not really")
    (tmp_path / "badtex.mtl").write_text("newmtl m\nKd 1 1 1\nmap_Kd broken.png\n")
    (tmp_path / "badtex.obj").write_text(
        "mtllib badtex.mtl\nusemtl m\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
        "f 1/1 2/2 3/3\n")
    small = tmp_path / "small.stl"
    trimesh.creation.box().export(str(small))
    huge = tmp_path / "huge.obj"  # finite in float64, but not once scaled by 1e12
    huge.write_text("v 0 0 0\nv 1e300 0 0\nv 0 1e300 0\nf 1 2 3\n")
    _glb_with_a_broken_embedded_texture(tmp_path / "badtex.glb")
    return [
        (str(tmp_path / "missing.glb"), {}, "no such file"),
        (str(tmp_path / "model.fbx"), {}, "unsupported extension '.fbx'; accepted: .glb, .gltf"),
        (str(tmp_path / "garbage.glb"), {}, "trimesh cannot parse it"),
        (str(cloud), {}, "no triangles"),
        (str(nan_obj), {}, "NaN/Inf vertex positions"),
        (str(gltf), {}, "is missing"),
        (str(tmp_path / "badtex.obj"), {}, "texture 'broken.png' cannot be decoded"),
        (str(tmp_path / "badtex.glb"), {}, "cannot be decoded"),
        (str(huge), {"scale": "1e12"}, "non-finite coordinates once its node transform and "
                                       "scale=1e+12 are applied; accepted: finite coordinates"),
        (str(small), {"scale": "0"}, r"scale='0'; accepted: finite numbers in (0, 1e+12]"),
        (str(small), {"up": "x"}, "accepted: y, z"),
        (str(small), {"units": "m"}, "has no parameter 'units'; accepted: scale, up, ground"),
    ]


def test_bad_inputs_are_one_line_errors_naming_the_file_and_cache_nothing(tmp_path, monkeypatch):
    _own_cache(monkeypatch, tmp_path)
    for path, params, fragment in _bad_inputs(tmp_path):
        before = _cache_files()
        with pytest.raises(InvalidInputError) as err:
            get_scene(path, **params)
        message = str(err.value)
        assert fragment in message, (path, message)
        assert "\n" not in message
        assert Path(path).name in message or "parameter" in message, message
        assert _cache_files() == before


def test_a_millimetre_file_scene_is_imported_in_the_canonical_frame(tmp_path):
    # A 1 mm box (diagonal 1.7e-3) was refused before the canonical frame (Mitsuba's float32
    # ray offset, about 9e-5, is 5 % of it); now it is stored centred with diagonal 2, and
    # world_from_canonical (also in params, for the stored rows) says where it was.
    path = tmp_path / "tiny.stl"
    box = trimesh.creation.box(extents=(1e-3, 1e-3, 1e-3))
    box.apply_translation((0.0, 5e-4, 0.0))
    box.export(str(path))
    scene = get_scene(str(path))
    assert scene.diagonal() == pytest.approx(2.0, rel=1e-6)
    np.testing.assert_allclose(np.add(*scene.bounds()), 0.0, atol=1e-6)
    lo, hi = scene.world_bounds()
    np.testing.assert_allclose(lo, [-5e-4, 0.0, -5e-4], atol=1e-9)
    np.testing.assert_allclose(hi, [5e-4, 1e-3, 5e-4], atol=1e-9)
    frame = scene.params["world_from_canonical"]
    assert frame["scale"] == pytest.approx(np.sqrt(3) * 1e-3 / 2, rel=1e-6)
    np.testing.assert_allclose(frame["offset"], [0.0, 5e-4, 0.0], atol=1e-12)
    # In metres (scale=1000 of the same file) it is the same canonical scene.
    metres = get_scene(str(path), scale="1000")
    np.testing.assert_allclose(metres.objects[0].mesh.positions, scene.objects[0].mesh.positions,
                               atol=1e-6)
    assert metres.params["world_from_canonical"]["scale"] == pytest.approx(1e3 * frame["scale"])


def test_scene_info_prints_counts_materials_and_repairs(tmp_path, capsys):
    path = _write_obj(tmp_path, extra="f 9 9 10\n")
    assert main(["scene", "info", str(path), "--variant", "glossy"]) == 0
    out = capsys.readouterr().out
    assert "2 objects, 24 triangles, 16 vertices" in out
    assert "1 degenerate" in out and "0 non-manifold edges" in out
    assert "material shiny: kd (0.600, 0.200, 0.100) ks (0.300, 0.250, 0.200) s 80" in out
    assert "bounds (-1.5, -0.5, -0.5) .. (1.5, 0.5, 0.5)" in out


def test_scene_info_of_a_builtin_name_summarises_the_builtin_scene(capsys):
    assert main(["scene", "info", "sphere-over-plane"]) == 0
    out = capsys.readouterr().out
    built = get_scene("sphere-over-plane")
    assert out.startswith(f"scene {built.name} (diffuse) built in")
    assert f"{len(built.objects)} objects, {built.n_triangles} triangles" in out
    assert "repaired" not in out
    assert main(["scene", "info", "sphere-over-plan"]) == 2
    assert "unknown scene 'sphere-over-plan'; did you mean 'sphere-over-plane'" in \
        capsys.readouterr().err


def test_scene_info_bad_input_exits_2(tmp_path, capsys):
    for path, params, fragment in _bad_inputs(tmp_path):
        argv = ["scene", "info", path] + [f"--scene-param={k}={v}" for k, v in params.items()]
        assert main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith("prtbench: error: ") and fragment in err and "\n" not in err


def _sphere_over_ground(path: Path) -> Path:
    """A clay ball (glTF dielectric, roughness 0.6) over a 24×24-quad floor without material."""
    scene = trimesh.Scene()
    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.5)
    ball.visual = trimesh.visual.TextureVisuals(material=trimesh.visual.material.PBRMaterial(
        baseColorFactor=[178, 140, 102, 255], metallicFactor=0.0, roughnessFactor=0.6))
    scene.add_geometry(ball, node_name="ball", geom_name="ball",
                       transform=trimesh.transformations.translation_matrix([0, 0.7, 0]))
    t = np.linspace(-1.5, 1.5, 25)
    x, z = np.meshgrid(t, t)
    idx = np.arange(25 * 25).reshape(25, 25)
    a, b, c, d = (idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(),
                  idx[1:, :-1].ravel())
    floor = trimesh.Trimesh(np.stack([x.ravel(), np.zeros(x.size), z.ravel()], 1),
                            np.concatenate([np.stack([a, c, b], 1), np.stack([a, d, c], 1)]),
                            process=False)
    assert np.allclose(floor.face_normals, [0, 1, 0])  # the floor faces up
    scene.add_geometry(floor, node_name="floor", geom_name="floor")
    scene.export(str(path))
    return path


@pytest.mark.slow  # repeats test_canonical_frame's and the glb-plants runs of vertex on a glTF file
def test_vertex_prt_on_a_gltf_file_beats_the_trivial_images(tmp_path):
    # End to end through the runner (quick profile, path reference): ~28 dB masked PSNR
    # measured; the gate is the flat, half-bright and unshadowed images of the same reference.
    import sqlite3

    from prtbench.bench.job import Job
    from prtbench.bench.regress import gate
    from prtbench.bench.submit import run

    path = _sphere_over_ground(tmp_path / "ball.glb")
    results = tmp_path / "results.sqlite"
    job = Job(method="vertex", scene=str(path), profile="quick", views=2)
    summary = run(job, results_path=results, progress=False, echo=False).summary
    assert summary.scene.startswith("ball-") and summary.status == "ok"
    assert not gate(job, summary.mean_metrics())
    assert summary.mean_metrics()["psnr_masked"] > 20.0
    # The results store records the file name and its content hash.
    rows = sqlite3.connect(results).execute("select scene, scene_params from renders").fetchall()
    assert len(rows) == 2 and rows[0][0] == summary.scene
    assert '"file": "ball.glb"' in rows[0][1]
    assert read_scene_file(str(path))[1].sha256 in rows[0][1]


def _as_trimesh_scene(scene, material, *, translation=None) -> "trimesh.Scene":
    """A built-in scene as a trimesh scene: one node per object (moved by ``translation``), its
    normals stored, ``material(name, kd8)`` its trimesh material from kd in 8 bits."""
    out = trimesh.Scene()
    transform = (np.eye(4) if translation is None
                 else trimesh.transformations.translation_matrix(translation))
    for o in scene.objects:
        mesh = trimesh.Trimesh(o.mesh.positions, o.mesh.faces, vertex_normals=o.mesh.normals,
                               process=False)
        kd = np.round(np.array(o.material.kd) * 255).astype(np.uint8)
        mesh.visual = trimesh.visual.TextureVisuals(material=material(o.name, kd))
        out.add_geometry(mesh, node_name=o.name, geom_name=o.name, transform=transform)
    return out


def _as_gltf_scene(scene, *, translation=None) -> "trimesh.Scene":
    """For glTF: kd as the 8-bit baseColorFactor of a non-metallic rough material."""
    return _as_trimesh_scene(scene, lambda name, kd: trimesh.visual.material.PBRMaterial(
        baseColorFactor=[*kd, 255], metallicFactor=0.0, roughnessFactor=1.0, name=name),
        translation=translation)


def test_translated_export_of_a_builtin_scene_imports_as_the_same_scene_moved(tmp_path):
    # plants (diffuse) written to glTF by trimesh, every node translated by t, its normals
    # stored: the import is the built-in scene moved by t, so a camera moved by t sees the same
    # geometry pixels, normals and materials (kd up to glTF's 8-bit colour factors).
    from dataclasses import replace

    from prtbench.transport.raytrace import geometry_mask

    builtin = get_scene("plants")
    t = np.array([10.0, -2.0, 3.5])
    out = _as_gltf_scene(builtin, translation=t)
    path = tmp_path / "plants.glb"
    out.export(str(path))
    imported, report = read_scene_file(str(path))
    assert report.normals_computed == 0 and report.degenerate_faces == 0
    assert imported.n_triangles == builtin.n_triangles
    by_name = {o.name: o for o in imported.objects}
    for o in builtin.objects:
        m = by_name[o.name]
        # Compared corner by corner: unused vertices of the built-in mesh are dropped.
        mine, theirs = m.mesh.faces, o.mesh.faces
        np.testing.assert_allclose(_world(imported, m.mesh.positions[mine]),
                                   o.mesh.positions[theirs] + t, atol=2e-5)
        np.testing.assert_allclose(m.mesh.normals[mine], o.mesh.normals[theirs], atol=1e-5)
        np.testing.assert_allclose(m.material.kd, o.material.kd, atol=0.5 / 255 + 1e-9)
    for view in builtin.trajectory.views[:3]:
        moved = replace(view, eye=tuple(np.add(view.eye, t)), target=tuple(np.add(view.target, t)))
        moved = imported.world_from_canonical.inverse().view(moved)  # the import's frame
        a = geometry_mask(builtin, view, 64, 48)
        b = geometry_mask(imported, moved, 64, 48)
        assert a.sum() > 500 and np.mean(a != b) < 0.002  # edge pixels may flip in float32


def test_scene_params_reach_file_scenes_from_run_and_reference(tmp_path, capsys):
    path = tmp_path / "small.stl"
    trimesh.creation.box().export(str(path))
    for command in (["run", "--method", "vertex"], ["reference"]):
        argv = command + ["--scene", str(path), "--scene-param", "up=x"]
        assert main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith("prtbench: error: ") and "up='x'; accepted: y, z" in err, err


def test_file_scene_over_sloan_matrix_limit_is_refused_naming_the_limit(tmp_path, capsys,
                                                                        monkeypatch):
    # Icosphere subdivision 7: 163842 vertices; at sh_bands=8 a vertex's matrix is 8⁴ floats,
    # so 2 GiB (the default max_bytes) holds 131072 vertices: the file is over the limit.
    path = tmp_path / "big.ply"
    trimesh.creation.icosphere(subdivisions=7).export(str(path))
    _own_cache(monkeypatch, tmp_path)
    before = _cache_files()
    argv = ["run", "--method", "sloan-matrix", "--scene", str(path), "--set", "sh_bands=8",
            "--profile", "smoke", "--results", str(tmp_path / "r.sqlite"),
            "--out", str(tmp_path / "out")]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("prtbench: error: ") and "\n" not in err, err
    assert "327680 triangles / 163842 vertices" in err, err
    assert "limit of 131072 vertices at sh_bands=8" in err and "use sh_bands=7 or fewer" in err
    assert "big-" in err  # the file scene's name
    assert _cache_files() == before
    assert not (tmp_path / "r.sqlite").exists() and not (tmp_path / "out").exists()


def _builtin_and_imported_psnr(method: str, name: str, path: Path, *, builtin, light: str,
                               scene_params: dict | None = None) -> tuple[float, float]:
    """Masked PSNR of ``method`` (smoke, one view) on the built-in scene ``name`` and on its
    export ``path``, the import seen from the built-in's views and exposure; each against its
    own path reference. The built-in run must beat its trivial images (a measurement, not
    noise)."""
    import copy

    from prtbench.bench.job import Job
    from prtbench.bench.regress import gate
    from prtbench.bench.runner import execute, prepare

    import dataclasses

    psnr = []
    for scene in (name, str(path)):
        job = Job(method=method, scene=scene, profile="smoke", views=1, light=light,
                  scene_params=(scene_params or {}) if scene == name else {})
        prepared = prepare(job, store=False)
        if scene != name:
            assert prepared.scene.name.startswith(f"{name}-")  # really the imported file
            moved = copy.copy(prepared.scene)
            # The built-in's views are in the file's world: into the import's canonical frame.
            into = moved.world_from_canonical.inverse()
            moved.trajectory = dataclasses.replace(
                builtin.trajectory, views=tuple(map(into.view, builtin.trajectory.views)))
            moved.exposure = builtin.exposure
            prepared.scene = moved.with_views(1)
        summary = execute(prepared, progress=False, echo=False)
        assert summary.status == "ok"
        psnr.append(summary.mean_metrics()["psnr_masked"])
        if scene == name:
            assert not gate(job, summary.mean_metrics())
    return psnr[0], psnr[1]


@pytest.mark.parametrize("method", [
    "vertex",
    # ~10 s; test_canonical_frame runs texture-tpfl on glTF files in make test
    pytest.param("texture-tpfl", marks=pytest.mark.slow),
])
def test_plants_exported_to_glb_measures_as_the_builtin_plants(tmp_path, method):
    # plants (diffuse, procedural: no fetched asset, ~5 s) written to GLB by trimesh (positions
    # and normals as stored, kd through glTF's 8-bit factors), imported, and run with vertex and
    # texture-tpfl (its atlas made by xatlas: the export has no UVs) at smoke on the built-in's views and exposure. Each is measured against its own path
    # reference (a separate cache entry: the file scene hashes differently), so the two masked
    # PSNRs may differ by the references' Monte-Carlo noise and the kd rounding (≤ 0.5/255).
    # 1 dB is the acceptance bound for an imported scene; measured: 0.001 dB.
    # vertex's own regression case: a subdivided ground under the sun, where the shadows are
    # what is measured (under sky, at 1 view, vertex does not beat the unshadowed image here).
    params = {"ground_subdivisions": 32}
    builtin = get_scene("plants", **params)
    out = _as_gltf_scene(builtin)
    path = tmp_path / "plants.glb"
    out.export(str(path))

    psnr = _builtin_and_imported_psnr(method, "plants", path, builtin=builtin, light="sun",
                                      scene_params=params)
    print(f"{method}: masked PSNR built-in {psnr[0]:.3f} dB, imported {psnr[1]:.3f} dB")
    assert abs(psnr[0] - psnr[1]) < 1.0


def test_file_scene_over_the_memory_triangle_limit_is_refused(tmp_path, monkeypatch, capsys):
    # The machine's memory stands in as 1000 triangles' worth (512 B each through a run): the
    # 1280-triangle icosphere is refused naming its count and the limit; 320 are accepted.
    import prtbench.api.config as config
    from prtbench.scene.params import BYTES_PER_TRIANGLE

    monkeypatch.setattr(config, "memory_budget", lambda: 1000 * BYTES_PER_TRIANGLE)
    path = tmp_path / "ball.stl"
    trimesh.creation.icosphere(subdivisions=3).export(str(path))
    _own_cache(monkeypatch, tmp_path)
    before = _cache_files()
    assert main(["run", "--method", "vertex", "--scene", str(path), "--profile", "smoke",
                 "--results", str(tmp_path / "r.sqlite"), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("prtbench: error: ") and "\n" not in err, err
    assert "ball.stl' with 1280 triangles" in err and "at most 1000 triangles" in err, err
    assert _cache_files() == before and not (tmp_path / "out").exists()
    small = tmp_path / "small.stl"
    trimesh.creation.icosphere(subdivisions=2).export(str(small))
    assert read_scene_file(str(small))[0].n_triangles == 320


def _as_obj_scene(scene) -> "trimesh.Scene":
    """For OBJ+MTL: kd as the MTL's ``Kd`` (trimesh's SimpleMaterial) and ``Ks`` 0 (trimesh
    writes 0.4 by default, which the reader would take as a glossy lobe)."""
    return _as_trimesh_scene(scene, lambda name, kd: trimesh.visual.material.SimpleMaterial(
        diffuse=[*kd, 255], specular=[0, 0, 0, 255], ambient=[0, 0, 0, 255],
        name=name.replace("/", "_")))


@pytest.mark.assets
def test_cgal_lion_exported_to_obj_measures_as_the_builtin_lion(tmp_path):
    # Issue #14's must-hold: the CGAL lion head (a fetched asset, hence `assets`) written to
    # OBJ+MTL by trimesh and run with texture-tpfl (its atlas made by xatlas: the export has no
    # UVs) within 1 dB masked PSNR of the built-in `lion`, each against its own path reference,
    # on the built-in's views and exposure. Measured at quick by hand (last stop): 27.66 vs
    # 27.77 dB; at smoke (this test) 23.89 vs 23.84 dB.
    builtin = get_scene("lion")
    path = tmp_path / "lion.obj"
    _as_obj_scene(builtin).export(str(path))
    assert (tmp_path / "material.mtl").is_file()  # trimesh writes the MTL beside the OBJ
    imported, _ = read_scene_file(str(path))
    assert len(imported.objects) == len(builtin.objects)
    assert all(np.allclose(o.material.ks, 0.0) for o in imported.objects)  # diffuse, as built
    psnr = _builtin_and_imported_psnr("texture-tpfl", "lion", path, builtin=builtin, light="sky")
    print(f"texture-tpfl lion: masked PSNR built-in {psnr[0]:.3f} dB, OBJ {psnr[1]:.3f} dB")
    assert abs(psnr[0] - psnr[1]) < 1.0
