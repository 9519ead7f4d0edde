#version 430
// Ng 2003 wavelet vertex PRT: the CPU has formed each vertex's Σ_i T_i L_i over the k selected
// Haar terms (incident radiance integral, solid angles folded into T); here B = kd/π · that.
// With a compressed transport (compress=pca/vq/cpca, CPCA_OUTPUTS defined) the CPU has instead
// projected the k terms onto each cluster's mean and basis, and the vertex forms its own sum
// from its cluster's table and its n' weights (cpca.glsl, Sloan 2003).
#include "brdf.glsl"

#ifdef CPCA_OUTPUTS
#include "cpca.glsl"
#else
layout(std430, binding = 0) readonly buffer Incident { float incident[]; };
#endif

uniform mat4 clip_from_world;

in vec3 in_position;
in vec3 kd;

out vec3 radiance;

void main() {
#ifdef CPCA_OUTPUTS
    vec3 e = cpca_output(gl_VertexID, cpca_cluster_of(gl_VertexID), 0);
#else
    int base = 3 * gl_VertexID;
    vec3 e = vec3(incident[base], incident[base + 1], incident[base + 2]);
#endif
    radiance = kd / BRDF_PI * e;  // the diffuse term of phong_brdf
    gl_Position = clip_from_world * vec4(in_position, 1.0);
}
