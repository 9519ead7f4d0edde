#version 430
// Ng 2004 wavelet triple products: the CPU has formed each vertex's outgoing radiance
// kd ⊙ TP(L, V, D) + ks ⊙ TP(L, V, G) towards the eye; the raster only interpolates it.

layout(std430, binding = 0) readonly buffer Outgoing { float outgoing[]; };

uniform mat4 clip_from_world;

in vec3 in_position;

out vec3 radiance;

void main() {
    int base = 3 * gl_VertexID;
    radiance = vec3(outgoing[base], outgoing[base + 1], outgoing[base + 2]);
    gl_Position = clip_from_world * vec4(in_position, 1.0);
}
