// Analytic lights with shadow maps, shared by the data-driven method's passes.
// Light i: type 0 directional, 1 point, 2 spot (Mitsuba's linear angular falloff).
// Tiles of the shadow atlas store a linear metric: the distance to the light (perspective
// tiles) or the depth along the light's travel direction (orthographic tiles).
#ifndef DATA_DRIVEN_LIGHTS_GLSL
#define DATA_DRIVEN_LIGHTS_GLSL

#include "brdf.glsl"

uniform int n_lights;
uniform vec4 light_pos_type[MAX_LIGHTS];   // xyz: position, or direction to the light; w: type
uniform vec4 light_axis_cos[MAX_LIGHTS];   // xyz: spot axis; w: cos(cutoff)
uniform vec4 light_power_tile[MAX_LIGHTS]; // rgb: intensity (W/sr) or irradiance; w: first tile
uniform vec4 light_cone[MAX_LIGHTS];       // x: cutoff (rad), y: cos(beam), z: 1/(cutoff-beam), w: tiles
uniform mat4 tile_matrix[MAX_TILES];       // clip_from_world of each shadow tile
uniform vec4 tile_rect[MAX_TILES];         // xy: atlas texel offset, z: side, w: texel size factor
uniform vec4 tile_ref[MAX_TILES];          // xyz: light position (w=1) or travel direction (w=0)
uniform sampler2D shadow_atlas;
uniform vec2 shadow_bias;                  // x: normal offset, y: depth bias (in texels)

float shadow_tap(ivec2 texel, ivec2 lo, ivec2 hi, float receiver) {
    float occluder = texelFetch(shadow_atlas, clamp(texel, lo, hi), 0).r;
    return receiver <= occluder ? 1.0 : 0.0;
}

// Fraction of a 2x2 bilinear PCF footprint that sees the light from p (normal n).
float tile_visibility(int t, vec3 p, vec3 n) {
    vec4 rect = tile_rect[t];
    vec4 ref = tile_ref[t];
    float dist = ref.w > 0.5 ? length(p - ref.xyz) : 1.0;
    float texel_world = rect.w * dist;
    vec3 q = p + n * (shadow_bias.x * texel_world);
    vec4 clip = tile_matrix[t] * vec4(q, 1.0);
    if (clip.w <= 0.0) return 1.0;
    vec2 ndc = clip.xy / clip.w;
    if (any(greaterThan(abs(ndc), vec2(1.0)))) return 1.0;
    float receiver = (ref.w > 0.5 ? length(q - ref.xyz) : dot(q, ref.xyz))
                     - shadow_bias.y * texel_world;
    vec2 f = (ndc * 0.5 + 0.5) * rect.z - 0.5;
    vec2 base = floor(f);
    vec2 w = f - base;
    ivec2 lo = ivec2(rect.xy);
    ivec2 hi = lo + ivec2(int(rect.z) - 1);
    ivec2 b = lo + ivec2(base);
    float v00 = shadow_tap(b, lo, hi, receiver);
    float v10 = shadow_tap(b + ivec2(1, 0), lo, hi, receiver);
    float v01 = shadow_tap(b + ivec2(0, 1), lo, hi, receiver);
    float v11 = shadow_tap(b + ivec2(1, 1), lo, hi, receiver);
    return mix(mix(v00, v10, w.x), mix(v01, v11, w.x), w.y);
}

// Cube tiles are ordered +X, -X, +Y, -Y, +Z, -Z (the face a direction from the light leaves by).
int cube_face(vec3 d) {
    vec3 a = abs(d);
    if (a.x >= a.y && a.x >= a.z) return d.x > 0.0 ? 0 : 1;
    if (a.y >= a.z) return d.y > 0.0 ? 2 : 3;
    return d.z > 0.0 ? 4 : 5;
}

// Shadowed irradiance at p with shading normal n: sum over lights of E V max(n.l, 0).
vec3 direct_irradiance(vec3 p, vec3 n) {
    vec3 total = vec3(0.0);
    for (int i = 0; i < n_lights; ++i) {
        vec4 pt = light_pos_type[i];
        vec3 to_light;
        vec3 power = light_power_tile[i].rgb;
        int type = int(pt.w + 0.5);
        if (type == 0) {
            to_light = pt.xyz;
        } else {
            vec3 d = pt.xyz - p;
            float dist2 = max(dot(d, d), 1e-12);
            to_light = d * inversesqrt(dist2);
            power /= dist2;
            if (type == 2) {
                float cos_t = dot(-to_light, light_axis_cos[i].xyz);
                vec4 cone = light_cone[i];
                float ramp = cos_t >= cone.y ? 1.0 : (cone.x - acos(clamp(cos_t, -1.0, 1.0))) * cone.z;
                power *= cos_t > light_axis_cos[i].w ? ramp : 0.0;
            }
        }
        float cos_n = dot(n, to_light);
        if (cos_n <= 0.0 || max(power.r, max(power.g, power.b)) <= 0.0) continue;
        int tile = int(light_power_tile[i].w + 0.5);
        if (int(light_cone[i].w + 0.5) == 6) tile += cube_face(p - pt.xyz);
        total += power * (cos_n * tile_visibility(tile, p, n));
    }
    return total;
}

#endif  // DATA_DRIVEN_LIGHTS_GLSL
