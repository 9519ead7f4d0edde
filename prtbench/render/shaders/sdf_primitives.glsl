// Signed distance primitives and smooth Booleans, the GLSL twins of prtbench/sdf/nodes.py
// (same formulas, same argument order). Negative inside. Round primitives have their axis
// along +Y. Included by the generated scene_sdf.glsl (prtbench.transport.sdf.SdfNode.glsl()).
#ifndef PRTBENCH_SDF_PRIMITIVES_GLSL
#define PRTBENCH_SDF_PRIMITIVES_GLSL

float sdf_sphere(vec3 p, float radius) {
    return length(p) - radius;
}

float sdf_box(vec3 p, vec3 half_size) {
    vec3 q = abs(p) - half_size;
    return length(max(q, 0.0)) + min(max(q.x, max(q.y, q.z)), 0.0);
}

float sdf_round_box(vec3 p, vec3 half_size, float radius) {
    return sdf_box(p, half_size - radius) - radius;
}

float sdf_capsule(vec3 p, vec3 a, vec3 b, float radius) {
    vec3 pa = p - a;
    vec3 ba = b - a;
    float denom = dot(ba, ba);
    float h = denom > 0.0 ? clamp(dot(pa, ba) / denom, 0.0, 1.0) : 0.0;
    return length(pa - h * ba) - radius;
}

float sdf_torus(vec3 p, float major, float minor) {
    return length(vec2(length(p.xz) - major, p.y)) - minor;
}

float sdf_cylinder(vec3 p, float radius, float half_height) {
    vec2 d = vec2(length(p.xz) - radius, abs(p.y) - half_height);
    return min(max(d.x, d.y), 0.0) + length(max(d, 0.0));
}

// Capped cone: radius r1 at y = -h, r2 at y = +h. Distance to the (rho, y) trapezoid's caps
// and slanted side, negative inside.
float sdf_cone(vec3 p, float h, float r1, float r2) {
    float rho = length(p.xz);
    float y = p.y;
    float bottom = length(vec2(max(rho - r1, 0.0), y + h));
    float top = length(vec2(max(rho - r2, 0.0), y - h));
    vec2 e = vec2(r2 - r1, 2.0 * h);
    float t = clamp(dot(vec2(rho - r1, y + h), e) / dot(e, e), 0.0, 1.0);
    float side = length(vec2(rho - r1, y + h) - t * e);
    float unsigned_d = min(min(bottom, top), side);
    bool inside = abs(y) <= h && rho <= r1 + (r2 - r1) * (y + h) / (2.0 * h);
    return inside ? -unsigned_d : unsigned_d;
}

// The 1-Lipschitz bound (|p/r| - 1) * min(r): exact on the surface.
float sdf_ellipsoid(vec3 p, vec3 radii) {
    return (length(p / radii) - 1.0) * min(radii.x, min(radii.y, radii.z));
}

float sdf_plane(vec3 p, vec3 normal, float height) {
    return dot(p, normal) - height;
}

// Polynomial smooth min/max: min(a, b) - h^2 k / 4 with h = max(k - |a - b|, 0) / k.
float sdf_smin(float a, float b, float k) {
    if (k <= 0.0) return min(a, b);
    float h = max(k - abs(a - b), 0.0) / k;
    return min(a, b) - h * h * k * 0.25;
}

float sdf_smax(float a, float b, float k) {
    if (k <= 0.0) return max(a, b);
    float h = max(k - abs(a - b), 0.0) / k;
    return max(a, b) + h * h * k * 0.25;
}

#endif
