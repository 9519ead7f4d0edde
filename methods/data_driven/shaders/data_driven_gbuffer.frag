#version 430
// Fake G-buffer (Belcour et al. 2022 §4.3): deferred shading of the measurement points.
// Texel (i, s) of the G-buffer textures is sub-point s of measurement point i; the output
// pixel i is the mean outgoing diffuse radiance kd/pi * E over its SUPERSAMPLE sub-points.
#include "data_driven_lights.glsl"

uniform sampler2D g_position;
uniform sampler2D g_normal;
uniform sampler2D g_albedo;
out vec4 radiance;

void main() {
    int i = int(gl_FragCoord.x);
    vec3 sum = vec3(0.0);
    for (int s = 0; s < SUPERSAMPLE; ++s) {
        vec3 p = texelFetch(g_position, ivec2(i, s), 0).xyz;
        vec3 n = texelFetch(g_normal, ivec2(i, s), 0).xyz;
        vec3 kd = texelFetch(g_albedo, ivec2(i, s), 0).rgb;
        sum += kd / BRDF_PI * direct_irradiance(p, n);
    }
    radiance = vec4(sum / float(SUPERSAMPLE), 1.0);
}
