#version 430
// Occlusion of rays from SSBOs by sphere tracing, one fragment per ray (prtbench.transport.sdf
// SdfTracer(backend="gl")): ray i is at gl_FragCoord (i % row_width, i / row_width).
#include "sdf_trace.glsl"

layout(std430, binding = 0) readonly buffer Origins { vec4 origins[]; };      // xyz, tmax
layout(std430, binding = 1) readonly buffer Directions { vec4 directions[]; };
uniform int n_rays;
uniform int row_width;

layout(location = 0) out vec4 out_occluded;   // 1 when the ray hits the surface

void main() {
    int i = int(gl_FragCoord.y) * row_width + int(gl_FragCoord.x);
    if (i >= n_rays) {
        out_occluded = vec4(0.0);
        return;
    }
    vec4 o = origins[i];
    out_occluded = vec4(sdf_occluded(o.xyz, normalize(directions[i].xyz), o.w) ? 1.0 : 0.0);
}
