// Test probe for prt_shading.glsl: evaluates every API function for one case, inputs and
// outputs in storage buffers (see tests/prtbench/render/test_prt_shading.py for the layouts).
// Case layout (floats): T[n²], H[n²·3], kd[3], ks[3], s, n[3], wo[3].
// Output layout: H_tp[n²·3], H_tpfl[n²·3], shade[3], g[n].
#include "prt_shading.glsl"

#define IN_STRIDE (SH_COEFFS * 4 + 13)
#define OUT_STRIDE (SH_COEFFS * 6 + 3 + SH_BANDS)

layout(std430, binding = 0) readonly buffer Inputs { float inputs[]; };
layout(std430, binding = 3) writeonly buffer Outputs { float outputs[]; };

uniform vec3 light_sh[SH_COEFFS];

void probe(int case_index) {
    int at = case_index * IN_STRIDE;
    float T[SH_COEFFS];
    vec3 H[SH_COEFFS];
    for (int i = 0; i < SH_COEFFS; ++i) {
        T[i] = inputs[at + i];
        int h = at + SH_COEFFS + 3 * i;
        H[i] = vec3(inputs[h], inputs[h + 1], inputs[h + 2]);
    }
    int p = at + 4 * SH_COEFFS;
    vec3 kd = vec3(inputs[p], inputs[p + 1], inputs[p + 2]);
    vec3 ks = vec3(inputs[p + 3], inputs[p + 4], inputs[p + 5]);
    float s = inputs[p + 6];
    vec3 n = vec3(inputs[p + 7], inputs[p + 8], inputs[p + 9]);
    vec3 wo = vec3(inputs[p + 10], inputs[p + 11], inputs[p + 12]);

    vec3 h_tp[SH_COEFFS];
    vec3 h_tpfl[SH_COEFFS];
    triple_product(T, light_sh, h_tp);
    tpfl_product(T, h_tpfl);
    vec3 shade = shade_transferred(H, kd, ks, s, n, wo);
    float g[SH_BANDS];
    phong_zonal_coeffs(s, g);

    int o = case_index * OUT_STRIDE;
    for (int k = 0; k < SH_COEFFS; ++k) {
        for (int c = 0; c < 3; ++c) {
            outputs[o + 3 * k + c] = h_tp[k][c];
            outputs[o + 3 * SH_COEFFS + 3 * k + c] = h_tpfl[k][c];
        }
    }
    for (int c = 0; c < 3; ++c) {
        outputs[o + 6 * SH_COEFFS + c] = shade[c];
    }
    for (int l = 0; l < SH_BANDS; ++l) {
        outputs[o + 6 * SH_COEFFS + 3 + l] = g[l];
    }
}
