#version 430
// One probe case per point; PROBE_IN_VERTEX selects the stage that runs prt_shading.glsl.
#include "prt_shading_probe.glsl"

flat out int case_index;

void main() {
    case_index = gl_VertexID;
#if PROBE_IN_VERTEX
    probe(gl_VertexID);
#endif
    // Point at pixel (case, 0) of a CASES × 1 target, so the fragment stage runs once per case.
    gl_Position = vec4((float(gl_VertexID) + 0.5) / float(CASES) * 2.0 - 1.0, 0.0, 0.0, 1.0);
    gl_PointSize = 1.0;
}
