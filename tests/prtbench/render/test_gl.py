"""prtbench.render.gl and the shared shader includes (sh.glsl, brdf.glsl) on the headless EGL context.

Stage files for these tests are written to a temporary directory (``search_path``); they
include the real ``methods/shaders`` files, which is what is under test.
"""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest

from prtbench.api.errors import InvalidInputError, PrtbenchError, UnknownNameError
from prtbench.io.imageio import linear_to_srgb
from prtbench.render import gl
from prtbench.transport.sh import eval_sh, phong_zonal, zonal_convolve

FULLSCREEN_VERT = """#version 330
// One triangle covering the viewport, no vertex inputs.
void main() {
    vec2 corner = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2);
    gl_Position = vec4(corner * 2.0 - 1.0, 0.0, 1.0);
}
"""

SH_FRAG = """#version 330
#include "sh.glsl"
uniform sampler2D u_dirs;
uniform int u_base;
layout(location = 0) out vec4 out0;
layout(location = 1) out vec4 out1;
layout(location = 2) out vec4 out2;
layout(location = 3) out vec4 out3;

float coeff(float y[SH_COEFFS], int i) {
    return i < SH_COEFFS ? y[i] : 0.0;
}

vec4 group(float y[SH_COEFFS], int first) {
    return vec4(coeff(y, first), coeff(y, first + 1), coeff(y, first + 2), coeff(y, first + 3));
}

void main() {
    float y[SH_COEFFS];
    sh_eval(texelFetch(u_dirs, ivec2(gl_FragCoord.xy), 0).xyz, y);
    out0 = group(y, u_base);
    out1 = group(y, u_base + 4);
    out2 = group(y, u_base + 8);
    out3 = group(y, u_base + 12);
}
"""

ZONAL_FRAG = """#version 330
#include "sh.glsl"
uniform sampler2D u_axes;
uniform vec3 u_coeffs[SH_COEFFS];
uniform float u_zonal[SH_BANDS];
out vec4 color;
void main() {
    vec3 axis = texelFetch(u_axes, ivec2(gl_FragCoord.xy), 0).xyz;
    float coeffs_r[SH_COEFFS];
    for (int i = 0; i < SH_COEFFS; ++i) coeffs_r[i] = u_coeffs[i].r;
    color = vec4(sh_zonal_eval_rgb(u_coeffs, u_zonal, axis), sh_zonal_eval(coeffs_r, u_zonal, axis));
}
"""

BRDF_FRAG = """#version 330
#include "brdf.glsl"
uniform sampler2D u_n_s;
uniform sampler2D u_wi;
uniform sampler2D u_wo;
uniform sampler2D u_kd;
uniform sampler2D u_ks;
layout(location = 0) out vec4 out_brdf;
layout(location = 1) out vec4 out_srgb;
void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec4 n_s = texelFetch(u_n_s, p, 0);
    vec3 kd = texelFetch(u_kd, p, 0).rgb;
    out_brdf = vec4(phong_brdf(kd, texelFetch(u_ks, p, 0).rgb, n_s.w, n_s.xyz,
                               texelFetch(u_wi, p, 0).xyz, texelFetch(u_wo, p, 0).xyz), 0.0);
    out_srgb = vec4(srgb_from_linear(kd * 3.0 - 1.0), 0.0);
}
"""

MESH_VERT = """#version 330
in vec3 in_position;
in vec3 in_color;
in float in_unused_by_fragment;
out vec3 color;
void main() {
    color = in_color;
    gl_Position = vec4(in_position, 1.0);
}
"""

MESH_FRAG = """#version 330
in vec3 color;
out vec4 out_color;
void main() { out_color = vec4(color, 1.0); }
"""

VALUE_FRAG = """#version 330
uniform vec4 u_value;
layout(location = 0) out vec4 out0;
layout(location = 1) out vec4 out1;
void main() {
    out0 = u_value;
    out1 = -2.0 * u_value + vec4(VALUE_OFFSET);
}
"""


@pytest.fixture(scope="module")
def ctx():
    try:
        return gl.create_context()
    except gl.GLUnavailableError as exc:  # test_context_starts reports the failure itself
        pytest.skip(str(exc))


