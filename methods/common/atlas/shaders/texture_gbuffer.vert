#version 430
// PRTT Algorithm 2, vertex stage: every atlas vertex goes to its texel-space position; the
// geometry stage widens each triangle so that every texel it touches gets a fragment.
in vec2 in_atlas_uv;
in vec3 in_position;
in vec3 in_normal;
in vec2 in_mesh_uv;
in vec4 in_tangent;
in float in_chart;
in float in_normal_mapped;

out GBufferCorner {
    vec2 atlas_uv;
    vec3 position;
    vec3 normal;
    vec2 mesh_uv;
    vec4 tangent;
    float chart;
    float normal_mapped;
} corner;

void main() {
    corner.atlas_uv = in_atlas_uv;
    corner.position = in_position;
    corner.normal = in_normal;
    corner.mesh_uv = in_mesh_uv;
    corner.tangent = in_tangent;
    corner.chart = in_chart;
    corner.normal_mapped = in_normal_mapped;
    gl_Position = vec4(in_atlas_uv * 2.0 - 1.0, 0.0, 1.0);
}
