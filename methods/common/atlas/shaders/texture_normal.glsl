// Tangent-space normal mapping shared by the transfer-texture G-buffer pass and the shading
// pass (PRTT §6.2), so the transfer is computed at exactly the normal the renderer shades with.
// The numpy twin is methods.common.atlas.shading.apply_normal_map (used for bounce hits).
#ifndef PRTBENCH_TEXTURE_NORMAL_GLSL
#define PRTBENCH_TEXTURE_NORMAL_GLSL

// n: interpolated vertex normal (any length); tangent.xyz: interpolated dP/du direction,
// tangent.w: handedness (+1 when the bitangent is cross(n, t)); texel: the normal map's RGB
// in [0, 1], storing (n_T, n_B, n_N)·0.5 + 0.5. Returns the unit shading normal.
vec3 apply_normal_map(vec3 n, vec4 tangent, vec3 texel) {
    vec3 nn = normalize(n);
    // Gram–Schmidt: interpolation leaves t slightly off the plane perpendicular to n.
    vec3 t = tangent.xyz - nn * dot(nn, tangent.xyz);
    float len_t = length(t);
    if (len_t < 1e-12) {
        return nn;  // no usable tangent frame (no UV gradient): keep the geometric normal
    }
    t /= len_t;
    vec3 b = (tangent.w < 0.0 ? -1.0 : 1.0) * cross(nn, t);
    vec3 m = texel * 2.0 - 1.0;
    vec3 shading = m.x * t + m.y * b + m.z * nn;
    float len_s = length(shading);
    return len_s > 1e-12 ? shading / len_s : nn;
}

#endif  // PRTBENCH_TEXTURE_NORMAL_GLSL
