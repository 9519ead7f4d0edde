#version 430
// Stores the linear metric the receivers compare against (see data_driven_lights.glsl).
uniform vec4 ref;  // xyz: light position (w = 1) or travel direction (w = 0)
in vec3 world;
out float metric;

void main() {
    metric = ref.w > 0.5 ? length(world - ref.xyz) : dot(world, ref.xyz);
}
