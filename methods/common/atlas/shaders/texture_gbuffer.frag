#version 430
// PRTT Algorithm 2, fragment stage: world position and (shading) normal of the surface point
// nearest to the texel centre, plus the chart id that dilation uses to keep charts apart.
#include "texture_normal.glsl"

uniform sampler2D normal_map;

flat in vec2 texel_a;
flat in vec2 texel_b;
flat in vec2 texel_c;
flat in vec3 position_a;
flat in vec3 position_b;
flat in vec3 position_c;
flat in vec3 normal_a;
flat in vec3 normal_b;
flat in vec3 normal_c;
flat in vec2 mesh_uv_a;
flat in vec2 mesh_uv_b;
flat in vec2 mesh_uv_c;
flat in vec4 tangent_a;
flat in vec4 tangent_b;
flat in vec4 tangent_c;
flat in float chart;
flat in float normal_mapped;

layout(location = 0) out vec4 g_position;  // xyz, w = 1 on covered texels
layout(location = 1) out vec4 g_normal;    // xyz unit normal, w = chart id

// Half the diagonal of a texel (plus rounding slack): a texel's square meets the triangle
// only if its centre is at most this far from it.
const float TOUCH_DISTANCE = 0.70711;

float cross2(vec2 u, vec2 v) {
    return u.x * v.y - u.y * v.x;
}

// Barycentrics of the point of triangle (a, b, c) nearest to p, and that distance.
vec3 nearest_barycentric(vec2 p, vec2 a, vec2 b, vec2 c, out float dist) {
    float area = cross2(b - a, c - a);
    if (abs(area) > 1e-12) {
        float wa = cross2(b - p, c - p) / area;
        float wb = cross2(c - p, a - p) / area;
        float wc = 1.0 - wa - wb;
        if (wa >= 0.0 && wb >= 0.0 && wc >= 0.0) {
            dist = 0.0;
            return vec3(wa, wb, wc);
        }
    }
    // Outside (or a degenerate triangle): the nearest point lies on an edge.
    vec2 from[3] = vec2[3](a, b, c);
    vec2 to[3] = vec2[3](b, c, a);
    dist = 1e30;
    vec3 best = vec3(1.0, 0.0, 0.0);
    for (int e = 0; e < 3; ++e) {
        vec2 edge = to[e] - from[e];
        float t = clamp(dot(p - from[e], edge) / max(dot(edge, edge), 1e-30), 0.0, 1.0);
        float d = length(p - (from[e] + t * edge));
        if (d < dist) {
            dist = d;
            vec3 w = vec3(0.0);
            w[e] = 1.0 - t;
            w[(e + 1) % 3] = t;
            best = w;
        }
    }
    return best;
}

void main() {
    float dist;
    vec3 w = nearest_barycentric(gl_FragCoord.xy, texel_a, texel_b, texel_c, dist);
    if (dist > TOUCH_DISTANCE) {
        discard;
    }
    // Where triangles share a texel the one nearest to its centre wins (depth test LESS).
    gl_FragDepth = 0.5 * dist;
    vec3 position = w.x * position_a + w.y * position_b + w.z * position_c;
    vec3 n = w.x * normal_a + w.y * normal_b + w.z * normal_c;
    if (length(n) < 1e-8) {
        // Opposite vertex normals cancelled (a folded crease): use the face's own normal.
        n = cross(position_b - position_a, position_c - position_a);
        if (length(n) < 1e-20) {
            n = vec3(0.0, 1.0, 0.0);
        }
    }
    n = normalize(n);
    if (normal_mapped > 0.5) {
        vec2 mesh_uv = w.x * mesh_uv_a + w.y * mesh_uv_b + w.z * mesh_uv_c;
        vec4 tangent = w.x * tangent_a + w.y * tangent_b + w.z * tangent_c;
        n = apply_normal_map(n, tangent, texture(normal_map, mesh_uv).rgb);
    }
    g_position = vec4(position, 1.0);
    g_normal = vec4(n, chart);
}
