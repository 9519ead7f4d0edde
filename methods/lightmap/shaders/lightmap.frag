#version 430
// Directional lightmap, shading pass: one bilinear fetch per coefficient from the lightmap's
// texture array (layer texture_set·COEFFS + k), the decode of its storage, and the irradiance
// E at the pixel's normal n (normal-mapped where the object has the scene's normal map):
//   diffuse: E = c_0 (the irradiance baked at the texel's normal);
//   SH:      E = Σ_l √(4π/(2l+1)) g_l Σ_m c_lm Y_lm(n) (sh_zonal_eval_rgb, zonal = g_l);
//   H-basis: E = Σ_k c_k H_k(n_local), n_local = n in the tangent frame of the unmapped normal
//            (branchless frame of Duff et al. 2017, as methods.lightmap.encoding.local_frames).
// Radiance B = kd/π · E; back faces are black. The numpy twin of the decode is
// methods.lightmap.encoding.decode.
// Defines: COEFFS, STORAGE (0 float16, 1 rgbm, 2 scaled8), ENCODING_SH (with SH_BANDS),
// ENCODING_HBASIS.
layout(early_fragment_tests) in;

#include "brdf.glsl"
#include "texture_normal.glsl"
#if ENCODING_SH
#include "sh.glsl"
uniform float zonal[SH_BANDS];
#endif
#if ENCODING_HBASIS
// H_k(ω) = Σ_j hbasis[k·COEFFS + j] m_j(ω), m = (1, y, z, x, xy, x² − y²).
uniform float hbasis[COEFFS * COEFFS];
#endif

uniform sampler2DArray lightmap;
uniform sampler2D normal_map;
#if STORAGE == 0
uniform float half_scale;          // coefficient k = rgb · half_scale (a power of two)
#elif STORAGE == 1
uniform float rgbm_range;          // coefficient 0 = rgb · a · rgbm_range
uniform float ratio_bound[COEFFS]; // coefficient k > 0 = (rgb − 0.5) · 2 · bound_k · coefficient 0
#elif STORAGE == 2
uniform vec3 scale[COEFFS];        // coefficient k = rgb · scale_k + bias_k
uniform vec3 bias[COEFFS];
#endif

in vec3 normal;
in vec2 atlas_uv;
in vec2 mesh_uv;
in vec4 tangent;
flat in vec3 kd;
flat in int texture_set;
flat in int normal_mapped;

out vec4 color;

void main() {
    if (!gl_FrontFacing) {  // one-sided surfaces: seen from behind is black
        color = vec4(0.0, 0.0, 0.0, 1.0);
        return;
    }
    vec3 c[COEFFS];
    for (int k = 0; k < COEFFS; ++k) {
        vec4 t = texture(lightmap, vec3(atlas_uv, float(texture_set * COEFFS + k)));
#if STORAGE == 0
        c[k] = t.rgb * half_scale;
#elif STORAGE == 1
        c[k] = k == 0 ? t.rgb * t.a * rgbm_range : (t.rgb - 0.5) * (2.0 * ratio_bound[k]) * c[0];
#else
        c[k] = t.rgb * scale[k] + bias[k];
#endif
    }
    vec3 nv = normalize(normal);
    vec3 n = normal_mapped == 1 ? apply_normal_map(nv, tangent, texture(normal_map, mesh_uv).rgb)
                                : nv;
#if ENCODING_SH
    vec3 irradiance = sh_zonal_eval_rgb(c, zonal, n);
#elif ENCODING_HBASIS
    float sgn = nv.z >= 0.0 ? 1.0 : -1.0;
    float a = -1.0 / (sgn + nv.z);
    float b = nv.x * nv.y * a;
    vec3 t1 = vec3(1.0 + sgn * nv.x * nv.x * a, sgn * b, -sgn * nv.x);
    vec3 t2 = vec3(b, sgn + nv.y * nv.y * a, -nv.y);
    vec3 l = vec3(dot(t1, n), dot(t2, n), dot(nv, n));
    float m[6] = float[6](1.0, l.y, l.z, l.x, l.x * l.y, l.x * l.x - l.y * l.y);
    vec3 irradiance = vec3(0.0);
    for (int k = 0; k < COEFFS; ++k) {
        float h = 0.0;
        for (int j = 0; j <= k; ++j) {  // the matrix is lower triangular (Gram–Schmidt)
            h += hbasis[k * COEFFS + j] * m[j];
        }
        irradiance += h * c[k];
    }
#else
    vec3 irradiance = c[0];
#endif
    color = vec4(kd / BRDF_PI * irradiance, 1.0);
}
