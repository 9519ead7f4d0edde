#version 430
// Matrix transfer u = M x (Belcour et al. 2022 eq. 10, §5.2): one output texel per group of
// four basis elements (and per colour channel for the mono-channel basis). Element 0 is the
// mean, whose coefficient is the norm of the direct vector (§4.2); element e > 0 uses row e-1
// of M (one column per vector entry). The mono-channel basis has one M per colour channel
// (the paper's "three different transfer matrices"), stacked: channel c's row e-1 is texture
// row c * channel_stride + e-1 (stride n - 1, or 0 when one matrix serves all channels).
uniform sampler2D direct_vector;   // (P, 1): rgb of each measurement point
uniform sampler2D transfer_matrix; // (3P, n - 1) interleaved or (P, 3 (n - 1)) mono, r channel
uniform int n_points;
uniform int n_basis;
#if !MULTI_CHANNEL
uniform int channel_stride;        // rows between channels' matrices: n - 1, or 0 if shared
#endif
out vec4 coefficients;

#if GAMMA_SPACE
// The lights' largest power: v / light_scale before the power keeps float32 finite for any
// light (the coefficients are homogeneous in x; the shading multiplies light_scale back).
uniform float light_scale;
#endif

float to_transfer_space(float v) {
#if GAMMA_SPACE
    return pow(max(v / light_scale, 0.0), 1.0 / GAMMA);
#else
    return v;
#endif
}

void main() {
    int group = int(gl_FragCoord.x);
    vec4 acc = vec4(0.0);
    float norm2 = 0.0;
#if MULTI_CHANNEL
    for (int i = 0; i < n_points; ++i) {
        vec3 x = texelFetch(direct_vector, ivec2(i, 0), 0).rgb;
        for (int c = 0; c < 3; ++c) {
            float v = to_transfer_space(x[c]);
            norm2 += v * v;
            for (int k = 0; k < 4; ++k) {
                int e = 4 * group + k;
                if (e >= 1 && e < n_basis)
                    acc[k] += texelFetch(transfer_matrix, ivec2(3 * i + c, e - 1), 0).r * v;
            }
        }
    }
#else
    int channel = int(gl_FragCoord.y);
    for (int i = 0; i < n_points; ++i) {
        float v = to_transfer_space(texelFetch(direct_vector, ivec2(i, 0), 0)[channel]);
        norm2 += v * v;
        for (int k = 0; k < 4; ++k) {
            int e = 4 * group + k;
            if (e >= 1 && e < n_basis)
                acc[k] += texelFetch(transfer_matrix, ivec2(i, channel * channel_stride + e - 1), 0).r * v;
        }
    }
#endif
    if (group == 0) acc[0] = sqrt(norm2);
    coefficients = acc;
}
