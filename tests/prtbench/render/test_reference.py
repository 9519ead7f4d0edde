"""The Mitsuba reference renders the same scene, light, camera and BRDF as prtbench (DESIGN.md §6).

Analytic cases first: white-furnace spheres (radiance = albedo), one-sided quads, shading with
our vertex normals, texture orientation, the camera footprint of a sphere, and a sun shadow
that must land where our own ray tracer puts it. All renders are tiny (≤ 64×48 pixels).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.ndimage
import scipy.special

mi = pytest.importorskip("mitsuba")

from prtbench.api.cache import content_key  # noqa: E402
from prtbench.api.errors import InvalidInputError  # noqa: E402
from prtbench.io import imageio  # noqa: E402
from prtbench.render import mitsuba_variant, reference
from prtbench.render.mitsuba_bsdf import brdf  # noqa: E402
from prtbench.scene.model import Material, Scene, SceneObject, Texture, TriangleMesh, View
from prtbench.scene.registry import get_scene
from prtbench.transport.lights import get_light  # noqa: E402
from scenes.primitives import uv_sphere  # noqa: E402

FRONT = View(eye=(0.0, 0.0, 3.5), target=(0.0, 0.0, 0.0), fov_y=40.0)


class _Light:
    """A minimal lat-long light (what render_reference needs: name, image, content_hash)."""

    def __init__(self, name: str, image: np.ndarray):
        self.name, self.image = name, np.asarray(image, np.float32)

    def content_hash(self) -> str:
        return content_key(self.name, self.image)


def _sphere_scene(material: Material, *, radius: float = 1.0, center=(0.0, 0.0, 0.0),
                  segments: int = 64) -> Scene:
    mesh = uv_sphere(radius=radius, segments=segments, center=center)
    return Scene("test-sphere", [SceneObject("sphere", mesh, material)])


def _quad(center, right, up, *, normal=None, uvs: bool = False) -> TriangleMesh:
    """A rectangle spanned by ``right`` × ``up`` (CCW seen from ``right × up``)."""
    c, r, u = (np.asarray(x, np.float64) for x in (center, right, up))
    positions = np.array([c - r - u, c + r - u, c + r + u, c - r + u])
    n = np.cross(r, u) if normal is None else np.asarray(normal, np.float64)
    normals = np.tile(n / np.linalg.norm(n), (4, 1))
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32) if uvs else None
    return TriangleMesh(positions, np.array([[0, 1, 2], [0, 2, 3]]), normals, uv)


def _sphere_hits(view: View, width: int, height: int, center, radius: float):
    """Pixel-centre rays against the exact sphere: (distance of the centre from each ray,
    hit point, normal, direction to the eye), and a pixel footprint size at the sphere."""
    origins, dirs = view.primary_rays(width, height)
    oc = np.asarray(center, np.float64) - origins
    along = np.sum(oc * dirs, axis=-1)
    dist = np.linalg.norm(oc - along[..., None] * dirs, axis=-1)
    t = along - np.sqrt(np.maximum(radius ** 2 - dist ** 2, 0.0))
    points = origins + t[..., None] * dirs
    normals = (points - np.asarray(center)) / radius
    depth = float(np.linalg.norm(np.asarray(view.eye) - np.asarray(center)))
    footprint = depth * 2.0 * math.tan(math.radians(view.fov_y) / 2) / height
    return dist, normals, -dirs, footprint


def _albedo(cos_view: float, s: float, kd, ks) -> np.ndarray:
    """∫_H f cos θi dωi (local frame) by Gauss–Legendre × midpoint quadrature, (3,)."""
    x, w = scipy.special.roots_legendre(500)
    mu, w_mu = 0.5 * (x + 1), 0.5 * w
    n_phi = 1000
    phi = (np.arange(n_phi) + 0.5) * 2 * math.pi / n_phi
    mu_g, phi_g = np.meshgrid(mu, phi, indexing="ij")
    sin_t = np.sqrt(1 - mu_g ** 2)
    dirs = np.stack([sin_t * np.cos(phi_g), sin_t * np.sin(phi_g), mu_g], -1).reshape(-1, 3)
    weights = np.repeat(w_mu, n_phi) * (2 * math.pi / n_phi)
    view = np.array([math.sqrt(max(1 - cos_view ** 2, 0.0)), 0.0, cos_view])
    f = brdf(np.array(kd), np.array(ks), s, np.array([0.0, 0.0, 1.0]), dirs,
             np.broadcast_to(view, dirs.shape))
    return (f * (dirs[:, 2] * weights)[:, None]).sum(axis=0)


# --- variant, arguments -----------------------------------------------------------------------

def test_variant_override_and_bad_values(monkeypatch):
    monkeypatch.setenv(mitsuba_variant.VARIANT_ENV, "scalar_rgb")
    assert mitsuba_variant.select_variant() == "scalar_rgb"
    monkeypatch.setenv(mitsuba_variant.VARIANT_ENV, "no_such_variant")
    with pytest.raises(InvalidInputError, match="no_such_variant"):
        mitsuba_variant.select_variant()
    monkeypatch.delenv(mitsuba_variant.VARIANT_ENV)
    assert mitsuba_variant.select_variant() in mitsuba_variant.VARIANT_ORDER
    assert reference.reference_kind() == "path"
    scene = _sphere_scene(Material())
    with pytest.raises(InvalidInputError, match="spp=1"):
        reference.render_reference(scene, get_light("white"), FRONT, width=8, height=8, spp=1)


def test_integrator_depth_mapping():
    mitsuba_variant.select_variant()
    scene = _sphere_scene(Material())
    for bounces in (0, 1, 3):
        d = reference.mitsuba_scene_dict(scene, get_light("white"), FRONT, width=8, height=8,
                                         bounces=bounces)
        assert d["integrator"]["max_depth"] == bounces + 2
        assert d["integrator"]["rr_depth"] > d["integrator"]["max_depth"]
        assert d["integrator"]["hide_emitters"] is True


# --- furnaces ---------------------------------------------------------------------------------

def test_white_furnace_diffuse_sphere_is_its_albedo():
    scene = _sphere_scene(Material(kd=(0.5, 0.5, 0.5)))
    w = h = 48
    ref = reference.render_reference(scene, get_light("white"), FRONT, width=w, height=h, spp=64)
    dist, normals, to_eye, foot = _sphere_hits(FRONT, w, h, (0, 0, 0), 1.0)
    facing = np.sum(normals * to_eye, axis=-1)
    interior = (dist < 1.0 - 1.5 * foot) & (facing > 0.3)
    background = dist > 1.0 + 1.5 * foot
    assert interior.sum() > 400 and background.sum() > 400
    assert np.all(ref.image[background] == 0.0)
    values = ref.image[interior]
    assert 0 < ref.noise_rmse < 0.05
    assert abs(values.mean() - 0.5) < 0.005
    worst_sigma = np.abs(values - 0.5).max() / ref.noise_rmse
    assert worst_sigma < 4.0, worst_sigma


def test_prtphong_with_ks_zero_equals_builtin_diffuse():
    """ks = 0: the plug-in and Mitsuba's ``diffuse`` draw the same directions, so the same
    seed gives the same image up to float rounding."""
    mitsuba_variant.select_variant()
    scene = _sphere_scene(Material(kd=(0.6, 0.4, 0.2)))
    light = get_light("sky")
    images = []
    for builtin in (True, False):
        d = reference.mitsuba_scene_dict(scene, light, FRONT, width=24, height=24, bounces=0,
                                         spp=16, use_builtin_diffuse=builtin)
        images.append(np.asarray(mi.render(mi.load_dict(d), spp=16, seed=3)))
    assert images[0][..., :3].max() > 0.1
    assert np.allclose(images[0], images[1], rtol=1e-3, atol=1e-5)


def test_glossy_furnace_equals_directional_albedo():
    kd, ks, s = (0.3, 0.3, 0.3), (0.5, 0.5, 0.5), 32.0
    scene = _sphere_scene(Material(kd=kd, ks=ks, shininess=s))
    w = h = 32
    ref = reference.render_reference(scene, get_light("white"), FRONT, width=w, height=h,
                                     spp=256)
    dist, normals, to_eye, foot = _sphere_hits(FRONT, w, h, (0, 0, 0), 1.0)
    cos_view = np.sum(normals * to_eye, axis=-1)
    geometry = dist < 1.0 + 1.5 * foot
    assert ref.image[geometry].max() <= 1.0 + 5 * ref.noise_rmse
    checked = 0
    # 3×3 blocks: the centre (ωo = n) and blocks further out, up to ~60° from the normal.
    for row, col in ((15, 15), (15, 20), (10, 15), (15, 24), (8, 9)):
        block = (slice(row - 1, row + 2), slice(col - 1, col + 2))
        if not np.all(dist[block] < 1.0 - 1.5 * foot):
            continue
        expected = np.mean([_albedo(c, s, kd, ks)[0] for c in cos_view[block].ravel()])
        measured = float(ref.image[block][..., 0].mean())
        assert abs(measured - expected) < 4 * ref.noise_rmse / 3 + 0.004, (row, col)
        checked += 1
    assert checked >= 4
    centre = _albedo(1.0, s, kd, ks)[0]
    assert centre == pytest.approx(0.3 + 0.5 * (s + 1) / (s + 2), abs=1e-6)


@pytest.mark.parametrize("light_name", ["sky", "sun"])
def test_plane_radiance_matches_light_integral(light_name):
    """Unoccluded diffuse quads facing several directions: radiance = kd/π·∫ L max(n·ω, 0) dω
    with L from prtbench's own lookup (``light.radiance``), so Mitsuba's envmap mapping and
    interpolation agree with the lights module in direction and scale."""
    light = get_light(light_name)
    kd = 0.5
    n_phi, n_theta = 2048, 1024
    u = (np.arange(n_phi) + 0.5) / n_phi
    theta = (np.arange(n_theta) + 0.5) * math.pi / n_theta
    dirs = np.stack(np.broadcast_arrays(
        np.sin(2 * math.pi * u)[None, :] * np.sin(theta)[:, None], np.cos(theta)[:, None],
        -np.cos(2 * math.pi * u)[None, :] * np.sin(theta)[:, None]), axis=-1).reshape(-1, 3)
    d_omega = np.repeat(np.sin(theta), n_phi) * (2 * math.pi / n_phi) * (math.pi / n_theta)
    radiance = light.radiance(dirs)
    for normal in ((0.0, 1.0, 0.0), (0.6, 0.8, 0.0), (0.0, 0.5, -math.sqrt(0.75))):
        n = np.asarray(normal)
        expected = kd / math.pi * (radiance * (np.maximum(dirs @ n, 0) * d_omega)[:, None]).sum(0)
        side = np.cross(n, [0.3, 0.2, 1.0])
        side /= np.linalg.norm(side)
        quad = _quad((0, 0, 0), side, np.cross(n, side))
        scene = Scene("facing", [SceneObject("quad", quad, Material(kd=(kd, kd, kd)))])
        view = View(eye=tuple(3.0 * n), target=(0.0, 0.0, 0.0), up=tuple(np.cross(n, side)),
                    fov_y=20.0)
        ref = reference.render_reference(scene, light, view, width=12, height=12, spp=1024)
        measured = ref.image[2:10, 2:10].reshape(-1, 3).mean(0)
        assert np.allclose(measured, expected, rtol=2e-3, atol=4 * ref.noise_rmse / 8), (
            normal, measured, expected)


# --- one-sidedness and normals ----------------------------------------------------------------

@pytest.mark.parametrize("glossy", [False, True])
def test_back_faces_are_black(glossy):
    material = Material(kd=(0.5, 0.5, 0.5), ks=(0.3, 0.3, 0.3) if glossy else (0, 0, 0),
                        shininess=16.0)
    light = get_light("white")
    w = h = 24
    away = _quad((0, 0, 0), (0, 1, 0), (1, 0, 0))  # right × up = −Z: faces away from the eye
    towards = _quad((0, 0, 0), (1, 0, 0), (0, 1, 0))
    # Winding towards the eye but normals away: our normals decide the front side.
    normals_away = _quad((0, 0, 0), (1, 0, 0), (0, 1, 0), normal=(0, 0, -1))
    images = {}
    for name, mesh in (("away", away), ("towards", towards), ("normals_away", normals_away)):
        scene = Scene(f"quad-{name}", [SceneObject("quad", mesh, material)])
        images[name] = reference.render_reference(scene, light, FRONT, width=w, height=h,
                                                  spp=16).image
    assert np.all(images["away"] == 0.0)
    assert np.all(images["normals_away"] == 0.0)
    covered = images["towards"][6:18, 6:18]
    assert covered.min() > 0.3  # the control is lit (a quad 2×2 at distance 3.5 covers them)


def test_shading_uses_our_vertex_normals():
    """A camera-facing quad whose vertex normals tilt 60° up, under a sky that is 1 above the
    horizon and 0 below: radiance kd·(1 + sin β)/2 for normal elevation β (kd/2 if Mitsuba
    used the geometric normal)."""
    height = 257  # a texel row exactly on the horizon keeps the bilinear ramp symmetric
    rows = np.arange(height) / (height - 1)  # Mitsuba's envmap rows sit at θ = π·i/(H−1)
    sky = np.where(rows < 0.5, 1.0, np.where(rows == 0.5, 0.5, 0.0))
    light = _Light("upper-hemisphere", np.repeat(np.repeat(sky[:, None, None], 2 * height, 1),
                                                 3, 2))
    beta = math.radians(60.0)
    normal = (0.0, math.sin(beta), math.cos(beta))
    for n, expected in (((0.0, 0.0, 1.0), 0.5 * 0.5),
                        (normal, 0.5 * (1 + math.sin(beta)) / 2)):
        quad = _quad((0, 0, 0), (1, 0, 0), (0, 1, 0), normal=n)
        scene = Scene("tilted", [SceneObject("quad", quad, Material(kd=(0.5, 0.5, 0.5)))])
        ref = reference.render_reference(scene, light, FRONT, width=16, height=16, spp=64)
        centre = ref.image[4:12, 4:12, 0]
        assert abs(centre.mean() - expected) < 3 * ref.noise_rmse / 8 + 2e-3, (n, centre.mean())


def test_textured_albedo_orientation():
    """Texture row 0 is v = 0 (bottom): a texture of four constant 2×2-texel quadrants shows
    in the matching image quadrants (white furnace: radiance = kd)."""
    quadrants = np.array([[0.1, 0.3], [0.6, 0.9]], np.float32)  # [v][u]
    texels = np.kron(quadrants, np.ones((2, 2), np.float32))  # 4×4, row 0 = v bottom
    tex = Texture(np.repeat(texels[..., None], 3, axis=2), name="quadrants")
    quad = _quad((0, 0, 0), (1, 0, 0), (0, 1, 0), uvs=True)
    scene = Scene("textured", [SceneObject("quad", quad, Material(kd=tex))])
    view = View(eye=(0.0, 0.0, 2.0), target=(0.0, 0.0, 0.0), fov_y=2 * math.degrees(math.atan(0.5)))
    ref = reference.render_reference(scene, get_light("white"), view, width=16, height=16, spp=16)
    # The quad spans exactly the image; bilinear lookups inside a quadrant's middle only mix
    # texels of that quadrant, so these pixels are exactly the quadrant's albedo.
    img = ref.image[..., 0]
    bottom_left, bottom_right = img[11:13, 3:5].mean(), img[11:13, 11:13].mean()
    top_left, top_right = img[3:5, 3:5].mean(), img[3:5, 11:13].mean()
    measured = np.array([[bottom_left, bottom_right], [top_left, top_right]])
    assert np.allclose(measured, quadrants, atol=4 * ref.noise_rmse / 2 + 1e-3), measured


# --- camera -----------------------------------------------------------------------------------

def test_camera_matches_view_primary_rays():
    """An off-centre sphere in a non-square image covers exactly the pixels our camera's
    pixel-centre rays say (outside a one-pixel band around its outline)."""
    center, radius = (0.9, 0.45, -0.3), 0.5
    scene = _sphere_scene(Material(kd=(0.5, 0.5, 0.5)), radius=radius, center=center)
    view = View(eye=(0.3, 0.8, 3.0), target=(0.1, 0.2, 0.0), up=(0.0, 1.0, 0.0), fov_y=35.0)
    w, h = 56, 40
    ref = reference.render_reference(scene, get_light("white"), view, width=w, height=h, spp=8)
    dist, _, _, foot = _sphere_hits(view, w, h, center, radius)
    inside, outside = dist < radius - 1.5 * foot, dist > radius + 1.5 * foot
    lit = ref.image[..., 0] > 0
    assert inside.sum() > 100
    assert np.all(lit[inside]) and not np.any(lit[outside])


# --- bounces ----------------------------------------------------------------------------------

def test_one_bounce_brightens_a_concave_corner():
    floor = _quad((0.5, 0, 0.5), (0.5, 0, 0), (0, 0, -0.5))     # normal +Y
    wall_x = _quad((0, 0.5, 0.5), (0, 0, 0.5), (0, 0.5, 0))     # normal +X
    wall_z = _quad((0.5, 0.5, 0), (0.5, 0, 0), (0, 0.5, 0))     # normal +Z
    material = Material(kd=(0.8, 0.8, 0.8))
    scene = Scene("corner", [SceneObject(n, m, material) for n, m in
                             (("floor", floor), ("wall_x", wall_x), ("wall_z", wall_z))])
    view = View(eye=(2.0, 1.6, 2.0), target=(0.3, 0.3, 0.3), fov_y=40.0)
    light = get_light("white")
    direct = reference.render_reference(scene, light, view, width=24, height=24, spp=32)
    one = reference.render_reference(scene, light, view, width=24, height=24, spp=32, bounces=1)
    mask = direct.image[..., 0] > 0
    assert mask.sum() > 100
    gain = one.image[mask].mean() - direct.image[mask].mean()
    stderr = math.hypot(direct.noise_rmse, one.noise_rmse) / math.sqrt(mask.sum())
    assert gain > 6 * stderr and gain > 0.03, (gain, stderr)


# --- cache ------------------------------------------------------------------------------------

def test_cache_hit_metadata_and_corruption(monkeypatch):
    scene = _sphere_scene(Material(kd=(0.4, 0.5, 0.6)), segments=16)
    light = get_light("white")
    args = dict(width=12, height=10, spp=8, seed=5)
    first = reference.render_reference(scene, light, FRONT, **args)
    assert not first.cache_hit and first.path.is_file()
    meta = imageio.read_exr_metadata(first.path)
    assert meta["spp"] == "8" and meta["variant"] == first.variant
    assert meta["mitsuba_version"] == mi.__version__
    assert float(meta["noise_rmse"]) == first.noise_rmse
    assert float(meta["noise_rmse_display"]) == first.noise_rmse_display

    def no_render(*a, **k):
        raise AssertionError("rendered although the reference is cached")

    with monkeypatch.context() as m:
        m.setattr(reference, "_render_half", no_render)
        second = reference.render_reference(scene, light, FRONT, **args)
    assert second.cache_hit and second.path == first.path
    assert np.array_equal(second.image, first.image)
    assert (second.spp, second.noise_rmse, second.variant) == (first.spp, first.noise_rmse,
                                                              first.variant)
    # A different seed or spp is a different reference.
    other = reference.render_reference(scene, light, FRONT, **{**args, "seed": 6})
    assert other.path != first.path and not other.cache_hit

    # A truncated file is detected and re-rendered (same seeds: the same image).
    data = first.path.read_bytes()
    first.path.write_bytes(data[: len(data) // 2])
    third = reference.render_reference(scene, light, FRONT, **args)
    assert not third.cache_hit and np.allclose(third.image, first.image, atol=1e-6)
    # So is an EXR without our metadata.
    imageio.write_exr(first.path, np.zeros((10, 12, 3), np.float32))
    fourth = reference.render_reference(scene, light, FRONT, **args)
    assert not fourth.cache_hit and fourth.image.max() > 0
    assert reference.render_reference(scene, light, FRONT, **args).cache_hit


def test_render_references_over_views():
    scene = _sphere_scene(Material(), segments=16)
    views = [FRONT, View(eye=(3.5, 0.0, 0.0), target=(0.0, 0.0, 0.0), fov_y=40.0)]
    refs = reference.render_references(scene, "white", views, width=8, height=8, spp=4,
                                       progress=False)
    assert len(refs) == 2 and refs[0].path != refs[1].path
    assert all(r.image.shape == (8, 8, 3) and r.spp == 4 for r in refs)


# --- the sun's shadow -------------------------------------------------------------------------

def test_sun_shadow_agrees_with_our_ray_tracer():
    """Under the ``sun`` light the ground pixels Mitsuba renders dark are exactly those our own
    tracer (View.primary_rays → first_hit → occlusion towards the sun) finds shadowed: this
    ties the envmap mapping and the camera of the reference to prtbench's."""
    from prtbench.transport.raytrace import Tracer, offset_origins

    scene = get_scene("sphere-over-plane")
    light = get_light("sun")
    # From the side of the shadow (which falls back-left, away from the sun at azimuth 60°).
    view = View(eye=(-3.0, 3.0, -1.0), target=(-0.4, 0.3, -0.2), fov_y=45.0)
    w, h = 64, 48
    ref = reference.render_reference(scene, light, view, width=w, height=h, spp=32)

    tracer = Tracer.from_scene(scene)
    origins, dirs = view.primary_rays(w, h)
    hits = tracer.first_hit(origins.reshape(-1, 3), dirs.reshape(-1, 3))
    ground_index = [o.name for o in scene.objects].index("ground")
    ground = hits.hit & (tracer.object_of_face[np.maximum(hits.face, 0)] == ground_index)
    points = origins.reshape(-1, 3) + hits.t[:, None].astype(np.float64) * dirs.reshape(-1, 3)
    sun = np.asarray(light.brightest_direction(), np.float64)
    shadow = np.zeros(len(points), bool)
    up = np.tile([0.0, 1.0, 0.0], (int(ground.sum()), 1))
    shadow[ground] = tracer.occluded(
        offset_origins(points[ground], up, diagonal=scene.diagonal()),
        np.broadcast_to(sun, (int(ground.sum()), 3)))
    shadow, ground = shadow.reshape(h, w), ground.reshape(h, w)
    assert shadow.sum() > 100 and (ground & ~shadow).sum() > 1000

    # Only pixels whose whole footprint is ground (not the plane's far edge or the sphere's
    # outline, where the box filter mixes surfaces).
    ring = np.ones((3, 3), bool)
    ground = scipy.ndimage.binary_erosion(ground, ring)
    radiance = ref.image[..., 0]
    lit_level = radiance[ground & ~shadow].mean()
    dark = ground & (radiance < 0.5 * lit_level)
    ours = ground & shadow
    iou = (dark & ours).sum() / (dark | ours).sum()
    assert iou >= 0.9, iou
    # Disagreements are only boundary pixels (partly shadowed footprints).
    boundary = (scipy.ndimage.binary_dilation(ours, ring)
                & ~scipy.ndimage.binary_erosion(ours, ring, border_value=1))
    assert not np.any((dark ^ ours) & ~boundary)
