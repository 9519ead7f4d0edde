#version 430
// Factored BRDF (factored-brdf; Wang et al. 2004): per vertex, J light dot products with the
// view-independent transfer vectors T^j (SH of V·h_j), weighted by the outgoing factors g_j
// looked up at the view direction in the vertex's local frame. The fragment stage
// (interpolated_radiance.frag) interpolates the radiance.
//
// Defines: SH_BANDS (1..8), TERMS (J).
// Binding 0: T, vertex-major float32 (V, J, n²).
// outgoing_factors: (materials·J) RGB layers of an R × 4R table; s = φ/(2π) repeating,
// t = θ/(π/2) clamped (prtbench/compress/factor.py, HemisphereGrid); layer material·J + j.
#include "sh.glsl"

layout(std430, binding = 0) readonly buffer FactoredTransfer { float factored_transfer[]; };

uniform sampler2DArray outgoing_factors;
uniform mat4 clip_from_world;
uniform vec3 eye;
uniform vec3 light_sh[SH_COEFFS];

in vec3 in_position;
in vec3 normal;
in vec3 tangent;
in vec3 bitangent;
in float material;

out vec3 radiance;

const float PI = 3.14159265358979;

void main() {
    vec3 n = normalize(normal);
    vec3 wo = normalize(eye - in_position);
    vec3 local = vec3(dot(wo, tangent), dot(wo, bitangent), dot(wo, n));
    float theta = acos(clamp(local.z, -1.0, 1.0));
    // atan(0, 0) is undefined in GLSL: at the pole every φ reads the same first row anyway.
    float phi = length(local.xy) > 1e-12 ? atan(local.y, local.x) : 0.0;
    if (phi < 0.0) {
        phi += 2.0 * PI;
    }
    vec2 st = vec2(phi / (2.0 * PI), min(theta, 0.5 * PI) / (0.5 * PI));
    int layer = int(material + 0.5) * TERMS;
    int base = gl_VertexID * TERMS * SH_COEFFS;
    vec3 sum = vec3(0.0);
    for (int j = 0; j < TERMS; ++j) {
        vec3 lit = vec3(0.0);
        int row = base + j * SH_COEFFS;
        for (int i = 0; i < SH_COEFFS; ++i) {
            lit += factored_transfer[row + i] * light_sh[i];
        }
        sum += textureLod(outgoing_factors, vec3(st, float(layer + j)), 0.0).rgb * lit;
    }
    radiance = sum;
    gl_Position = clip_from_world * vec4(in_position, 1.0);
}
