#version 430
// Wavelet transfer textures: passes the atlas UV, texture set and diffuse albedo to the
// fragment stage, which reads the CPU-relit incident radiance texture there.
uniform mat4 clip_from_world;

in vec3 in_position;
in vec2 in_atlas_uv;
in float in_texture_set;
in vec3 in_kd;

out vec2 atlas_uv;
flat out int texture_set;
flat out vec3 kd;

void main() {
    atlas_uv = in_atlas_uv;
    texture_set = int(in_texture_set + 0.5);
    kd = in_kd;
    gl_Position = clip_from_world * vec4(in_position, 1.0);
}
