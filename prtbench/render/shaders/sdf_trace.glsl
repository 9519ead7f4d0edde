// Sphere tracing of the generated scene SDF: the GLSL twin of prtbench/sdf/trace.py (same loop,
// same constants). Needs the virtual include scene_sdf.glsl (prtbench.transport.sdf.SdfSurface.glsl(),
// passed to prtbench.render.gl.load_program as sources=surface.glsl_sources()), which defines
// scene_sdf / scene_material / scene_sdf_material and SDF_BOUNDS_LO, SDF_BOUNDS_HI,
// SDF_HIT_EPS, SDF_NORMAL_STEP.
//
//   bool  trace(vec3 ro, vec3 rd, out vec3 p, out vec3 n, out int material)
//   bool  sdf_occluded(vec3 ro, vec3 rd, float tmax)
//   float sdf_march(vec3 ro, vec3 rd, float tmin, float tmax)   // hit distance or -1
//   vec3  sdf_normal(vec3 p)
#ifndef PRTBENCH_SDF_TRACE_GLSL
#define PRTBENCH_SDF_TRACE_GLSL

#include "scene_sdf.glsl"

#ifndef SDF_MAX_STEPS
#define SDF_MAX_STEPS 512
#endif
#ifndef SDF_RELAXATION
#define SDF_RELAXATION 1.4
#endif

// Entry and exit distances of the ray through the bounds box; false when it misses the box.
bool sdf_box_interval(vec3 ro, vec3 rd, out float t0, out float t1) {
    vec3 inv = 1.0 / rd;
    vec3 a = (SDF_BOUNDS_LO - ro) * inv;
    vec3 b = (SDF_BOUNDS_HI - ro) * inv;
    vec3 near_t = min(a, b);
    vec3 far_t = max(a, b);
    t0 = max(max(near_t.x, near_t.y), near_t.z);
    t1 = min(min(far_t.x, far_t.y), far_t.z);
    return t0 <= t1;
}

// Over-relaxed sphere tracing (Keinert et al. 2014) of [tmin, tmax] inside the bounds box.
// Steps are omega * d; when the step left a gap between the unbounding spheres of this and the
// previous point, or landed inside, it is undone and the safe step d taken (omega = 1 after).
float sdf_march(vec3 ro, vec3 rd, float tmin, float tmax) {
    float t0, t1;
    if (!sdf_box_interval(ro, rd, t0, t1)) return -1.0;
    float t = max(t0, tmin);
    float end_t = min(t1, tmax);
    if (t > end_t) return -1.0;
    float omega = SDF_RELAXATION;
    float prev_r = 0.0;
    float prev_step = 0.0;
    for (int i = 0; i < SDF_MAX_STEPS; ++i) {
        float r = scene_sdf(ro + t * rd);
        bool fail = omega > 1.0 && prev_step > 0.0 && (abs(r) + prev_r < prev_step || r < 0.0);
        if (fail) {
            t = t - prev_step + prev_r;
            omega = 1.0;
            prev_step = prev_r;
        } else {
            if (r < SDF_HIT_EPS) return t;
            float step_t = omega * r;
            t += step_t;
            prev_r = r;
            prev_step = step_t;
            if (t > end_t) return -1.0;
        }
    }
    return -1.0;
}

// Never set, so 0 (GL zero-initialises uniforms) but unknown to the compiler: loops bounded
// by N + sdf_loop_zero stay rolled. Compilers inline every call, so this keeps one copy of
// scene_sdf per loop instead of one per unrolled iteration (a neural SDF made llvmpipe take
// tens of seconds to compile the unrolled normal taps).
uniform int sdf_loop_zero;

const vec3 SDF_TETRAHEDRON[4] = vec3[](vec3(1.0, -1.0, -1.0), vec3(-1.0, -1.0, 1.0),
                                       vec3(-1.0, 1.0, -1.0), vec3(1.0, 1.0, 1.0));

// Unit outward normal: tetrahedral differences (4 evaluations) with step SDF_NORMAL_STEP.
vec3 sdf_normal(vec3 p) {
    vec3 g = vec3(0.0);
    for (int i = 0; i < 4 + sdf_loop_zero; ++i) {
        vec3 k = SDF_TETRAHEDRON[i];
        g += k * scene_sdf(p + k * SDF_NORMAL_STEP);
    }
    float len = length(g);
    return len > 0.0 ? g / len : vec3(0.0, 1.0, 0.0);
}

// First hit of the ray (ro, unit rd): position, unit normal and material id (-1 on a miss).
bool trace(vec3 ro, vec3 rd, out vec3 p, out vec3 n, out int material) {
    float t = sdf_march(ro, rd, 0.0, 3.0e38);
    if (t < 0.0) {
        p = vec3(0.0);
        n = vec3(0.0);
        material = -1;
        return false;
    }
    p = ro + t * rd;
    n = sdf_normal(p);
    scene_sdf_material(p, material);
    return true;
}

// Is anything hit along (ro, unit rd) before tmax? Offset ro off the surface first.
bool sdf_occluded(vec3 ro, vec3 rd, float tmax) {
    return sdf_march(ro, rd, 0.0, tmax) >= 0.0;
}

#endif