@pytest.fixture()
def shader_files(tmp_path):
    """Write stage files into tmp_path; returns that directory for ``search_path``."""
    sources = {"fullscreen.vert.glsl": FULLSCREEN_VERT, "sh_eval.frag.glsl": SH_FRAG,
               "zonal.frag.glsl": ZONAL_FRAG, "brdf.frag.glsl": BRDF_FRAG,
               "mesh.vert.glsl": MESH_VERT, "mesh.frag.glsl": MESH_FRAG,
               "value.frag.glsl": VALUE_FRAG}
    for name, text in sources.items():
        (tmp_path / name).write_text(text)
    return tmp_path


def _float_texture(ctx, data: np.ndarray):
    """An RGBA32F texture holding (H, W, 4) ``data`` with texel (x, y) = data[y, x]."""
    data = np.ascontiguousarray(data, dtype=np.float32)
    tex = ctx.texture((data.shape[1], data.shape[0]), 4, data.tobytes(), dtype="f4")
    tex.filter = (ctx.NEAREST, ctx.NEAREST)
    return tex


def _fullscreen(ctx, program, target):
    target.use()
    target.clear()
    vao = ctx.vertex_array(program, [])
    vao.render(vertices=3)
    vao.release()


def _test_directions() -> np.ndarray:
    """(16, 24, 3) unit directions: a θ–φ grid with the poles, the axes and random ones."""
    rng = np.random.default_rng(7)
    theta, phi = np.meshgrid(np.linspace(0, np.pi, 16), np.linspace(0, 2 * np.pi, 24), indexing="ij")
    dirs = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], -1)
    special = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    random = rng.normal(size=(18, 3))
    dirs[1, :24] = np.concatenate([special, random / np.linalg.norm(random, axis=1, keepdims=True)])
    return dirs


def test_context_starts_and_names_renderer():
    ctx = gl.create_context()
    assert gl.create_context() is ctx  # process-wide singleton
    assert ctx.version_code >= 330
    renderer = gl.renderer_string(ctx)
    assert " / " in renderer and len(renderer) > 5
    assert renderer == gl.renderer_string()


def test_render_target_round_trips_unclamped_floats(ctx, shader_files):
    program = gl.load_program(ctx, "fullscreen.vert", "value.frag", search_path=[shader_files],
                              defines={"VALUE_OFFSET": 0.5})
    value = np.array([-2.5, 1.0e5, 0.125, 3.75], np.float32)
    program["u_value"].value = tuple(value)
    target = gl.RenderTarget(ctx, 5, 3, attachments=2)
    _fullscreen(ctx, program, target)
    first, second = target.read(0), target.read(1)
    assert first.shape == (3, 5, 4) and first.dtype == np.float32
    np.testing.assert_array_equal(first, np.broadcast_to(value, first.shape))
    np.testing.assert_array_equal(second, np.broadcast_to(-2 * value + 0.5, second.shape))
    with pytest.raises(InvalidInputError):
        target.read(2)
    target.release()


def test_render_target_rejects_bad_sizes(ctx):
    with pytest.raises(InvalidInputError, match="size"):
        gl.RenderTarget(ctx, 0, 4)
    with pytest.raises(InvalidInputError, match="attachments"):
        gl.RenderTarget(ctx, 4, 4, attachments=99)


def test_read_row_zero_is_top_and_upload_mesh_binds_by_name(ctx, shader_files):
    program = gl.load_program(ctx, "mesh.vert", "mesh.frag", search_path=[shader_files])
    # One triangle inside the top half of clip space (y > 0), colour per vertex.
    positions = np.array([[-0.9, 0.1, 0.0], [0.9, 0.1, 0.0], [0.0, 0.9, 0.0]], np.float32)
    colors = np.array([[1.0, 2.0, 3.0]] * 3, np.float32)
    vao = gl.upload_mesh(ctx, program, positions, np.array([[0, 1, 2]]),
                         attributes={"in_color": colors, "in_unused_by_fragment": np.zeros(3),
                                     "in_not_in_program": np.ones((3, 2))})
    assert vao.extra["bytes"] == 3 * 3 * 4 + 3 * 3 * 4 + 3 * 4  # unused inputs were skipped
    target = gl.RenderTarget(ctx, 16, 16)
    target.use()
    target.clear()
    vao.render()
    image = target.read()
    covered = image[..., 3] > 0
    assert covered[:8].sum() > 20  # drawn rows are at the top of the array
    assert not covered[8:].any()
    np.testing.assert_array_equal(image[covered][:, :3], np.broadcast_to([1, 2, 3], (covered.sum(), 3)))
    target.release()


