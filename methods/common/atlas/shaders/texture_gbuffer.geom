#version 430
// Conservative texel coverage: each triangle is drawn as its texel-space bounding box grown by
// one texel, carrying the whole triangle as flat attributes; the fragment stage keeps texels
// whose centre lies within half a texel diagonal of the triangle (every texel whose square the
// triangle touches) and interpolates at the closest point of the triangle. Plain rasterisation
// would miss texels whose centre is outside every triangle (slivers, chart borders) although
// bilinear lookups inside the triangle read them.
layout(triangles) in;
layout(triangle_strip, max_vertices = 4) out;

uniform float resolution;

in GBufferCorner {
    vec2 atlas_uv;
    vec3 position;
    vec3 normal;
    vec2 mesh_uv;
    vec4 tangent;
    float chart;
    float normal_mapped;
} corner[];

flat out vec2 texel_a;   // triangle corners in texel units
flat out vec2 texel_b;
flat out vec2 texel_c;
flat out vec3 position_a;
flat out vec3 position_b;
flat out vec3 position_c;
flat out vec3 normal_a;
flat out vec3 normal_b;
flat out vec3 normal_c;
flat out vec2 mesh_uv_a;
flat out vec2 mesh_uv_b;
flat out vec2 mesh_uv_c;
flat out vec4 tangent_a;
flat out vec4 tangent_b;
flat out vec4 tangent_c;
flat out float chart;
flat out float normal_mapped;

void emit(vec2 texel) {
    // Outputs are undefined after EmitVertex: restate the flat triangle for every vertex.
    texel_a = corner[0].atlas_uv * resolution;
    texel_b = corner[1].atlas_uv * resolution;
    texel_c = corner[2].atlas_uv * resolution;
    position_a = corner[0].position;
    position_b = corner[1].position;
    position_c = corner[2].position;
    normal_a = corner[0].normal;
    normal_b = corner[1].normal;
    normal_c = corner[2].normal;
    mesh_uv_a = corner[0].mesh_uv;
    mesh_uv_b = corner[1].mesh_uv;
    mesh_uv_c = corner[2].mesh_uv;
    tangent_a = corner[0].tangent;
    tangent_b = corner[1].tangent;
    tangent_c = corner[2].tangent;
    chart = corner[0].chart;
    normal_mapped = corner[0].normal_mapped;
    gl_Position = vec4(texel / resolution * 2.0 - 1.0, 0.0, 1.0);
    EmitVertex();
}

void main() {
    vec2 a = corner[0].atlas_uv * resolution;
    vec2 b = corner[1].atlas_uv * resolution;
    vec2 c = corner[2].atlas_uv * resolution;
    vec2 lo = min(min(a, b), c) - 1.0;
    vec2 hi = max(max(a, b), c) + 1.0;
    emit(vec2(lo.x, lo.y));
    emit(vec2(hi.x, lo.y));
    emit(vec2(lo.x, hi.y));
    emit(vec2(hi.x, hi.y));
    EndPrimitive();
}
