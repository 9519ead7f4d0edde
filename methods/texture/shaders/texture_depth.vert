#version 430
// Early depth pre-pass of the transfer-texture renderer: depth only, the same position
// expression as texture_prt.vert (both invariant), so the shading pass's depth test with
// GL_LEQUAL passes exactly the visible fragments.
invariant gl_Position;

uniform mat4 clip_from_world;

in vec3 in_position;

void main() {
    gl_Position = clip_from_world * vec4(in_position, 1.0);
}
