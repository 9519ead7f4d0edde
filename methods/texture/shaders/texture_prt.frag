#version 430
// Transfer textures (PRTT §4–5), shading pass: per fragment, sample the transfer vector T from
// the texture array, form the transferred radiance H (TP: H_k = Σ_ij Γ_ijk T_i L_j; TPFL:
// H_k = Σ_i T_i M_ik), add the baked interreflection textures T_1…T_k (already radiance, RGB),
// and shade with the Phong BRDF (prt_shading.glsl). Back faces are black.
//
// Defines: SH_BANDS, PRODUCT_TP (1: triple product with light_sh, 0: TPFL matrix),
// TRANSFER_LAYERS = ceil(n²/4) RGBA layers per texture, BOUNCES, BOUNCE_LAYERS =
// ceil(3n²/4) layers per bounce texture, TEXTURE_SETS (textures per bounce).
// Layers: transfer_layers[set·TRANSFER_LAYERS + g] holds coefficients 4g…4g+3;
// bounce_layers[((b·TEXTURE_SETS) + set)·BOUNCE_LAYERS + g] holds flat values 4g…4g+3 of
// T_{b+1}, flat value 3k + c being coefficient k of channel c.
layout(early_fragment_tests) in;

#include "prt_shading.glsl"
#include "texture_normal.glsl"

#ifdef CPCA_OUTPUTS
// Compressed texels (compress = pca / vq / cpca): H straight from the form.
#include "texture_cpca.glsl"
#else
uniform sampler2DArray transfer_layers;
#endif
#if BOUNCES > 0
uniform sampler2DArray bounce_layers;
#endif
uniform sampler2D normal_map;
uniform vec3 eye;
#if PRODUCT_TP
uniform vec3 light_sh[SH_COEFFS];
#endif

in vec3 world_position;
in vec3 normal;
in vec2 atlas_uv;
in vec2 mesh_uv;
in vec4 tangent;
flat in vec3 kd;
flat in vec3 ks;
flat in float shininess;
flat in int texture_set;
flat in int normal_mapped;

out vec4 color;

void main() {
    if (!gl_FrontFacing) {
        color = vec4(0.0, 0.0, 0.0, 1.0);
        return;
    }
    vec3 H[SH_COEFFS];
#ifdef CPCA_OUTPUTS
    cpca_texture_transfer(atlas_uv, texture_set, H);
#else
    float T[SH_COEFFS];
    int base = texture_set * TRANSFER_LAYERS;
    for (int g = 0; g < TRANSFER_LAYERS; ++g) {
        vec4 texel = texture(transfer_layers, vec3(atlas_uv, float(base + g)));
        for (int c = 0; c < 4; ++c) {
            if (4 * g + c < SH_COEFFS) {
                T[4 * g + c] = texel[c];
            }
        }
    }
#if PRODUCT_TP
    triple_product(T, light_sh, H);
#else
    tpfl_product(T, H);
#endif
#endif
#if BOUNCES > 0
    for (int b = 0; b < BOUNCES; ++b) {
        int bounce_base = (b * TEXTURE_SETS + texture_set) * BOUNCE_LAYERS;
        for (int g = 0; g < BOUNCE_LAYERS; ++g) {
            vec4 texel = texture(bounce_layers, vec3(atlas_uv, float(bounce_base + g)));
            for (int c = 0; c < 4; ++c) {
                int flat_index = 4 * g + c;
                if (flat_index < 3 * SH_COEFFS) {
                    H[flat_index / 3][flat_index % 3] += texel[c];
                }
            }
        }
    }
#endif
    vec3 n = normalize(normal);
    if (normal_mapped == 1) {
        n = apply_normal_map(n, tangent, texture(normal_map, mesh_uv).rgb);
    }
    vec3 wo = normalize(eye - world_position);
    color = vec4(shade_transferred(H, kd, ks, shininess, n, wo), 1.0);
}
