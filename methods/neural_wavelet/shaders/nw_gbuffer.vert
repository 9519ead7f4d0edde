#version 430
// Neural wavelet transport (Raghavan 2023): world position, normal and per-object material for
// the G-buffer pass; the network itself runs in torch on the covered pixels.
uniform mat4 clip_from_world;

in vec3 in_position;
in vec3 normal;
in vec3 kd;
in vec3 ks;
in float shininess;

out vec3 world_position;
out vec3 world_normal;
out vec3 v_kd;
out vec3 v_ks;
out float v_shininess;

void main() {
    world_position = in_position;
    world_normal = normal;
    v_kd = kd;
    v_ks = ks;
    v_shininess = shininess;
    gl_Position = clip_from_world * vec4(in_position, 1.0);
}
