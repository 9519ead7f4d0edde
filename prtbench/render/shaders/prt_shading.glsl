// Shared PRT glossy shading: Phong zonal coefficients, shading of transferred radiance, and the
// two ways to get transferred radiance from a transfer vector (triple product, fixed-light TPFL).
// Used by the vertex methods (vertex-tp, vertex-tpfl, sloan-matrix) and the transfer-texture
// methods (texture-tp, texture-tpfl); keep this API stable.
//
// Requires SH_BANDS (1..8) #defined before inclusion (load_program(defines={"SH_BANDS": n})).
// Includes sh.glsl (SH_COEFFS = SH_BANDS², sh_eval, sh_zonal_eval_rgb) and brdf.glsl.
//
// API
// ---
//   void phong_zonal_coeffs(float s, out float g[SH_BANDS])
//       Zonal coefficients g_l of the normalised Phong lobe (s+1)/(2π)·max(μ,0)^s, equal to
//       prtbench.transport.sh.phong_zonal(s, SH_BANDS) (same ratio recurrence; s in [0, 1e4]).
//   vec3 shade_transferred(vec3 H[SH_COEFFS], vec3 kd, vec3 ks, float s, vec3 n, vec3 wo)
//       Outgoing radiance kd/π·√(4π)·H_0 + ks·Σ_l √(4π/(2l+1))·g_l(s)·Σ_m H_lm Y_lm(r),
//       r = phong_mirror(n, wo); H = SH projection of L·V·max(n·ω, 0) (cosine included),
//       n the unit shading normal, wo the unit direction towards the eye.
//   vec3 shade_transferred_zonal(vec3 H[SH_COEFFS], vec3 kd, vec3 ks, float g[SH_BANDS],
//                                vec3 n, vec3 wo)
//       The same with precomputed g (e.g. per-object constant s).
//   void triple_product(float T[SH_COEFFS], vec3 L[SH_COEFFS], out vec3 H[SH_COEFFS])
//       TP: H_k = Σ_ij Γ_ijk T_i L_j over the sparse Γ list in the SSBO at PRT_GAMMA_BINDING.
//   void tpfl_product(float T[SH_COEFFS], out vec3 H[SH_COEFFS])
//       TPFL: H_k = Σ_i T_i M_ik with M = prtbench.transport.sh.tpfl_matrix(L, SH_BANDS) in the SSBO at
//       PRT_TPFL_BINDING.
//
// Buffer bindings (std430 shader storage buffers; override the defaults by #defining the
// names before inclusion). Binding 0 is left to the method's per-vertex / per-texel data.
//   PRT_GAMMA_BINDING = 1: Γ non-zeros, one PrtGammaEntry {uint ijk; float value;} (8 bytes) per
//       entry, ijk = i | (j << 8) | (k << 16); the entry count is the buffer length (the whole
//       buffer must hold exactly the list). Built by prtbench.render.prt_shading.gamma_entries(n).
//   PRT_TPFL_BINDING = 2: M in a std140 UNIFORM block, one vec4 (rgb, pad) per (i, k), entry
//       i·n² + k (n⁴·16 bytes: 64 KiB at 8 bands, the GL minimum block size limit). Built by
//       prtbench.render.prt_shading.tpfl_buffer_data(light, n). Uniform reads are ~7× cheaper than storage-
//       buffer reads in llvmpipe fragment shaders. #define PRT_TPFL_SSBO to read M instead from
//       a std430 storage buffer at the same binding, float32 (n², n², 3) C-order
//       (prtbench.render.prt_shading.tpfl_buffer_data(light, n, ssbo=True)).
// The light SH is passed by value (typically a `uniform vec3 light_sh[SH_COEFFS]`, (n², 3) RGB).
#ifndef PRTBENCH_PRT_SHADING_GLSL
#define PRTBENCH_PRT_SHADING_GLSL

#include "sh.glsl"
#include "brdf.glsl"

#ifndef PRT_GAMMA_BINDING
#define PRT_GAMMA_BINDING 1
#endif
#ifndef PRT_TPFL_BINDING
#define PRT_TPFL_BINDING 2
#endif

