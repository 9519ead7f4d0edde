"""Transfer precompute: analytic transfer, the sphere over a plane, caching, interreflection."""

from __future__ import annotations

import math
import os
import time

import numpy as np
import pytest

from prtbench.api.errors import InvalidInputError
from prtbench.scene.model import Material, Scene, SceneObject, Texture, TriangleMesh
from prtbench.scene.registry import get_scene
from prtbench.transport import sh
from prtbench.transport.bounce_transfer import compute_bounce_transfer
from prtbench.transport.ray_pattern import ShRotation, tangent_frames
from prtbench.transport.raytrace import Tracer
from prtbench.transport.transfer import compute_transfer, compute_transfer_with_stderr
from scenes.primitives import uv_sphere


def _lonely_triangle_scene(center=(0.0, 0.0, 0.0), size=1e-2) -> Scene:
    """One small triangle facing +Z: nothing can occlude a point on it."""
    c = np.asarray(center, dtype=np.float64)
    p = c + np.array([[-size, -size, 0.0], [size, -size, 0.0], [0.0, size, 0.0]])
    mesh = TriangleMesh(p, np.array([[0, 1, 2]]), np.tile([0.0, 0.0, 1.0], (3, 1)))
    return Scene("lonely", [SceneObject("tri", mesh, Material())])


@pytest.fixture
def fresh_cache(tmp_path, monkeypatch):
    root = tmp_path / "cache"
    monkeypatch.setenv("PRTBENCH_CACHE", str(root))
    return root


def _cache_files(root) -> list[str]:
    """Cache entries (``.npz``); their ``.time.json`` compute-time records are not entries."""
    return [os.path.join(d, f) for d, _, files in os.walk(root) for f in files
            if not f.endswith(".time.json")] if root.exists() else []


# --- shadowed transfer ------------------------------------------------------------------------

def test_unoccluded_transfer_matches_the_clamped_cosine_constants():
    scene = _lonely_triangle_scene()
    centre = np.array([[0.0, -1e-2 / 3, 0.0]])
    up = np.array([[0.0, 0.0, 1.0]])
    t, err = compute_transfer_with_stderr(scene, centre, up, bands=3, rays_per_point=4096,
                                          use_cache=False, progress=False)
    expected = np.zeros(9)
    expected[sh.index(0, 0)] = math.sqrt(math.pi) / 2
    expected[sh.index(1, 0)] = math.sqrt(math.pi / 3)
    expected[sh.index(2, 0)] = math.sqrt(5 * math.pi) / 8
    assert (err[0] < 0.05).all() and (err[0] > 0).all()
    assert np.all(np.abs(t[0] - expected) <= 3 * err[0] + 1e-6), (t[0], expected, err[0])
    # The fast path (local accumulation + SH rotation) gives the same numbers.
    fast = compute_transfer(scene, centre, up, bands=3, rays_per_point=4096, use_cache=False,
                            progress=False)
    np.testing.assert_allclose(fast, t, atol=2e-6)


def test_unoccluded_transfer_for_any_normal_is_the_rotated_clamped_cosine():
    # A far-away triangle: points at the origin see the whole sphere of directions.
    scene = _lonely_triangle_scene(center=(50.0, 50.0, 50.0))
    rng = np.random.default_rng(4)
    normals = rng.normal(size=(6, 3))
    normals = np.concatenate([normals, [[0, 0, -1.0], [0, 1.0, 0], [1e-9, 0, 1.0]]])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    points = np.zeros_like(normals)
    bands = 4
    t, err = compute_transfer_with_stderr(scene, points, normals, bands=bands,
                                          rays_per_point=2048, use_cache=False, progress=False)
    # T_lm(n) = √(4π/(2l+1)) g_l Y_lm(n) for the clamped cosine lobe g about n.
    ls, _ = sh.lm_of(bands)
    kernel = np.sqrt(4 * np.pi / (2 * ls + 1)) * sh.clamped_cosine_zonal(bands)[ls]
    expected = sh.eval_sh(normals, bands) * kernel
    assert np.all(np.abs(t - expected) <= 3 * err + 1e-6)
    assert err.max() < 0.06
    fast = compute_transfer(scene, points, normals, bands=bands, rays_per_point=2048,
                            use_cache=False, progress=False)
    np.testing.assert_allclose(fast, t, atol=2e-6)


