#version 430
// Glossy vertex PRT (vertex-tp, vertex-tpfl, sloan-matrix): per vertex, the transferred
// incident radiance H (SH projection of L·V·max(n·ω, 0)), then the Phong shading of
// prt_shading.glsl towards the eye. The fragment stage (interpolated_radiance.frag) interpolates it.
//
// Defines: SH_BANDS (1..8), GLOSSY_MODE: 0 = triple product T ⊗ L over the Γ list (binding 1),
// 1 = TPFL H_k = Σ_i T_i M_ik with the per-light matrix (binding 2), 2 = Sloan's transfer
// matrix, H_k = Σ_i M_ki L_i.
// Binding 0: per-vertex data, vertex-major float32: T (V, n²) for modes 0/1, M (V, n², n²) for 2.
// MATRIX_RGB (mode 2, sloan-matrix with bounces): interreflected RGB matrices (V, n², n², 3),
// H_kc = Σ_i M_kic L_ic.
#include "prt_shading.glsl"

#ifdef CPCA_OUTPUTS
// Compressed matrices (sloan-matrix compress=pca/vq/cpca): H from cpca.glsl.
#include "cpca.glsl"
#else
layout(std430, binding = 0) readonly buffer VertexTransfer { float vertex_transfer[]; };
#endif

uniform mat4 clip_from_world;
uniform vec3 eye;
uniform vec3 light_sh[SH_COEFFS];

in vec3 in_position;
in vec3 normal;
in vec3 kd;
in vec3 ks;
in float shininess;

out vec3 radiance;

void main() {
    vec3 H[SH_COEFFS];
#if GLOSSY_MODE == 2 && defined(CPCA_OUTPUTS)
    int cluster = cpca_cluster_of(gl_VertexID);
    for (int k = 0; k < SH_COEFFS; ++k) {
        H[k] = cpca_output(gl_VertexID, cluster, k);
    }
#elif GLOSSY_MODE == 2 && defined(MATRIX_RGB)
    int base = gl_VertexID * SH_COEFFS * SH_COEFFS * 3;
    for (int k = 0; k < SH_COEFFS; ++k) {
        vec3 sum = vec3(0.0);
        int row = base + k * SH_COEFFS * 3;
        for (int i = 0; i < SH_COEFFS; ++i) {
            int at = row + i * 3;
            sum += vec3(vertex_transfer[at], vertex_transfer[at + 1], vertex_transfer[at + 2])
                   * light_sh[i];
        }
        H[k] = sum;
    }
#elif GLOSSY_MODE == 2
    int base = gl_VertexID * SH_COEFFS * SH_COEFFS;
    for (int k = 0; k < SH_COEFFS; ++k) {
        vec3 sum = vec3(0.0);
        int row = base + k * SH_COEFFS;
        for (int i = 0; i < SH_COEFFS; ++i) {
            sum += vertex_transfer[row + i] * light_sh[i];
        }
        H[k] = sum;
    }
#else
    float T[SH_COEFFS];
    int base = gl_VertexID * SH_COEFFS;
    for (int i = 0; i < SH_COEFFS; ++i) {
        T[i] = vertex_transfer[base + i];
    }
#if GLOSSY_MODE == 0
    triple_product(T, light_sh, H);
#else
    tpfl_product(T, H);
#endif
#endif
    vec3 n = normalize(normal);
    vec3 wo = normalize(eye - in_position);
    radiance = shade_transferred(H, kd, ks, shininess, n, wo);
    gl_Position = clip_from_world * vec4(in_position, 1.0);
}
