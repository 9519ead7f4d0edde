#version 430
// Learnt transfer, torch path (thesis §4.1.4.2, fig. 4.4): the GL pass only writes G-buffers;
// torch then evaluates the network on the covered pixels and shades them.
//   0: world position, w = +1 front face / −1 back face (0 where no geometry: cleared)
//   1: unit normal, w = sub-scene network index
//   2: kd, w = Phong exponent s
//   3: ks
#include "learnt_partition_data.glsl"
#include "learnt_partition.glsl"

in vec3 world_position;
in vec3 world_normal;
in vec3 v_kd;
in vec3 v_ks;
in float v_shininess;
flat in int v_object;

layout(location = 0) out vec4 g_position;
layout(location = 1) out vec4 g_normal;
layout(location = 2) out vec4 g_kd;
layout(location = 3) out vec4 g_ks;

void main() {
    g_position = vec4(world_position, gl_FrontFacing ? 1.0 : -1.0);
    g_normal = vec4(normalize(world_normal), float(learnt_group(world_position, v_object)));
    g_kd = vec4(v_kd, v_shininess);
    g_ks = vec4(v_ks, 0.0);
}
