#version 430
// Learnt transfer (thesis ch. 4): world position, normal and per-object material for the
// fragment stages (depth pre-pass, shading with the MLP, or the torch path's G-buffer).
uniform mat4 clip_from_world;

in vec3 in_position;
in vec3 normal;
in vec3 kd;
in vec3 ks;
in float shininess;
in float object_id;

out vec3 world_position;
out vec3 world_normal;
out vec3 v_kd;
out vec3 v_ks;
out float v_shininess;
flat out int v_object;

// The depth pre-pass and the shading pass use different programs: invariance guarantees the
// same depth in both, so the shading pass's LEQUAL test keeps exactly the visible fragments.
invariant gl_Position;

void main() {
    world_position = in_position;
    world_normal = normal;
    v_kd = kd;
    v_ks = ks;
    v_shininess = shininess;
    v_object = int(object_id + 0.5);
    gl_Position = clip_from_world * vec4(in_position, 1.0);
}
