#version 430
// Learnt transfer on an SDF scene, GLSL path (thesis §4.1.4.1 and §4.2.2): one full-screen pass.
// Each fragment sphere-traces its primary ray (sdf_trace.glsl), evaluates the transfer MLP at
// the hit point and SDF normal with the hard-coded mat4 weights (learnt_mlp.glsl + the generated
// learnt_weights.glsl), turns the transfer T into transferred radiance H with the light (TPFL,
// the thesis's global light matrix, or TP) and shades H with the Phong BRDF of the hit's
// material id (prt_shading.glsl). Misses are background 0. An SDF has no back faces: primary
// rays start outside the surface and stop at its first zero crossing, the outside.
// Defines: SH_BANDS, LEARNT_PRODUCT_TP (0/1), SDF_MATERIALS (material count);
// virtual includes: scene_sdf.glsl (prtbench.transport.sdf), learnt_weights.glsl (methods/learnt/glsl.py).
#include "sdf_camera.glsl"
#include "sdf_trace.glsl"
#include "prt_shading.glsl"
#include "learnt_weights.glsl"
#include "learnt_mlp.glsl"

// Materials per SDF material id (SdfSurface.materials), set by methods/learnt_sdf.py.
uniform vec3 material_kd[SDF_MATERIALS];
uniform vec3 material_ks[SDF_MATERIALS];
uniform float material_shininess[SDF_MATERIALS];
#if LEARNT_PRODUCT_TP
uniform vec3 light_sh[SH_COEFFS];
#endif

out vec4 color;

void main() {
    vec3 ro, rd, p, n;
    int material;
    primary_ray(gl_FragCoord.xy, ro, rd);
    if (!trace(ro, rd, p, n, material)) {
        color = vec4(0.0, 0.0, 0.0, 1.0);
        return;
    }
    int id = clamp(material, 0, SDF_MATERIALS - 1);
    float T[SH_COEFFS];
    learnt_network(0, p, n, T);  // one network for the whole SDF (a constant index: see mlp)
    vec3 H[SH_COEFFS];
#if LEARNT_PRODUCT_TP
    triple_product(T, light_sh, H);
#else
    tpfl_product(T, H);
#endif
    vec3 wo = -rd;  // = normalize(eye - p): the hit lies on the primary ray
    color = vec4(shade_transferred(H, material_kd[id], material_ks[id], material_shininess[id],
                                   n, wo), 1.0);
}
