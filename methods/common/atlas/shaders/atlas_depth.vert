#version 430
// Early depth pre-pass of the atlas renderer: the same position expression as atlas_mesh.vert
// (both invariant), so the shading pass's depth test with GL_LEQUAL passes exactly the visible
// fragments.
invariant gl_Position;

uniform mat4 clip_from_world;

in vec3 in_position;

void main() {
    gl_Position = clip_from_world * vec4(in_position, 1.0);
}
