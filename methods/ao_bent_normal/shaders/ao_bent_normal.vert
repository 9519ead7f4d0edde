#version 430
// AO and bent normal per vertex: radiance = kd/π · AO · E(b), E the Ramamoorthi–Hanrahan
// irradiance of the light's SH L2 at the bent normal b (sh_zonal_eval_rgb with the clamped
// cosine's zonal coefficients). Requires SH_BANDS (3).
#include "sh.glsl"
#include "brdf.glsl"

// (b.x, b.y, b.z, AO) per vertex.
layout(std430, binding = 0) readonly buffer AoBent { vec4 ao_bent[]; };

uniform mat4 clip_from_world;
uniform vec3 light_sh[SH_COEFFS];
uniform float zonal[SH_BANDS];

in vec3 in_position;
in vec3 kd;

out vec3 radiance;

void main() {
    vec4 t = ao_bent[gl_VertexID];
    radiance = kd / BRDF_PI * t.w * sh_zonal_eval_rgb(light_sh, zonal, t.xyz);
    gl_Position = clip_from_world * vec4(in_position, 1.0);
}
