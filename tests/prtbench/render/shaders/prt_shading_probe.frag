#version 430
// Fragment-stage half of the prt_shading.glsl probe (see prt_shading_probe.vert).
#include "prt_shading_probe.glsl"

flat in int case_index;
out vec4 color;

void main() {
#if !PROBE_IN_VERTEX
    probe(case_index);
#endif
    color = vec4(1.0);
}