struct PrtGammaEntry {
    uint ijk;     // i | (j << 8) | (k << 16)
    float value;  // Γ_ijk = ∫ Y_i Y_j Y_k dω
};

layout(std430, binding = PRT_GAMMA_BINDING) readonly buffer PrtGamma {
    PrtGammaEntry prt_gamma[];
};

#ifdef PRT_TPFL_SSBO
layout(std430, binding = PRT_TPFL_BINDING) readonly buffer PrtTpfl {
    float prt_tpfl[];
};
#else
layout(std140, binding = PRT_TPFL_BINDING) uniform PrtTpflBlock {
    vec4 prt_tpfl_m[SH_COEFFS * SH_COEFFS];
};
#endif

// g_l = N_l (s+1) I_l with I_0 = 1/(s+1), I_1 = 1/(s+2), I_l = (s−l+2)/(s+l+1) I_{l−2}
// (prtbench.transport.sh._legendre_moments). Carrying r_l = (s+1) I_l directly keeps every step a ratio
// of comparable numbers, so float32 is accurate up to s = 1e4 (r_0 = 1 exactly).
void phong_zonal_coeffs(float s, out float g[SH_BANDS]) {
    float r_prev2 = 1.0;                  // r_{l-2}
    float r_prev = (s + 1.0) / (s + 2.0); // r_{l-1}
    for (int l = 0; l < SH_BANDS; ++l) {
        float r;
        if (l == 0) {
            r = 1.0;
        } else if (l == 1) {
            r = r_prev;
        } else {
            float fl = float(l);
            r = (s - fl + 2.0) / (s + fl + 1.0) * r_prev2;
            r_prev2 = r_prev;
            r_prev = r;
        }
        g[l] = sqrt(float(2 * l + 1) / (4.0 * SH_PI)) * r;
    }
}

vec3 shade_transferred_zonal(vec3 H[SH_COEFFS], vec3 kd, vec3 ks, float g[SH_BANDS], vec3 n,
                             vec3 wo) {
    // ∫ Y_00 dω = √(4π): the diffuse term integrates H against the constant kd/π.
    vec3 radiance = kd / BRDF_PI * (3.5449077018110318 * H[0]);
    if (any(greaterThan(ks, vec3(0.0)))) {
        radiance += ks * sh_zonal_eval_rgb(H, g, phong_mirror(n, wo));
    }
    return radiance;
}

vec3 shade_transferred(vec3 H[SH_COEFFS], vec3 kd, vec3 ks, float s, vec3 n, vec3 wo) {
    float g[SH_BANDS];
    phong_zonal_coeffs(s, g);
    return shade_transferred_zonal(H, kd, ks, g, n, wo);
}

void triple_product(float T[SH_COEFFS], vec3 L[SH_COEFFS], out vec3 H[SH_COEFFS]) {
    for (int k = 0; k < SH_COEFFS; ++k) {
        H[k] = vec3(0.0);
    }
    int count = prt_gamma.length();
    for (int e = 0; e < count; ++e) {
        uint ijk = prt_gamma[e].ijk;
        int i = int(ijk & 0xFFu);
        int j = int((ijk >> 8) & 0xFFu);
        int k = int(ijk >> 16);
        H[k] += (prt_gamma[e].value * T[i]) * L[j];
    }
}

void tpfl_product(float T[SH_COEFFS], out vec3 H[SH_COEFFS]) {
    for (int k = 0; k < SH_COEFFS; ++k) {
        H[k] = vec3(0.0);
    }
    for (int i = 0; i < SH_COEFFS; ++i) {
#ifdef PRT_TPFL_SSBO
        int row = i * SH_COEFFS * 3;
        for (int k = 0; k < SH_COEFFS; ++k) {
            int at = row + 3 * k;
            H[k] += T[i] * vec3(prt_tpfl[at], prt_tpfl[at + 1], prt_tpfl[at + 2]);
        }
#else
        int row = i * SH_COEFFS;
        for (int k = 0; k < SH_COEFFS; ++k) {
            H[k] += T[i] * prt_tpfl_m[row + k].xyz;
        }
#endif
    }
}

#endif  // PRTBENCH_PRT_SHADING_GLSL
