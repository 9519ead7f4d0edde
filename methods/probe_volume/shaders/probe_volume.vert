#version 430
// Probe volume: pass world position, normal and albedo to the fragment stage, which looks the
// probes up per pixel. The depth pre-pass draws with this stage too (and probe_depth.frag):
// gl_Position is invariant, so the shading pass's GL_LEQUAL test passes exactly the visible
// fragments.
invariant gl_Position;

uniform mat4 clip_from_world;

in vec3 in_position;
in vec3 normal;
in vec3 kd;

out vec3 world_position;
out vec3 world_normal;
out vec3 albedo;

void main() {
    world_position = in_position;  // scenes are stored in world space
    world_normal = normal;
    albedo = kd;
    gl_Position = clip_from_world * vec4(in_position, 1.0);
}
