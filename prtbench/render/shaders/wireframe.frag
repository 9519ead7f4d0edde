#version 430
// Edge coverage from barycentric coordinates: 1 on the triangle's edges (about line_width
// pixels wide, antialiased with fwidth), 0 inside. Output: (coverage, 0, 0, 1); alpha marks
// geometry, so hidden edges are removed by the ordinary depth test.

uniform float line_width;

in vec3 barycentric;

layout(location = 0) out vec4 frag_color;

void main() {
    vec3 pixels_per_unit = max(fwidth(barycentric), vec3(1e-6));
    vec3 distance_px = barycentric / pixels_per_unit;  // distance to each edge in pixels
    float nearest = min(distance_px.x, min(distance_px.y, distance_px.z));
    float coverage = 1.0 - smoothstep(0.5 * line_width - 0.5, 0.5 * line_width + 0.5, nearest);
    frag_color = vec4(coverage, 0.0, 0.0, 1.0);
}