def test_sh_rotation_matches_direct_evaluation():
    rng = np.random.default_rng(5)
    normals = np.concatenate([rng.normal(size=(20, 3)), [[0, 0, 1.0], [0, 0, -1.0], [1e-12, 0, -1]]])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    frames = tangent_frames(normals, rng.random(len(normals)) * 2 * np.pi)
    world_from_local = frames.transpose(0, 2, 1)
    np.testing.assert_allclose(np.linalg.det(world_from_local), 1.0, atol=1e-12)
    bands = 7
    local = rng.normal(size=(5, 3))
    local /= np.linalg.norm(local, axis=1, keepdims=True)
    rotate = ShRotation(bands)
    for d in local:
        # D(R)·Y(ω) = Y(Rω): the rotated delta function's coefficients.
        got = rotate(np.tile(sh.eval_sh(d[None], bands), (len(normals), 1)), world_from_local)
        np.testing.assert_allclose(got, sh.eval_sh(world_from_local @ d, bands), atol=1e-10)


def test_coefficient_major_rotation_is_the_point_major_one_in_place():
    """rotate_columns on (n², N) is __call__ on (N, n²), in place; both rotate each point as
    rotating it alone does (to rounding: BLAS takes another kernel for one row)."""
    rng = np.random.default_rng(7)
    normals = rng.normal(size=(33, 3))
    normals[:3] = [[0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [1e-12, 0.0, 1.0]]  # the gimbal cases
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    world_from_local = tangent_frames(normals, rng.uniform(0, 2 * np.pi, len(normals))
                                      ).transpose(0, 2, 1)
    for bands in (1, 2, 5, 9):
        rotate = ShRotation.for_bands(bands)
        coeffs = rng.normal(size=(len(normals), bands * bands))
        before = coeffs.copy()
        expected = np.stack([rotate(c[None], r[None])[0] for c, r in zip(coeffs, world_from_local)])
        rotated = rotate(coeffs, world_from_local)
        assert rotated.flags.c_contiguous
        np.testing.assert_allclose(rotated, expected, rtol=0, atol=1e-13)
        np.testing.assert_array_equal(coeffs, before)  # __call__ leaves its input alone
        columns = np.ascontiguousarray(coeffs.T)
        assert rotate.rotate_columns(columns, world_from_local) is columns
        np.testing.assert_array_equal(columns.T, rotated)
        # F-ordered input (its transpose is already C-contiguous) is copied, not overwritten.
        fortran = np.asfortranarray(coeffs)
        np.testing.assert_array_equal(rotate(fortran, world_from_local), rotated)
        np.testing.assert_array_equal(fortran, before)
    assert ShRotation.for_bands(5) is ShRotation.for_bands(5)
    shared = ShRotation.for_bands(5)
    assert not any(b.flags.writeable for b in shared.x_minus + shared.x_plus)  # shared constants


def test_sphere_over_plane_below_the_sphere_sees_one_minus_r_over_h_squared():
    r, h = 0.5, 1.0
    scene = get_scene("sphere-over-plane", radius=r, height=h)
    t, err = compute_transfer_with_stderr(scene, np.zeros((1, 3)), np.array([[0.0, 1.0, 0.0]]),
                                          bands=2, rays_per_point=8192, use_cache=False,
                                          progress=False)
    white = math.sqrt(4 * math.pi)  # the constant light L(ω) = 1 has L_00 = √(4π)
    unoccluded = white * t[0, 0]
    assert unoccluded == pytest.approx(math.pi * (1 - (r / h) ** 2), abs=3 * white * float(err[0, 0]))
    assert white * err[0, 0] < 0.05
    # The blocked cone is centred on the normal: its transfer keeps the zonal structure.
    assert abs(t[0, sh.index(1, 1)]) <= 3 * err[0, sh.index(1, 1)] + 1e-6
    assert abs(t[0, sh.index(1, 0)]) <= 3 * err[0, sh.index(1, 0)] + 1e-6


#: How far one point's transfer may move when its rays are summed in chunks of another size:
#: a few float32 roundings of coefficients of order 1 (the SH products are float32).
CHUNKING_ATOL = 2e-6


def test_results_do_not_depend_on_chunking_and_follow_the_seed():
    scene = get_scene("sphere-over-plane", sphere_segments=16)
    positions, normals, _, _ = scene.merged()
    tracer = Tracer.from_scene(scene)
    kw = dict(bands=3, rays_per_point=64, use_cache=False, progress=False, tracer=tracer)
    a = compute_transfer(scene, positions, normals, **kw)
    b = compute_transfer(scene, positions, normals, chunk_points=7, **kw)
    # The same rays in other chunks: equal up to float32 rounding, not bit for bit, since
    # OpenBLAS may sum a product of another shape in another kernel (on an AMD EPYC 65 % of
    # these coefficients differ, by at most 2.4e-7; a point given another point's rays
    # would differ by ~0.1).
    np.testing.assert_allclose(a, b, rtol=0, atol=CHUNKING_ATOL)
    assert np.abs(a).max() > 0.5
    # The rays do not depend on the band count: fewer bands are exactly a truncation.
    np.testing.assert_allclose(compute_transfer(scene, positions, normals, **{**kw, "bands": 2}),
                               a[:, :4], atol=1e-6)
    c = compute_transfer(scene, positions, normals, seed=1, **kw)
    assert not np.array_equal(a, c)
    # Different seeds agree statistically (white-light irradiance within a few percent on average).
    assert np.abs(a[:, 0] - c[:, 0]).mean() < 0.05 * np.abs(a[:, 0]).mean()
    assert a.dtype == np.float32 and a.shape == (len(positions), 9)


def test_padded_chunks_agree_with_whole_rounds_of_patterns():
    # 32-point chunks hold whole rounds of the 16 patterns; 40-point chunks (and the ragged
    # 8-point tail) are padded to whole rounds with zero-visibility rows. Both take one
    # stacked float32 matmul per chunk and agree to float32 rounding; rays beyond SUM_BLOCK
    # go in blocks (M = 300: two blocks, the second zero-padded), likewise. (Bit for bit on
    # an AVX-512 Xeon; on an AMD EPYC OpenBLAS rounds 1.6 % of them differently, by 7.5e-9.)
    from prtbench.transport import transfer as tr

    scene = get_scene("sphere-over-plane", sphere_segments=16, plane_subdivisions=4)
    positions, normals, _, _ = scene.merged()
    assert len(positions) >= 139
    tracer = Tracer.from_scene(scene)
    stacked = np.matmul
    for rays, blocks in ((48, 1), (300, 2)):
        calls = []

        def counting(*args, **kwargs):
            if np.ndim(args[0]) == 4:  # the projection's (not the ray directions')
                calls.append((np.shape(args[0]), np.asarray(args[0]).dtype))
            return stacked(*args, **kwargs)

        kw = dict(bands=6, rays_per_point=rays, use_cache=False, progress=False, tracer=tracer)
        whole = compute_transfer(scene, positions[:128], normals[:128], chunk_points=32, **kw)
        try:
            tr.np.matmul = counting
            padded = compute_transfer(scene, positions[:128], normals[:128], chunk_points=40,
                                      **kw)
        finally:
            tr.np.matmul = stacked
        k = min(rays, tr.SUM_BLOCK)
        # chunks 0-40, 40-80, 80-120 and 120-128: 3, 3, 3 and 1 -> 2 rows per pattern
        # (in any order: the chunks run on the precompute threads)
        expected = [((16, blocks, r, k), np.dtype(np.float32)) for r in (2, 3, 3, 3)]
        assert sorted(calls, key=lambda c: c[0]) == expected, calls
        np.testing.assert_allclose(padded, whole, rtol=0, atol=CHUNKING_ATOL)
        assert np.abs(padded).max() > 0.1


def test_default_chunks_start_short_and_cover_every_point_once():
    # The first default chunk is half a chunk, so that the precompute threads do not trace in
    # lockstep (they would all reach their numpy SH sums together); a job that fits one chunk
    # stays one chunk (the tracer then splits its rays over the threads). Nothing here
    # depends on the thread count.
    from prtbench.transport.transfer import LEAD_CHUNK_FRACTION, MAX_RAYS_PER_CHUNK, point_chunks

    step = MAX_RAYS_PER_CHUNK // 256
    sizes = [c.stop - c.start for c in point_chunks(4 * step, 256, None)]
    assert sizes == [int(step * LEAD_CHUNK_FRACTION)] + [step] * 3 + [step - sizes[0]]
    assert LEAD_CHUNK_FRACTION < 1
    for n_points in (0, 1, step - 1, step, step + 1, 3 * step + 5):
        chunks = point_chunks(n_points, 256, None)
        covered = np.concatenate([np.arange(c.start, c.stop) for c in chunks] + [[]])
        np.testing.assert_array_equal(covered, np.arange(n_points))
        if n_points <= step:
            assert len(chunks) == min(n_points, 1)
        assert max((c.stop - c.start for c in chunks), default=0) <= step
    # An explicit chunk size is taken as it is.
    assert [c.stop - c.start for c in point_chunks(10, 256, 4)] == [4, 4, 2]


def test_blas_thread_count_is_restored_after_the_loop():
    from prtbench.transport.parallel import _openblas_threads

    threads = _openblas_threads()
    if threads is None:
        pytest.skip("numpy is not linked against its bundled OpenBLAS")
    before = threads[0]()
    compute_transfer(_lonely_triangle_scene(), np.zeros((2, 3)), np.tile([0, 0, 1.0], (2, 1)),
                     bands=2, rays_per_point=8, use_cache=False, progress=False)
    assert threads[0]() == before


def test_progress_bar_goes_to_stderr(capsys):
    scene = _lonely_triangle_scene()
    compute_transfer(scene, np.zeros((3, 3)), np.tile([0, 0, 1.0], (3, 1)), bands=2,
                     rays_per_point=16, use_cache=False, progress=True)
    out, err = capsys.readouterr()
    assert out == "" and "transfer lonely" in err


def test_bad_inputs_raise_one_line_errors():
    scene = _lonely_triangle_scene()
    p, n = np.zeros((2, 3)), np.tile([0, 0, 1.0], (2, 1))
    kw = dict(use_cache=False, progress=False)
    with pytest.raises(InvalidInputError, match="normals"):
        compute_transfer(scene, p, n[:1], bands=2, rays_per_point=8, **kw)
    with pytest.raises(InvalidInputError, match="zero-length"):
        compute_transfer(scene, p, np.zeros((2, 3)), bands=2, rays_per_point=8, **kw)
    with pytest.raises(InvalidInputError, match="bands"):
        compute_transfer(scene, p, n, bands=0, rays_per_point=8, **kw)
    with pytest.raises(InvalidInputError, match="rays_per_point"):
        compute_transfer(scene, p, n, bands=2, rays_per_point=0, **kw)
    assert compute_transfer(scene, np.zeros((0, 3)), np.zeros((0, 3)), bands=2,
                            rays_per_point=8, **kw).shape == (0, 4)


# --- cache --------------------------------------------------------------------------------------

def test_second_call_hits_the_cache_and_a_corrupt_file_is_recomputed(fresh_cache, monkeypatch):
    scene = get_scene("sphere-over-plane", sphere_segments=16)
    positions, normals, _, _ = scene.merged()
    kw = dict(bands=3, rays_per_point=32, progress=False)
    first = compute_transfer(scene, positions, normals, **kw)
    files = _cache_files(fresh_cache)
    assert len(files) == 1 and files[0].endswith(".npz")

    def no_tracing(*args, **kwargs):
        raise AssertionError("a cache hit must not trace rays")

    with monkeypatch.context() as m:
        m.setattr(Tracer, "occluded", no_tracing)
        again = compute_transfer(scene, positions, normals, **kw)
    np.testing.assert_array_equal(again, first)
    # Any change of an input is a different key.
    other = compute_transfer(scene, positions, normals, bands=3, rays_per_point=32, seed=2,
                             progress=False)
    assert not np.array_equal(other, first) and len(_cache_files(fresh_cache)) == 2

    with open(files[0], "r+b") as fh:  # corrupt the first entry in place
        fh.seek(200)
        fh.write(b"\x00garbage\x00" * 8)
    recomputed = compute_transfer(scene, positions, normals, **kw)
    np.testing.assert_array_equal(recomputed, first)


def test_interrupt_leaves_nothing_in_the_cache(fresh_cache):
    scene = get_scene("sphere-over-plane", sphere_segments=16)
    positions, normals, _, _ = scene.merged()
    tracer = Tracer.from_scene(scene)
    calls = []

    def interrupted(origins, directions, **kwargs):
        calls.append(len(origins))
        if len(calls) == 2:  # the first chunk went through: stop in the middle
            raise KeyboardInterrupt
        return np.zeros(len(origins), dtype=bool)

    tracer.occluded = interrupted
    with pytest.raises(KeyboardInterrupt):
        compute_transfer(scene, positions, normals, bands=3, rays_per_point=16, chunk_points=50,
                         progress=False, tracer=tracer)
    assert len(calls) >= 2
    assert _cache_files(fresh_cache) == []


# --- interreflection ----------------------------------------------------------------------------

def _inside_sphere_scene(kd, segments=24) -> Scene:
    ball = uv_sphere(radius=1.0, segments=segments)
    inside = TriangleMesh(ball.positions, ball.faces[:, ::-1], -ball.normals)  # facing the centre
    return Scene("cavity", [SceneObject("cavity", inside, Material(kd=kd))])


def test_closed_cavity_with_uniform_irradiance_sums_the_geometric_series():
    # Furnace-style: give every vertex the same zero-bounce transfer c. Every ray from the inside
    # of a closed sphere hits its front side, so T^b = ρ^b c exactly, per channel.
    kd = (0.6, 0.3, 0.0)
    scene = _inside_sphere_scene(kd)
    positions, normals, _, _ = scene.merged()
    c = np.zeros((len(positions), 4))
    c[:, 0], c[:, 2] = 1.0, -0.25
    totals = []
    for bounces in range(4):
        out = compute_bounce_transfer(scene, positions, normals, vertex_transfer=c,
                                      bounces=bounces, rays_per_point=32, use_cache=False,
                                      progress=False)
        assert out.shape == (len(positions), 4, 3) and out.dtype == np.float32
        series = np.array([sum(rho**b for b in range(bounces + 1)) for rho in kd])
        np.testing.assert_allclose(out, c[:, :, None] * series, rtol=1e-5, atol=1e-6)
        totals.append(out[:, 0, :])
    increments = np.diff(np.array(totals), axis=0)  # T^1, T^2, T^3 (coefficient 0)
    assert (increments[:, :, :2] > 0).all()
    np.testing.assert_allclose(increments[1:, :, 0] / increments[:-1, :, 0], 0.6, rtol=1e-5)
    # Points that are not the vertex set: T^0 is gathered there (0: no light gets in), then the
    # bounces iterate on the vertices and are gathered at the points.
    pts = np.array([[0.0, -0.9, 0.0], [0.3, 0.2, -0.5]])
    nrm = np.array([[0.0, 1.0, 0.0], [0.0, -1.0, 0.0]])
    out = compute_bounce_transfer(scene, pts, nrm, vertex_transfer=c, bounces=3,
                                  rays_per_point=32, use_cache=False, progress=False)
    series = np.array([rho + rho**2 + rho**3 for rho in kd])
    np.testing.assert_allclose(out, np.broadcast_to(c[:2, :, None] * series, out.shape),
                               rtol=1e-5, atol=1e-6)


def test_one_bounce_below_a_sphere_gathers_its_form_factor_and_back_faces_give_nothing():
    r, h, rays = 0.5, 1.0, 8192
    scene = get_scene("sphere-over-plane", radius=r, height=h, sphere_segments=32)
    positions, _, _, object_of_face = scene.merged()
    n_ground = scene.objects[0].mesh.n_vertices
    c = np.zeros((len(positions), 1))
    c[n_ground:, 0] = 1.0  # only the sphere carries (synthetic) zero-bounce transfer
    point, up = np.zeros((1, 3)), np.array([[0.0, 1.0, 0.0]])
    t0 = compute_transfer(scene, point, up, bands=1, rays_per_point=rays, use_cache=False,
                          progress=False)
    out = compute_bounce_transfer(scene, point, up, vertex_transfer=c, bounces=1,
                                  rays_per_point=rays, use_cache=False, progress=False)
    kd = np.array(scene.objects[1].material.kd)
    # The cosine-weighted fraction of rays hitting the sphere is (r/h)²; each brings kd · 1.
    fraction = (r / h) ** 2
    sigma = math.sqrt(fraction * (1 - fraction) / rays)  # i.i.d. bound on the hit fraction
    np.testing.assert_allclose(out[0, 0] - t0[0, 0], kd * fraction, atol=3 * sigma)

    # The same sphere turned inside out: the point sees only its back faces.
    ball = scene.objects[1].mesh
    flipped = TriangleMesh(ball.positions, ball.faces[:, ::-1], -ball.normals)
    turned = Scene("turned", [scene.objects[0],
                              SceneObject("ball", flipped, scene.objects[1].material)])
    out = compute_bounce_transfer(turned, point, up, vertex_transfer=c, bounces=1,
                                  rays_per_point=rays, use_cache=False, progress=False)
    np.testing.assert_allclose(out[0, 0], t0[0, 0], rtol=1e-6)


def test_bounces_on_a_real_scene_grow_monotonically_and_converge():
    scene = get_scene("sphere-over-plane", sphere_segments=16, plane_subdivisions=4)
    positions, normals, _, _ = scene.merged()
    kw = dict(rays_per_point=64, use_cache=False, progress=False)
    t0 = compute_transfer(scene, positions, normals, bands=2, **kw)
    totals = [compute_bounce_transfer(scene, positions, normals, vertex_transfer=t0, bounces=b, **kw)
              for b in range(4)]
    np.testing.assert_allclose(totals[0], np.repeat(t0[:, :, None], 3, axis=2))
    dc = np.array([t[:, 0, :] for t in totals])  # white-light part, (bounces, V, 3)
    steps = np.diff(dc, axis=0)
    assert (steps >= -1e-7).all() and (steps.sum(axis=1) > 0).all()
    # Geometric convergence: a gather averages its rays' hits (each weighted by kd <= max kd), so
    # the largest increment shrinks at least by max(kd) per bounce and channel.
    max_kd = np.max([o.material.kd for o in scene.objects], axis=0)
    largest = steps.max(axis=1)  # (bounce, channel)
    assert (largest[1:] <= max_kd * largest[:-1] + 1e-6).all()
    assert (largest[1:] < largest[:-1]).all()


def test_zero_albedo_gives_back_the_shadowed_transfer():
    scene = get_scene("sphere-over-plane", sphere_segments=16)
    black = Scene("black", [SceneObject(o.name, o.mesh, Material(kd=(0.0, 0.0, 0.0)))
                            for o in scene.objects])
    positions, normals, _, _ = black.merged()
    t0 = compute_transfer(black, positions, normals, bands=3, rays_per_point=32, use_cache=False,
                          progress=False)
    out = compute_bounce_transfer(black, positions, normals, vertex_transfer=t0, bounces=3,
                                  rays_per_point=32, use_cache=False, progress=False)
    np.testing.assert_array_equal(out, np.repeat(t0[:, :, None], 3, axis=2))


def test_textured_albedo_is_sampled_at_the_hit_and_needs_uvs():
    constant = _inside_sphere_scene((0.5, 0.25, 0.125), segments=16)
    mesh = constant.objects[0].mesh
    uvs = np.random.default_rng(6).random((mesh.n_vertices, 2))
    image = np.broadcast_to(np.array([0.5, 0.25, 0.125], np.float32), (4, 4, 3))
    textured = Scene("textured", [SceneObject(
        "cavity", TriangleMesh(mesh.positions, mesh.faces, mesh.normals, uvs),
        Material(kd=Texture(np.array(image), name="flat")))])
    positions, normals, _, _ = constant.merged()
    c = np.ones((len(positions), 1))
    kw = dict(vertex_transfer=c, bounces=2, rays_per_point=16, use_cache=False, progress=False)
    np.testing.assert_allclose(compute_bounce_transfer(textured, positions, normals, **kw),
                               compute_bounce_transfer(constant, positions, normals, **kw),
                               rtol=1e-6)
    no_uvs = Scene("no-uvs", [SceneObject("cavity", mesh, Material(kd=Texture(np.array(image))))])
    with pytest.raises(InvalidInputError, match="uvs"):
        compute_bounce_transfer(no_uvs, positions, normals, **kw)


def test_bounce_input_errors_and_cache(fresh_cache):
    scene = _inside_sphere_scene((0.5, 0.5, 0.5), segments=12)
    positions, normals, _, _ = scene.merged()
    with pytest.raises(InvalidInputError, match="vertex_transfer shape"):
        compute_bounce_transfer(scene, positions, normals, vertex_transfer=np.ones((3, 4)),
                                bounces=1, rays_per_point=8, progress=False)
    with pytest.raises(InvalidInputError, match="bounces"):
        compute_bounce_transfer(scene, positions, normals,
                                vertex_transfer=np.ones((len(positions), 4)), bounces=-1,
                                rays_per_point=8, progress=False)
    kw = dict(vertex_transfer=np.ones((len(positions), 4)), bounces=2, rays_per_point=8,
              progress=False)
    first = compute_bounce_transfer(scene, positions, normals, **kw)
    assert len(_cache_files(fresh_cache)) == 1
    start = time.perf_counter()
    again = compute_bounce_transfer(scene, positions, normals, **kw)
    assert time.perf_counter() - start < 1.0
    np.testing.assert_array_equal(again, first)
