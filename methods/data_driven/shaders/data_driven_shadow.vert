#version 430
// Shadow-atlas tile: the scene seen from one light.
uniform mat4 clip_from_world;
in vec3 in_position;
out vec3 world;

void main() {
    world = in_position;
    gl_Position = clip_from_world * vec4(in_position, 1.0);
}
