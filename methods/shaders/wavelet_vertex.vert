#version 430
// Ng 2003 wavelet vertex PRT: the CPU has formed each vertex's Σ_i T_i L_i over the k selected
// Haar terms (incident radiance integral, solid angles folded into T); here B = kd/π · that.
#include "brdf.glsl"

layout(std430, binding = 0) readonly buffer Incident { float incident[]; };

uniform mat4 clip_from_world;

in vec3 in_position;
in vec3 kd;

out vec3 radiance;

void main() {
    int base = 3 * gl_VertexID;
    vec3 e = vec3(incident[base], incident[base + 1], incident[base + 2]);
    radiance = kd / BRDF_PI * e;  // the diffuse term of phong_brdf
    gl_Position = clip_from_world * vec4(in_position, 1.0);
}
