#version 430
// Plain textured diffuse: B = albedo(uv) · E/π with a constant irradiance E; back faces black.
uniform sampler2D albedo;
uniform vec3 irradiance_over_pi;

in vec2 atlas_uv;

out vec4 color;

void main() {
    color = gl_FrontFacing ? vec4(texture(albedo, atlas_uv).rgb * irradiance_over_pi, 1.0)
                           : vec4(0.0, 0.0, 0.0, 1.0);
}
