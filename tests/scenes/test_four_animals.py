"""four-animals (the Raghavan et al. 2023 stand-in) and cornell's tessellation knob."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.ndimage import binary_dilation

import scenes.four_animals  # noqa: F401  registers the scene where the installed metadata lags
from prtbench.api.errors import InvalidInputError
from prtbench.scene.registry import get_scene
from tests.scenes.test_scenes import _check_rebuilds_from_params, _check_scene, user_assets  # noqa: F401

#: 26 002 + 37 706 + 8 393 + 10 008 vertices of the four animals, the ring and the ground.
TRIANGLES = (165_000, 172_000)


@pytest.mark.assets
@pytest.mark.parametrize("variant", ["diffuse", "glossy"])
@pytest.mark.parametrize("trajectory", ["near", "far"])
def test_builds_bounded_and_sees_every_object(variant, trajectory, user_assets):
    scene = get_scene("four-animals", variant=variant, trajectory=trajectory)
    _check_scene(scene, TRIANGLES)  # 30 views, each mostly geometry, every object seen
    names = [o.name for o in scene.objects]
    assert names == ["ground", "armadillo", "bunny", "lion", "dragon", "ring"]
    lo, hi = scene.bounds()
    # Everything stands on the ground; only the ring is sunk 1 cm into it.
    assert -0.0101 < lo[1] < 0.0 and 0.6 < hi[1] < 1.0, (lo, hi)
    assert 6.0 < scene.diagonal() < 8.0
    for obj in scene.objects[1:]:
        olo, ohi = obj.mesh.positions.min(axis=0), obj.mesh.positions.max(axis=0)
        assert np.all(np.abs(olo[[0, 2]]) < 1.1) and np.all(np.abs(ohi[[0, 2]]) < 1.1), obj.name
        if obj.name != "ring":
            assert abs(olo[1]) < 1e-6, obj.name
    assert "CGAL" in scene.substitution
    _check_rebuilds_from_params(scene)


@pytest.mark.assets
def test_glossy_materials_where_stated(user_assets):
    glossy = {o.name: o.material for o in get_scene("four-animals", variant="glossy").objects}
    assert all(m.is_glossy for m in glossy.values())
    ring = glossy["ring"]
    # A metallic ring: a strong coloured lobe, sharper than anything else, over a dark base.
    assert min(ring.ks) >= 0.4 and max(ring.ks) >= 0.85 and max(ring.kd) <= 0.05
    assert ring.shininess >= 256 and all(ring.shininess > m.shininess
                                         for n, m in glossy.items() if n != "ring")
    assert glossy["ground"].ks[0] >= 0.2
    diffuse = get_scene("four-animals", variant="diffuse")
    assert not any(o.material.is_glossy for o in diffuse.objects)


@pytest.mark.assets
def test_near_and_far_trajectories_share_geometry_but_no_view(user_assets):
    near = get_scene("four-animals", trajectory="near")
    far = get_scene("four-animals", trajectory="far")
    # Methods precompute once for both: the content hash ignores cameras.
    assert near.content_hash() == far.content_hash()
    eyes_near = np.array([v.eye for v in near.trajectory.views])
    eyes_far = np.array([v.eye for v in far.trajectory.views])
    assert len(eyes_near) == len(eyes_far) == 30
    gaps = np.linalg.norm(eyes_far[:, None] - eyes_near[None], axis=-1)
    assert gaps.min() > 0.5, gaps.min()
    center = np.array(scenes.four_animals.CENTER)
    assert np.linalg.norm(eyes_far - center, axis=1).min() > np.linalg.norm(
        eyes_near - center, axis=1).max()
    # The far helix sweeps heights; the near orbit is level.
    assert np.ptp(eyes_near[:, 1]) < 1e-9 and np.ptp(eyes_far[:, 1]) > 1.0


def test_unknown_trajectory_is_one_line_error():
    with pytest.raises(InvalidInputError, match=r"trajectory='middle'.*near, far"):
        get_scene("four-animals", trajectory="middle")


@pytest.mark.assets
def test_mitsuba_reference_renders_finite_and_lit(user_assets):
    from prtbench.render.reference import render_reference
    from prtbench.transport.raytrace import geometry_mask

    scene = get_scene("four-animals", variant="glossy")
    view, width, height = scene.trajectory.views[0], 48, 36
    mask = geometry_mask(scene, view, width, height)
    direct = render_reference(scene, "sky", view, width=width, height=height, spp=8)
    bounced = render_reference(scene, "sky", view, width=width, height=height, spp=8,
                               bounces=1)
    for ref in (direct, bounced):
        assert ref.image.shape == (height, width, 3) and np.all(np.isfinite(ref.image))
        # Lit geometry: the median covered pixel displays well above black (exposure 0.7
        # targets a linear ~0.35); the background is not drawn (the box filter averages a
        # whole pixel, so silhouette pixels just outside the centre-sampled mask may be lit).
        assert np.median(ref.image[mask].mean(axis=1)) * scene.exposure > 0.05
        assert np.all(ref.image[~binary_dilation(mask)] == 0)
    # The glossy ground, ring and animals reflect each other: interreflection adds light.
    assert bounced.image[mask].mean() > 1.02 * direct.image[mask].mean()


# --- cornell's tessellation -------------------------------------------------------------------

def test_cornell_subdivisions_keep_the_box_and_its_default():
    base = get_scene("cornell", variant="glossy")
    assert get_scene("cornell", variant="glossy", subdivisions=1).content_hash() == \
        base.content_hash()
    assert base.params == {"skylight": 0.3}  # stored rows of the default are unchanged
    fine = get_scene("cornell", variant="glossy", subdivisions=8)
    _check_scene(fine, (2_000, 2_400))
    _check_rebuilds_from_params(fine)
    assert fine.params == {"skylight": 0.3, "subdivisions": 8}
    np.testing.assert_allclose(np.concatenate(fine.bounds()), np.concatenate(base.bounds()),
                               atol=1e-6)
    for a, b in zip(base.objects, fine.objects):
        assert a.name == b.name and a.material.spec() == b.material.spec()
        # Same surface, finer: equal area, no edge longer than a cell's diagonal.
        assert abs(a.mesh.triangle_areas().sum() - b.mesh.triangle_areas().sum()) < 1e-5
        p, f = b.mesh.positions, b.mesh.faces
        edges = np.linalg.norm(p[f] - p[np.roll(f, 1, axis=1)], axis=-1)
        assert edges.max() < np.sqrt(2) / 8 + 1e-6, a.name
    assert fine.n_vertices > 6 * base.n_vertices
    with pytest.raises(InvalidInputError, match="subdivisions=0"):
        get_scene("cornell", subdivisions=0)