def test_upload_mesh_rejects_bad_indices(ctx, shader_files):
    program = gl.load_program(ctx, "mesh.vert", "mesh.frag", search_path=[shader_files])
    with pytest.raises(InvalidInputError, match="face indices"):
        gl.upload_mesh(ctx, program, np.zeros((3, 3)), np.array([[0, 1, 3]]))
    with pytest.raises(InvalidInputError, match="in_color"):
        gl.upload_mesh(ctx, program, np.zeros((3, 3)), np.array([[0, 1, 2]]),
                       attributes={"in_color": np.zeros((4, 3))})


def test_gpu_timer_reports_positive_finite_times(ctx, shader_files):
    program = gl.load_program(ctx, "fullscreen.vert", "value.frag", search_path=[shader_files],
                              defines={"VALUE_OFFSET": 0})
    target = gl.RenderTarget(ctx, 64, 64, attachments=2)
    vao = ctx.vertex_array(program, [])
    target.use()
    times = gl.GpuTimer(ctx).time_frames(lambda: vao.render(vertices=3), warmup=2, frames=7)
    assert len(times.samples_ms) == 7
    assert 0 < times.median_ms < 1e4 and math.isfinite(times.p95_ms)
    assert min(times.samples_ms) <= times.median_ms <= times.p95_ms <= max(times.samples_ms)
    with pytest.raises(InvalidInputError, match="warmup"):
        gl.GpuTimer(ctx).time_frames(lambda: None, warmup=0)
    target.release()


def test_compile_error_names_file_and_line(ctx, shader_files):
    (shader_files / "broken.frag.glsl").write_text(
        "#version 330\nout vec4 color;\nvoid main() {\n    color = vec4(1.0)\n}\n")
    with pytest.raises(PrtbenchError, match=r"broken\.frag\.glsl' line 5"):
        gl.load_program(ctx, "fullscreen.vert", "broken.frag", search_path=[shader_files],
                        defines={"UNUSED": 1, "ALSO_UNUSED": 2.0})


def test_compile_error_inside_include_names_the_include(ctx, shader_files):
    (shader_files / "bad_include.glsl").write_text("float helper() {\n    return 1.0 +;\n}\n")
    (shader_files / "uses_bad.frag.glsl").write_text(
        '#version 330\n#include "bad_include.glsl"\nout vec4 color;\nvoid main() { color = vec4(helper()); }\n')
    with pytest.raises(PrtbenchError, match=r"bad_include\.glsl' line 2"):
        gl.load_program(ctx, "fullscreen.vert", "uses_bad.frag", search_path=[shader_files])


def test_link_error_is_a_prtbench_error(ctx, shader_files):
    # The stages disagree on the type of `varying`: each compiles, linking fails.
    (shader_files / "gives_vec3.vert.glsl").write_text(
        "#version 330\nout vec3 varying_value;\n"
        "void main() { varying_value = vec3(1.0); gl_Position = vec4(0.0); }\n")
    (shader_files / "wants_vec4.frag.glsl").write_text(
        "#version 330\nin vec4 varying_value;\nout vec4 color;\nvoid main() { color = varying_value; }\n")
    with pytest.raises(PrtbenchError, match="link error in 'gives_vec3.vert.glsl', 'wants_vec4.frag.glsl'"):
        gl.load_program(ctx, "gives_vec3.vert", "wants_vec4.frag", search_path=[shader_files])


def test_include_is_resolved_recursively_and_once(ctx, shader_files):
    # No include guards: a second textual copy would redefine the function and fail to compile.
    (shader_files / "leaf.glsl").write_text("float leaf_value() { return 0.25; }\n")
    (shader_files / "middle.glsl").write_text(
        '#include "leaf.glsl"\nfloat middle_value() { return 2.0 * leaf_value(); }\n')
    (shader_files / "twice.frag.glsl").write_text(
        '#version 330\n#include "middle.glsl"\n#include "leaf.glsl"\n#include "middle.glsl"\n'
        "out vec4 color;\nvoid main() { color = vec4(middle_value() + leaf_value() + EXTRA); }\n")
    program = gl.load_program(ctx, "fullscreen.vert", "twice.frag", search_path=[shader_files],
                              defines={"EXTRA": 1.5})
    target = gl.RenderTarget(ctx, 2, 2)
    _fullscreen(ctx, program, target)
    np.testing.assert_array_equal(target.read(), np.full((2, 2, 4), 0.5 + 0.25 + 1.5, np.float32))
    target.release()


