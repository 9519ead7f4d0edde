#version 430
// Sloan 2002 diffuse PRT: radiance B = kd/π · Σ_i T_i L_i, evaluated per vertex.
#include "brdf.glsl"

#ifdef CPCA_OUTPUTS
// Compressed transfer (compress=pca/vq/cpca): see cpca.glsl.
#include "cpca.glsl"
#else
layout(std430, binding = 0) readonly buffer Transfer { float transfer[]; };
#endif

uniform mat4 clip_from_world;
uniform vec3 light_sh[SH_COEFFS];

in vec3 in_position;
in vec3 kd;

out vec3 radiance;

void main() {
#ifdef CPCA_OUTPUTS
    vec3 incident = cpca_output(gl_VertexID, cpca_cluster_of(gl_VertexID), 0);
#else
    vec3 incident = vec3(0.0);
    int base = gl_VertexID * SH_COEFFS * TRANSFER_CHANNELS;
    for (int i = 0; i < SH_COEFFS; ++i) {
#if TRANSFER_CHANNELS == 1
        incident += transfer[base + i] * light_sh[i];
#else
        int k = base + 3 * i;
        incident += vec3(transfer[k], transfer[k + 1], transfer[k + 2]) * light_sh[i];
#endif
    }
#endif
    radiance = kd / BRDF_PI * incident;  // the diffuse term of phong_brdf
    gl_Position = clip_from_world * vec4(in_position, 1.0);
}
