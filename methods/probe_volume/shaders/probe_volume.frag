#version 430
// Probe volume (methods.probe_volume.method): per pixel, the 8 probes of the cell around
// p + normal_bias·n, weighted (TEST 0: trilinear; 1: invalid probes left out; 2: also DDGI's
// smooth back-face term and Chebyshev visibility from the probes' depth moments), their pool
// texels decoded (probe_decode.glsl, generated from methods.probe_volume.encoding), then
//   relight, SH:   R = Γ(V, L) (triple_product), E = Σ_l Â_l Σ_m R_lm Y_lm(n);
//   relight, cube: C_d = a_d · E_L(d) for the three axes n faces, E = Σ_i n_i² C_i;
//   fixed, SH:     E = Σ_l Â_l Σ_m R_lm Y_lm(n);   fixed, cube: E = Σ_i n_i² C_i;
// and B = kd/π · E. Back faces are black.
// Defines: COEFFS, CHANNELS (1 relight, 3 fixed), RELIGHT, CUBE, SH_BANDS, BRICKS, GRID_N
// (uniform), TEST, DEPTH_TEXELS and DEPTH_TILES_X (TEST 2).
layout(early_fragment_tests) in;

// sh.glsl (SH_BANDS) and triple_product (relight SH; the Γ list at binding 1).
#include "prt_shading.glsl"
#include "probe_decode.glsl"

#if CHANNELS == 3
#define COEFF vec3
#else
#define COEFF float
#endif

uniform sampler3D probe_valid;     // 1 where the probe is valid (R8)
uniform vec3 volume_origin;        // the lattice's corner
uniform vec3 cell_size;            // grid cell (uniform) or finest cell (bricks)
uniform float normal_bias;         // in cells of cell_size
uniform float zonal[SH_BANDS];     // clamped-cosine g_l
#if BRICKS
uniform usampler3D brick_index;    // slot | level << 24 per finest brick
uniform ivec3 pool_bricks;         // pool slots per axis
#endif
#if TEST == 2
uniform sampler2D depth_moments;   // RG: mean, mean² hit distance; one D×D tile per probe
#endif
#if RELIGHT
uniform vec3 light_sh[SH_COEFFS];
#endif

in vec3 world_position;
in vec3 world_normal;
in vec3 albedo;

out vec4 color;

#if TEST == 2
vec2 oct_encode(vec3 d) {
    vec2 p = d.xy / (abs(d.x) + abs(d.y) + abs(d.z));
    if (d.z < 0.0) {
        vec2 s = vec2(p.x >= 0.0 ? 1.0 : -1.0, p.y >= 0.0 ? 1.0 : -1.0);
        p = (1.0 - abs(p.yx)) * s;
    }
    return p * 0.5 + 0.5;
}

// Bilinear within the probe's own tile (clamped at its edges).
vec2 probe_depth(int id, vec3 dir) {
    ivec2 tile = ivec2(id % DEPTH_TILES_X, id / DEPTH_TILES_X) * DEPTH_TEXELS;
    vec2 uv = oct_encode(dir) * float(DEPTH_TEXELS) - 0.5;
    ivec2 i0 = ivec2(floor(uv));
    vec2 f = uv - vec2(i0);
    ivec2 lo = clamp(i0, ivec2(0), ivec2(DEPTH_TEXELS - 1));
    ivec2 hi = clamp(i0 + 1, ivec2(0), ivec2(DEPTH_TEXELS - 1));
    vec2 a = texelFetch(depth_moments, tile + ivec2(lo.x, lo.y), 0).rg;
    vec2 b = texelFetch(depth_moments, tile + ivec2(hi.x, lo.y), 0).rg;
    vec2 c = texelFetch(depth_moments, tile + ivec2(lo.x, hi.y), 0).rg;
    vec2 d = texelFetch(depth_moments, tile + ivec2(hi.x, hi.y), 0).rg;
    return mix(mix(a, b, f.x), mix(c, d, f.x), f.y);
}
#endif