def test_missing_shader_is_an_unknown_name(ctx, shader_files):
    with pytest.raises(UnknownNameError, match="no_such_stage"):
        gl.load_program(ctx, "fullscreen.vert", "no_such_stage.frag", search_path=[shader_files])
    (shader_files / "missing_include.frag.glsl").write_text('#version 330\n#include "nope.glsl"\n')
    with pytest.raises(UnknownNameError, match="nope.glsl"):
        gl.load_program(ctx, "fullscreen.vert", "missing_include.frag", search_path=[shader_files])


@pytest.mark.parametrize("bands", range(1, 9))
def test_sh_glsl_matches_eval_sh(ctx, shader_files, bands):
    dirs = _test_directions()
    h, w, _ = dirs.shape
    program = gl.load_program(ctx, "fullscreen.vert", "sh_eval.frag", search_path=[shader_files],
                              defines={"SH_BANDS": bands})
    dirs_texture = _float_texture(ctx, np.concatenate([dirs, np.zeros((h, w, 1))], -1))
    dirs_texture.use(0)  # sampler uniforms default to unit 0 (one band has no u_dirs at all)
    target = gl.RenderTarget(ctx, w, h, attachments=4)
    n = bands * bands
    coefficients = []
    for base in range(0, n, 16):
        program["u_base"].value = base
        _fullscreen(ctx, program, target)
        # read() puts row 0 at the top; the direction texture's row 0 is GL's bottom row.
        coefficients += [target.read(k)[::-1] for k in range(4)]
    got = np.concatenate(coefficients, axis=-1)[..., :n].reshape(-1, n)
    expected = eval_sh(dirs.reshape(-1, 3).astype(np.float32), bands)
    assert np.abs(got - expected).max() < 1e-4
    target.release()
    dirs_texture.release()


def test_sh_zonal_eval_matches_zonal_convolve(ctx, shader_files):
    bands = 5
    rng = np.random.default_rng(3)
    axes = rng.normal(size=(4, 8, 3))
    axes /= np.linalg.norm(axes, axis=-1, keepdims=True)
    coeffs = rng.normal(size=(bands * bands, 3))
    zonal = phong_zonal(12.0, bands)
    program = gl.load_program(ctx, "fullscreen.vert", "zonal.frag", search_path=[shader_files],
                              defines={"SH_BANDS": bands})
    texture = _float_texture(ctx, np.concatenate([axes, np.zeros((4, 8, 1))], -1))
    texture.use(0)
    program["u_axes"].value = 0
    program["u_coeffs"].write(coeffs.astype(np.float32).tobytes())
    program["u_zonal"].write(zonal.astype(np.float32).tobytes())
    target = gl.RenderTarget(ctx, 8, 4)
    _fullscreen(ctx, program, target)
    got = target.read()[::-1]
    expected = zonal_convolve(coeffs.T[:, None, None, :], zonal, axes.astype(np.float32)).transpose(1, 2, 0)
    scale = np.abs(expected).max()
    assert np.abs(got[..., :3] - expected).max() < 1e-5 * max(scale, 1.0)
    assert np.abs(got[..., 3] - expected[..., 0]).max() < 1e-5 * max(scale, 1.0)
    target.release()
    texture.release()


