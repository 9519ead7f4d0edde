#version 430
// G-buffer of the neural wavelet transport (read back and evaluated in torch):
//   0: world position, w = +1 front face / -1 back face (0 where no geometry: cleared)
//   1: unit normal, w = merged triangle index (the vertex-feature variant interpolates there)
//   2: kd, w = Phong exponent s
//   3: ks
in vec3 world_position;
in vec3 world_normal;
in vec3 v_kd;
in vec3 v_ks;
in float v_shininess;

layout(location = 0) out vec4 g_position;
layout(location = 1) out vec4 g_normal;
layout(location = 2) out vec4 g_kd;
layout(location = 3) out vec4 g_ks;

void main() {
    g_position = vec4(world_position, gl_FrontFacing ? 1.0 : -1.0);
    // Triangle indices below 2^24 are exact in a float32.
    g_normal = vec4(normalize(world_normal), float(gl_PrimitiveID));
    g_kd = vec4(v_kd, v_shininess);
    g_ks = vec4(v_ks, 0.0);
}
