// The radiance model's BRDF (DESIGN.md §4), shared by every method's shaders, and the
// display transform for previews (prtbench.io.imageio.display without exposure and clipping).
#ifndef PRTBENCH_BRDF_GLSL
#define PRTBENCH_BRDF_GLSL

const float BRDF_PI = 3.14159265358979323846;

// Mirror direction of wo about n (wo points away from the surface): r = 2(n·wo)n − wo.
// GLSL's reflect(I, N) reflects an incident direction, hence the sign flip.
vec3 phong_mirror(vec3 n, vec3 wo) {
    return reflect(-wo, n);
}

// f(wi, wo) = kd/π + ks (s+1)/(2π) max(wi·r, 0)^s, r = mirror of wo about n.
// The lobe is zero behind the mirror plane at every s: s = 0 is the hemisphere about r (as the
// reference's prtphong and sh.phong_zonal; pow(0, 0) is undefined in GLSL anyway).
vec3 phong_brdf(vec3 kd, vec3 ks, float s, vec3 n, vec3 wi, vec3 wo) {
    float cos_r = dot(wi, phong_mirror(n, wo));
    float lobe = cos_r > 0.0 ? pow(cos_r, s) : 0.0;
    return kd / BRDF_PI + ks * ((s + 1.0) / (2.0 * BRDF_PI)) * lobe;
}

// The sRGB transfer function on linear values, negatives clamped to 0 (no upper clip).
vec3 srgb_from_linear(vec3 linear) {
    vec3 x = max(linear, vec3(0.0));
    vec3 low = 12.92 * x;
    vec3 high = 1.055 * pow(x, vec3(1.0 / 2.4)) - 0.055;
    return mix(high, low, vec3(lessThanEqual(x, vec3(0.0031308))));
}

#endif  // PRTBENCH_BRDF_GLSL
