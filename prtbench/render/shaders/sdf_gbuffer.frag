#version 430
// G-buffer of an SDF scene by sphere tracing primary rays (prtbench.transport.sdf.sdf_gbuffer).
#include "sdf_camera.glsl"
#include "sdf_trace.glsl"

layout(location = 0) out vec4 out_position;   // hit position, 1 on a hit (0 on a miss)
layout(location = 1) out vec4 out_normal;     // unit normal, material id (-1 on a miss)

void main() {
    vec3 ro, rd, p, n;
    int material;
    primary_ray(gl_FragCoord.xy, ro, rd);
    if (trace(ro, rd, p, n, material)) {
        out_position = vec4(p, 1.0);
        out_normal = vec4(n, float(material));
    } else {
        out_position = vec4(0.0);
        out_normal = vec4(0.0, 0.0, 0.0, -1.0);
    }
}
