#version 430
// Cost baseline for transfer textures (benchmarks/test_texture_cost.py): the cheapest textured
// shader on the same atlas mesh, an albedo lookup times a constant irradiance.
uniform mat4 clip_from_world;

in vec3 in_position;
in vec2 in_atlas_uv;

out vec2 atlas_uv;

void main() {
    atlas_uv = in_atlas_uv;
    gl_Position = clip_from_world * vec4(in_position, 1.0);
}
