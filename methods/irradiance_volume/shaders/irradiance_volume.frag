#version 430
// Irradiance volume (Greger et al. 1998): trilinear interpolation of the probes' incident
// radiance SH at p + normal_bias·n (grid units), then diffuse shading by the clamped-cosine
// zonal convolution: B = kd/π · Σ_l sqrt(4π/(2l+1)) g_l Σ_m R_lm Y_lm(n).
// Requires SH_BANDS and GRID_N (probes per axis, >= 2) as defines; with DEPTH_ONLY defined
// it is the empty fragment stage of the depth pre-pass.
#ifdef DEPTH_ONLY
void main() {
}
#else
#include "sh.glsl"

// Coefficient i = a·SH_BANDS + b of probe (x, y, z) is texel (x + a·GRID_N, y, z + b·GRID_N).
uniform sampler3D probe_radiance;
// 1 where the probe is valid, 0 where it sits inside geometry (mostly back-face hits).
uniform sampler3D probe_valid;
uniform vec3 grid_origin;   // position of probe (0, 0, 0)
uniform vec3 cell_size;     // probe spacing per axis
uniform float normal_bias;  // lookup offset along the normal, in cells
uniform float zonal[SH_BANDS];  // clamped-cosine g_l (sh.clamped_cosine_zonal)

in vec3 world_position;
in vec3 world_normal;
in vec3 albedo;

out vec4 color;

void main() {
    if (!gl_FrontFacing) {  // one-sided surfaces: seen from behind is black
        color = vec4(0.0, 0.0, 0.0, 1.0);
        return;
    }
    vec3 n = normalize(world_normal);
    // Offsetting in grid units pushes the lookup one fraction of a cell off axis-aligned walls
    // whatever the cells' aspect ratio.
    vec3 g = clamp((world_position - grid_origin) / cell_size + normal_bias * n,
                   vec3(0.0), vec3(float(GRID_N - 1)));
    ivec3 base = min(ivec3(floor(g)), ivec3(GRID_N - 2));
    vec3 f = g - vec3(base);

    float weight[8];
    float valid_sum = 0.0;
    for (int c = 0; c < 8; ++c) {
        ivec3 corner = ivec3(c & 1, (c >> 1) & 1, (c >> 2) & 1);
        vec3 w3 = mix(vec3(1.0) - f, f, vec3(corner));
        float w = w3.x * w3.y * w3.z;
        bool valid = texelFetch(probe_valid, base + corner, 0).r > 0.5;
        weight[c] = valid ? w : 0.0;
        valid_sum += weight[c];
    }
    if (valid_sum <= 1e-6) {  // every corner inside geometry: plain trilinear
        valid_sum = 0.0;
        for (int c = 0; c < 8; ++c) {
            ivec3 corner = ivec3(c & 1, (c >> 1) & 1, (c >> 2) & 1);
            vec3 w3 = mix(vec3(1.0) - f, f, vec3(corner));
            weight[c] = w3.x * w3.y * w3.z;
            valid_sum += weight[c];
        }
    }

    vec3 coeffs[SH_COEFFS];
    for (int i = 0; i < SH_COEFFS; ++i) {
        coeffs[i] = vec3(0.0);
    }
    for (int c = 0; c < 8; ++c) {
        if (weight[c] <= 0.0) {
            continue;
        }
        ivec3 probe = base + ivec3(c & 1, (c >> 1) & 1, (c >> 2) & 1);
        float w = weight[c] / valid_sum;
        for (int i = 0; i < SH_COEFFS; ++i) {
            ivec3 texel = probe + ivec3((i / SH_BANDS) * GRID_N, 0, (i % SH_BANDS) * GRID_N);
            coeffs[i] += w * texelFetch(probe_radiance, texel, 0).rgb;
        }
    }
    vec3 irradiance = sh_zonal_eval_rgb(coeffs, zonal, n);
    color = vec4(albedo / SH_PI * irradiance, 1.0);
}
#endif  // DEPTH_ONLY
