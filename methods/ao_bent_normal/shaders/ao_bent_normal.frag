#version 430
// AO and bent normal per texel of the atlas, shading pass: radiance = kd/π · AO · E(b), E the
// Ramamoorthi–Hanrahan irradiance of the light's SH L2 at the bent normal b, sampled bilinearly
// and renormalised. Back faces are black.
// Defines: SH_BANDS (3), UNORM8 (1: texels hold 0.5 + 0.5·b and AO in 8-bit unorm; 0: raw).
layout(early_fragment_tests) in;

#include "sh.glsl"
#include "brdf.glsl"

uniform sampler2DArray ao_bent;  // layer = texture set
uniform vec3 light_sh[SH_COEFFS];
uniform float zonal[SH_BANDS];

in vec3 normal;
in vec2 atlas_uv;
flat in vec3 kd;
flat in int texture_set;

out vec4 color;

void main() {
    if (!gl_FrontFacing) {  // one-sided surfaces: seen from behind is black
        color = vec4(0.0, 0.0, 0.0, 1.0);
        return;
    }
    vec4 t = texture(ao_bent, vec3(atlas_uv, float(texture_set)));
#if UNORM8
    vec3 b = t.xyz * 2.0 - 1.0;
#else
    vec3 b = t.xyz;
#endif
    // Bilinear filtering shortens b between texels of diverging bent normals.
    float len_b = length(b);
    b = len_b > 1e-6 ? b / len_b : normalize(normal);
    color = vec4(kd / BRDF_PI * t.w * sh_zonal_eval_rgb(light_sh, zonal, b), 1.0);
}
