// Compressed transfer textures (texture-tp / texture-tpfl with compress = pca / vq / cpca;
// methods/texture/compressed.py): H at a texel is P[c][0] + Σ_j w_j P[c][1 + j] (cpca.glsl's
// table, the light already projected per cluster by the CPU), c the texel's cluster id
// (−1: an empty texel, H = 0) and w its PCA_VECTORS weights. Bilinear filtering blends the H of
// the four texels of the footprint (ids cannot be filtered); BILINEAR 0 reads the nearest one.
// Defines: CPCA_CLUSTERS, PCA_VECTORS, CPCA_OUTPUTS (= SH_COEFFS), CPCA_WEIGHT_LAYERS
// (ceil(PCA_VECTORS / 4) RGBA layers per texture), BILINEAR.
#include "cpca.glsl"

uniform isampler2DArray cpca_cluster_ids;
#if PCA_VECTORS > 0
uniform sampler2DArray cpca_weight_layers;
#endif

void cpca_texel_add(ivec2 texel, int set, float weight, inout vec3 H[SH_COEFFS]) {
    int cluster = texelFetch(cpca_cluster_ids, ivec3(texel, set), 0).r;
    if (cluster < 0 || weight == 0.0) {
        return;
    }
    int base = cluster * (1 + PCA_VECTORS) * CPCA_OUTPUTS;
#if PCA_VECTORS > 0
    float w[PCA_VECTORS];
    for (int g = 0; g < CPCA_WEIGHT_LAYERS; ++g) {
        vec4 texel_w = texelFetch(cpca_weight_layers, ivec3(texel, set * CPCA_WEIGHT_LAYERS + g), 0);
        for (int c = 0; c < 4; ++c) {
            if (4 * g + c < PCA_VECTORS) {
                w[4 * g + c] = texel_w[c];
            }
        }
    }
#endif
    for (int k = 0; k < SH_COEFFS; ++k) {
        vec3 sum = cpca_table(base + k);
#if PCA_VECTORS > 0
        for (int j = 0; j < PCA_VECTORS; ++j) {
            sum += w[j] * cpca_table(base + (1 + j) * CPCA_OUTPUTS + k);
        }
#endif
        H[k] += weight * sum;
    }
}

void cpca_texture_transfer(vec2 uv, int set, out vec3 H[SH_COEFFS]) {
    for (int k = 0; k < SH_COEFFS; ++k) {
        H[k] = vec3(0.0);
    }
    ivec2 size = textureSize(cpca_cluster_ids, 0).xy;
#if BILINEAR
    vec2 position = uv * vec2(size) - 0.5;
    ivec2 low = ivec2(floor(position));
    vec2 f = position - vec2(low);
    for (int dy = 0; dy < 2; ++dy) {
        for (int dx = 0; dx < 2; ++dx) {
            // CLAMP_TO_EDGE, as the uncompressed textures are sampled.
            ivec2 texel = clamp(low + ivec2(dx, dy), ivec2(0), size - 1);
            float weight = (dx == 1 ? f.x : 1.0 - f.x) * (dy == 1 ? f.y : 1.0 - f.y);
            cpca_texel_add(texel, set, weight, H);
        }
    }
#else
    cpca_texel_add(clamp(ivec2(floor(uv * vec2(size))), ivec2(0), size - 1), set, 1.0, H);
#endif
}