void main() {
    if (!gl_FrontFacing) {  // one-sided surfaces: seen from behind is black
        color = vec4(0.0, 0.0, 0.0, 1.0);
        return;
    }
    vec3 n = normalize(world_normal);
    vec3 p = world_position + normal_bias * n * cell_size;

    // The cell: its corner probe's texel, world position and id, and the probes' spacing.
#if BRICKS
    vec3 brick_size = 3.0 * cell_size;
    ivec3 sides = textureSize(brick_index, 0);
    ivec3 fine = clamp(ivec3(floor((p - volume_origin) / brick_size)), ivec3(0), sides - 1);
    uint entry = texelFetch(brick_index, fine, 0).r;
    int slot = int(entry & 0xFFFFFFu);
    int level = int(entry >> 24);
    int span = level == 0 ? 1 : (level == 1 ? 3 : 9);  // finest bricks per axis of the leaf
    vec3 brick_origin = volume_origin + vec3((fine / span) * span) * brick_size;
    vec3 spacing = cell_size * float(span);
    vec3 g = clamp((p - brick_origin) / spacing, vec3(0.0), vec3(3.0));
    ivec3 base = min(ivec3(floor(g)), ivec3(2));
    ivec3 slot_texel = 4 * ivec3(slot % pool_bricks.x, (slot / pool_bricks.x) % pool_bricks.y,
                                 slot / (pool_bricks.x * pool_bricks.y));
    ivec3 base_texel = slot_texel + base;
    vec3 base_world = brick_origin + vec3(base) * spacing;
#else
    vec3 spacing = cell_size;
    vec3 g = clamp((p - volume_origin) / spacing, vec3(0.0), vec3(float(GRID_N - 1)));
    ivec3 base = min(ivec3(floor(g)), ivec3(GRID_N - 2));
    ivec3 base_texel = base;
    vec3 base_world = volume_origin + vec3(base) * spacing;
#endif
    vec3 f = g - vec3(base);

    float weight[8];
    float weight_sum = 0.0;
    for (int c = 0; c < 8; ++c) {
        ivec3 corner = ivec3(c & 1, (c >> 1) & 1, (c >> 2) & 1);
        vec3 w3 = mix(vec3(1.0) - f, f, vec3(corner));
        float w = w3.x * w3.y * w3.z;
#if TEST >= 1
        bool valid = texelFetch(probe_valid, base_texel + corner, 0).r > 0.5;
        w = valid ? w : 0.0;
#endif
#if TEST == 2
        if (w > 0.0) {
#if BRICKS
            ivec3 at = base + corner;
            int id = 64 * slot + (at.x * 4 + at.y) * 4 + at.z;
#else
            ivec3 at = base + corner;
            int id = (at.x * GRID_N + at.y) * GRID_N + at.z;
#endif
            vec3 probe = base_world + vec3(corner) * spacing;
            // DDGI (rtxgi DDGIGetVolumeIrradiance): wrap shading towards the probe, the
            // Chebyshev bound of the depth moments, a floor, the crush, then trilinear.
            float wrap = (dot(normalize(probe - world_position), n) + 1.0) * 0.5;
            float dw = wrap * wrap + 0.2;
            vec3 rel = p - probe;
            float dist = length(rel);
            vec2 m = probe_depth(id, dist > 1e-9 ? rel / dist : n);
            float variance = abs(m.x * m.x - m.y);
            float chebyshev = 1.0;
            if (dist > m.x) {
                float v = dist - m.x;
                chebyshev = variance / (variance + v * v);
                chebyshev = max(chebyshev * chebyshev * chebyshev, 0.0);
            }
            dw *= max(0.05, chebyshev);
            dw = max(1e-6, dw);
            if (dw < 0.2) {
                dw *= dw * dw / (0.2 * 0.2);
            }
            w *= dw;
        }
#endif
        weight[c] = w;
        weight_sum += w;
    }
    if (weight_sum <= 1e-9) {  // every corner invalid (inside geometry): plain trilinear
        weight_sum = 0.0;
        for (int c = 0; c < 8; ++c) {
            vec3 w3 = mix(vec3(1.0) - f, f, vec3(ivec3(c & 1, (c >> 1) & 1, (c >> 2) & 1)));
            weight[c] = w3.x * w3.y * w3.z;
            weight_sum += weight[c];
        }
    }

    COEFF acc[COEFFS];
    for (int k = 0; k < COEFFS; ++k) {
        acc[k] = COEFF(0.0);
    }
    for (int c = 0; c < 8; ++c) {
        if (weight[c] <= 0.0) {
            continue;
        }
        COEFF probe[COEFFS];
        probe_coefficients(base_texel + ivec3(c & 1, (c >> 1) & 1, (c >> 2) & 1), probe);
        float w = weight[c] / weight_sum;
        for (int k = 0; k < COEFFS; ++k) {
            acc[k] += w * probe[k];
        }
    }

    vec3 irradiance;
#if CUBE
    vec3 sq = n * n;
    int ax = n.x >= 0.0 ? 0 : 1;
    int ay = n.y >= 0.0 ? 2 : 3;
    int az = n.z >= 0.0 ? 4 : 5;
#if RELIGHT
    // C_d = a_d · E_L(d), the light's L2 irradiance along the three axes n faces.
    vec3 cx = acc[ax] * sh_zonal_eval_rgb(light_sh, zonal, vec3(ax == 0 ? 1.0 : -1.0, 0.0, 0.0));
    vec3 cy = acc[ay] * sh_zonal_eval_rgb(light_sh, zonal, vec3(0.0, ay == 2 ? 1.0 : -1.0, 0.0));
    vec3 cz = acc[az] * sh_zonal_eval_rgb(light_sh, zonal, vec3(0.0, 0.0, az == 4 ? 1.0 : -1.0));
    irradiance = sq.x * cx + sq.y * cy + sq.z * cz;
#else
    irradiance = sq.x * acc[ax] + sq.y * acc[ay] + sq.z * acc[az];
#endif
#elif RELIGHT
    vec3 radiance[SH_COEFFS];
    triple_product(acc, light_sh, radiance);
    irradiance = sh_zonal_eval_rgb(radiance, zonal, n);
#else
    irradiance = sh_zonal_eval_rgb(acc, zonal, n);
#endif
    color = vec4(albedo / SH_PI * irradiance, 1.0);
}
