// Real spherical harmonics, matching prtbench/sh.py exactly (DESIGN.md §5):
// orthonormal, no Condon–Shortley phase, polar axis +Z, flat index i = l(l+1) + m.
// Requires SH_BANDS (1..8) to be #defined before inclusion (load_program(defines=...)).
// Included once per stage by prtbench.render.gl.load_program; the guard covers other loaders.
#ifndef PRTBENCH_SH_GLSL
#define PRTBENCH_SH_GLSL

#ifndef SH_BANDS
#error "sh.glsl: define SH_BANDS (1..8) before including it"
#endif
#if SH_BANDS < 1 || SH_BANDS > 8
#error "sh.glsl: SH_BANDS must be 1..8"
#endif

#define SH_COEFFS (SH_BANDS * SH_BANDS)

const float SH_PI = 3.14159265358979323846;

// All SH_COEFFS basis functions at direction `dir` (normalised here).
// Same recurrence as sh.eval_sh: normalised associated Legendre functions q_l^m (sin^m θ
// factored out) and (x + iy)^m = sin^m θ e^{imφ} for the azimuth, so no atan2 and no
// factorials. Loop bounds are compile-time constants, so compilers can unroll fully.
void sh_eval(vec3 dir, out float y[SH_COEFFS]) {
    vec3 d = normalize(dir);
    float re = 1.0;                          // Re (x + iy)^m
    float im = 0.0;                          // Im (x + iy)^m
    float qmm = 0.28209479177387814;         // sqrt(1 / 4π): q_0^0
    for (int m = 0; m < SH_BANDS; ++m) {
        if (m > 0) {
            qmm *= sqrt(float(2 * m + 1) / float(2 * m));
            float re_next = re * d.x - im * d.y;
            im = re * d.y + im * d.x;
            re = re_next;
        }
        float q_prev2 = 0.0;
        float q_prev = qmm;
        for (int l = m; l < SH_BANDS; ++l) {
            float q;
            if (l == m) {
                q = qmm;
            } else if (l == m + 1) {
                q = sqrt(float(2 * m + 3)) * d.z * qmm;
            } else {
                float fl = float(l);
                float fm = float(m);
                float a = sqrt((4.0 * fl * fl - 1.0) / (fl * fl - fm * fm));
                float b = sqrt(((fl - 1.0) * (fl - 1.0) - fm * fm) / (4.0 * (fl - 1.0) * (fl - 1.0) - 1.0));
                q = a * (d.z * q_prev - b * q_prev2);
            }
            if (l > m) {
                q_prev2 = q_prev;
                q_prev = q;
            }
            int center = l * (l + 1);
            if (m == 0) {
                y[center] = q;
            } else {
                y[center + m] = 1.41421356237309505 * q * re;
                y[center - m] = 1.41421356237309505 * q * im;
            }
        }
    }
}

// Σ_i a_i b_i: the integral of the product of two band-limited functions.
float sh_dot(float a[SH_COEFFS], float b[SH_COEFFS]) {
    float sum = 0.0;
    for (int i = 0; i < SH_COEFFS; ++i) {
        sum += a[i] * b[i];
    }
    return sum;
}

// Zonal convolution evaluated along `axis` (sh.zonal_convolve):
// (g ⋆ H)(a) = Σ_l sqrt(4π / (2l+1)) g_l Σ_m H_lm Y_lm(a), zonal[l] = g_l (e.g. sh.phong_zonal).
float sh_zonal_eval(float coeffs[SH_COEFFS], float zonal[SH_BANDS], vec3 axis) {
    float y[SH_COEFFS];
    sh_eval(axis, y);
    float sum = 0.0;
    for (int l = 0; l < SH_BANDS; ++l) {
        float band = 0.0;
        for (int m = -l; m <= l; ++m) {
            band += coeffs[l * (l + 1) + m] * y[l * (l + 1) + m];
        }
        sum += sqrt(4.0 * SH_PI / float(2 * l + 1)) * zonal[l] * band;
    }
    return sum;
}

// RGB variant of sh_zonal_eval: coefficients hold one vec3 (R, G, B) per basis function.
vec3 sh_zonal_eval_rgb(vec3 coeffs[SH_COEFFS], float zonal[SH_BANDS], vec3 axis) {
    float y[SH_COEFFS];
    sh_eval(axis, y);
    vec3 sum = vec3(0.0);
    for (int l = 0; l < SH_BANDS; ++l) {
        vec3 band = vec3(0.0);
        for (int m = -l; m <= l; ++m) {
            band += coeffs[l * (l + 1) + m] * y[l * (l + 1) + m];
        }
        sum += sqrt(4.0 * SH_PI / float(2 * l + 1)) * zonal[l] * band;
    }
    return sum;
}

#endif  // PRTBENCH_SH_GLSL
