#version 430
// Final pass of the data-driven method: the atlas render mesh with lightmap UVs.
uniform mat4 clip_from_world;
in vec3 in_position;
in vec3 normal;
in vec3 kd;
in vec2 lightmap_uv;
out vec3 world;
out vec3 shading_normal;
out vec3 albedo;
out vec2 uv;

void main() {
    world = in_position;
    shading_normal = normal;
    albedo = kd;
    uv = lightmap_uv;
    gl_Position = clip_from_world * vec4(in_position, 1.0);
}
