#version 430
// Interpolated per-vertex radiance; back faces are black (one-sided surfaces, as in Mitsuba).
in vec3 radiance;
out vec4 color;

void main() {
    color = gl_FrontFacing ? vec4(radiance, 1.0) : vec4(0.0, 0.0, 0.0, 1.0);
}
