#version 430
// Evaluates the scene SDF at points from an SSBO, one fragment per point (tests, probes):
// point i is at gl_FragCoord (i % row_width, i / row_width).
#include "sdf_trace.glsl"

layout(std430, binding = 0) readonly buffer Points { vec4 points[]; };
uniform int n_points;
uniform int row_width;

layout(location = 0) out vec4 out_value;    // distance, material id
layout(location = 1) out vec4 out_normal;   // sdf_normal

void main() {
    int i = int(gl_FragCoord.y) * row_width + int(gl_FragCoord.x);
    if (i >= n_points) {
        out_value = vec4(0.0);
        out_normal = vec4(0.0);
        return;
    }
    vec3 p = points[i].xyz;
    int material;
    float d = scene_sdf_material(p, material);
    out_value = vec4(d, float(material), 0.0, 1.0);
    out_normal = vec4(sdf_normal(p), 0.0);
}
