#version 430
// Learnt transfer, GLSL path (thesis §4.1.4.1): after an early depth pre-pass, each visible
// fragment evaluates the MLP with hard-coded weights at its world position and normal, turns
// the transfer T into transferred radiance H with the light (TPFL: the thesis's global light
// matrix, or TP) and shades H with the Phong BRDF (prt_shading.glsl). Back faces are black.
// Defines: SH_BANDS, LEARNT_PRODUCT_TP (0/1); generated includes from methods/learnt/glsl.py.
layout(early_fragment_tests) in;

#include "prt_shading.glsl"
#include "learnt_partition_data.glsl"
#include "learnt_weights.glsl"
#include "learnt_mlp.glsl"
#include "learnt_partition.glsl"

uniform vec3 eye;
#if LEARNT_PRODUCT_TP
uniform vec3 light_sh[SH_COEFFS];
#endif

in vec3 world_position;
in vec3 world_normal;
in vec3 v_kd;
in vec3 v_ks;
in float v_shininess;
flat in int v_object;

out vec4 color;

void main() {
    if (!gl_FrontFacing) {
        color = vec4(0.0, 0.0, 0.0, 1.0);
        return;
    }
    vec3 n = normalize(world_normal);
    float T[SH_COEFFS];
    learnt_transfer(learnt_group(world_position, v_object), world_position, n, T);
    vec3 H[SH_COEFFS];
#if LEARNT_PRODUCT_TP
    triple_product(T, light_sh, H);
#else
    tpfl_product(T, H);
#endif
    vec3 wo = normalize(eye - world_position);
    color = vec4(shade_transferred(H, v_kd, v_ks, v_shininess, n, wo), 1.0);
}