def test_phong_brdf_and_srgb_match_numpy(ctx, shader_files):
    rng = np.random.default_rng(11)
    h, w = 8, 16

    def unit(shape):
        v = rng.normal(size=shape + (3,))
        return v / np.linalg.norm(v, axis=-1, keepdims=True)

    n, wo = unit((h, w)), unit((h, w))
    mirror = 2 * np.sum(n * wo, -1, keepdims=True) * n - wo
    # Half the incident directions near the mirror direction so the lobe is well exercised.
    wi = unit((h, w))
    wi[::2] = mirror[::2] + 0.2 * unit((h // 2, w))
    wi /= np.linalg.norm(wi, axis=-1, keepdims=True)
    s = rng.choice([0.0, 1.0, 7.5, 64.0, 1000.0], size=(h, w, 1))
    kd, ks = rng.random((h, w, 3)), rng.random((h, w, 3))
    f32 = [a.astype(np.float32).astype(np.float64) for a in (n, wi, wo, kd, ks, s)]
    n, wi, wo, kd, ks, s = f32
    r = 2 * np.sum(n * wo, -1, keepdims=True) * n - wo
    cos_r = np.sum(wi * r, -1, keepdims=True)
    # Zero behind the mirror plane at every s, s = 0 included (the reference's convention).
    lobe = np.where(cos_r > 0, np.maximum(cos_r, 0) ** s, 0.0)
    expected = kd / np.pi + ks * (s + 1) / (2 * np.pi) * lobe

    program = gl.load_program(ctx, "fullscreen.vert", "brdf.frag", search_path=[shader_files])
    zero = np.zeros((h, w, 1))
    textures = [_float_texture(ctx, np.concatenate(parts, -1)) for parts in
                ((n, s), (wi, zero), (wo, zero), (kd, zero), (ks, zero))]
    for unit_index, (name, texture) in enumerate(zip(["u_n_s", "u_wi", "u_wo", "u_kd", "u_ks"], textures)):
        texture.use(unit_index)
        program[name].value = unit_index
    target = gl.RenderTarget(ctx, w, h, attachments=2)
    _fullscreen(ctx, program, target)
    got = target.read(0)[::-1, :, :3]
    np.testing.assert_allclose(got, expected, rtol=2e-4, atol=1e-6)
    assert (expected > kd / np.pi + 1e-3).sum() > 20  # the specular lobe contributed somewhere
    srgb = target.read(1)[::-1, :, :3]
    np.testing.assert_allclose(srgb, linear_to_srgb(kd * 3 - 1), rtol=1e-5, atol=1e-6)
    target.release()
    for texture in textures:
        texture.release()


def test_error_logs_of_both_driver_families_are_parsed(tmp_path):
    files = [tmp_path / "main.frag.glsl", tmp_path / "sh.glsl"]
    mesa = "GLSL Compiler failed\n\nfragment_shader\n===============\n1:42(7): error: `q' undeclared\n"
    nvidia = ("GLSL Compiler failed\n\nfragment_shader\n===============\n"
              "1(42) : warning C7050: unused\n1(43) : error C0000: syntax error, unexpected '}'\n")
    assert gl._compile_error_message(mesa, files, files[:1]) == (
        "GLSL error in shader 'sh.glsl' line 42: error: `q' undeclared")
    assert gl._compile_error_message(nvidia, files, files[:1]) == (
        "GLSL error in shader 'sh.glsl' line 43: error C0000: syntax error, unexpected '}'")


def test_unavailable_gl_names_the_packages(monkeypatch):
    import moderngl

    def no_display(**kwargs):
        raise Exception("eglGetDisplay failed")

    monkeypatch.setattr(gl, "_context", None)
    monkeypatch.setattr(moderngl, "create_standalone_context", no_display)
    with pytest.raises(gl.GLUnavailableError) as info:
        gl.create_context()
    message = str(info.value)
    assert "libegl1 libegl-mesa0 libgl1-mesa-dri" in message and "eglGetDisplay failed" in message
    assert "\n" not in message and isinstance(info.value, PrtbenchError)


def test_moderngl_is_imported_on_first_gl_use(monkeypatch):
    # Importing prtbench.render.gl (so any method module) must not import moderngl: `prtbench list
    # methods` imports the method modules for their summaries.
    code = ("import sys, prtbench.render.gl as gl\n"
            "before = 'moderngl' in sys.modules\n"
            "constant = gl.moderngl.TRIANGLES\n"
            "print(before, 'moderngl' in sys.modules, constant)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split()[:2] == ["False", "True"]
    import moderngl

    assert gl.moderngl is moderngl
    monkeypatch.setattr(gl, "_context", None)
    monkeypatch.setitem(sys.modules, "moderngl", None)  # what a missing package looks like
    with pytest.raises(gl.GLUnavailableError, match="moderngl is not installed; pip install moderngl"):
        gl.create_context()
    with pytest.raises(AttributeError, match="no attribute 'no_such_thing'"):
        gl.no_such_thing  # noqa: B018 - the module __getattr__ still refuses other names
