#version 430
// Wireframe overlay for figures: each triangle is drawn with its own three vertices carrying
// barycentric corners, so the fragment shader knows its distance to the triangle's edges.

uniform mat4 clip_from_world;

in vec3 in_position;
in vec3 in_barycentric;

out vec3 barycentric;

void main() {
    barycentric = in_barycentric;
    gl_Position = clip_from_world * vec4(in_position, 1.0);
}
