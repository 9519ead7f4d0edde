#version 430
// Direct light (shadow-mapped analytic lights) + indirect light blended from the basis
// textures (Belcour et al. 2022 §4.3, §5.2). Mono-channel basis: layer t holds elements
// 4t..4t+3 in RGBA and coefficient texel (t, c) their weights for channel c (a 4x3 matrix per
// texture). Interleaved basis: layer e holds element e's RGB, its weight is texel (e/4, 0)[e%4].
#include "data_driven_lights.glsl"

#if INDIRECT
uniform sampler2DArray basis;
uniform sampler2D coefficients;
#if GAMMA_SPACE
uniform float light_scale;  // the transfer pass divided the direct light by it
#endif
#endif

in vec3 world;
in vec3 shading_normal;
in vec3 albedo;
in vec2 uv;
out vec4 color;

vec3 indirect_radiance() {
    vec3 sum = vec3(0.0);
#if INDIRECT
#if MULTI_CHANNEL
    for (int e = 0; e < N_BASIS; ++e) {
        float w = texelFetch(coefficients, ivec2(e / 4, 0), 0)[e % 4];
        sum += w * texture(basis, vec3(uv, float(e))).rgb;
    }
#else
    for (int t = 0; t < N_TEXTURES; ++t) {
        vec4 b = texture(basis, vec3(uv, float(t)));
        sum += vec3(dot(b, texelFetch(coefficients, ivec2(t, 0), 0)),
                    dot(b, texelFetch(coefficients, ivec2(t, 1), 0)),
                    dot(b, texelFetch(coefficients, ivec2(t, 2), 0)));
    }
#endif
#if GAMMA_SPACE
    sum = light_scale * pow(max(sum, vec3(0.0)), vec3(GAMMA));
#endif
#endif
    return sum;
}

void main() {
    if (!gl_FrontFacing) {  // one-sided surfaces, as in the reference
        color = vec4(0.0, 0.0, 0.0, 1.0);
        return;
    }
    vec3 n = normalize(shading_normal);
    vec3 result = vec3(0.0);
#if DIRECT
    result += albedo / BRDF_PI * direct_irradiance(world, n);
#endif
    result += indirect_radiance();
    color = vec4(result, 1.0);
}
