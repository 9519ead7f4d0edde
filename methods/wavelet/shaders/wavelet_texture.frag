#version 430
// Wavelet transfer textures: B = kd/π · E, with E = Σ_{i in k} T_i L_i per texel formed on the
// CPU this frame (the k selected Haar lighting terms) and looked up bilinearly in the atlas.
// Back faces are black (one-sided surfaces, as in Mitsuba).
#include "brdf.glsl"

uniform sampler2DArray incident;

in vec2 atlas_uv;
flat in int texture_set;
flat in vec3 kd;

out vec4 color;

void main() {
    vec3 e = texture(incident, vec3(atlas_uv, float(texture_set))).rgb;
    color = gl_FrontFacing ? vec4(kd / BRDF_PI * e, 1.0) : vec4(0.0, 0.0, 0.0, 1.0);
}
