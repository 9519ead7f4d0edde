// Primary rays of a prtbench.scene.model.View through pixel centres, exactly View.primary_rays
// (OpenGL convention: the camera looks down its -Z; gl_FragCoord has y up, so row 0 of the
// read-back image is the top). Uniforms are set by prtbench.transport.sdf.bind_camera.
#ifndef PRTBENCH_SDF_CAMERA_GLSL
#define PRTBENCH_SDF_CAMERA_GLSL

uniform vec3 sdf_eye;                   // camera position, world space
uniform mat3 sdf_world_from_camera;     // columns: camera right, up, back
uniform float sdf_tan_half_fov;         // tan(fov_y / 2)
uniform vec2 sdf_viewport;              // width, height in pixels

void primary_ray(vec2 frag_coord, out vec3 ro, out vec3 rd) {
    vec2 ndc = frag_coord / sdf_viewport * 2.0 - 1.0;
    float aspect = sdf_viewport.x / sdf_viewport.y;
    vec3 d = vec3(ndc.x * sdf_tan_half_fov * aspect, ndc.y * sdf_tan_half_fov, -1.0);
    ro = sdf_eye;
    rd = normalize(sdf_world_from_camera * d);
}

#endif
