#version 430
// The atlas mesh of a per-texel method (methods.common.atlas.raster.AtlasRenderer), vertex
// stage: passes the world position, the shading frame, both UVs, the texture set and the
// object's constant material to the method's fragment stage, which samples its textures.
invariant gl_Position;

uniform mat4 clip_from_world;

in vec3 in_position;
in vec3 in_normal;
in vec2 in_atlas_uv;
in vec2 in_mesh_uv;
in vec4 in_tangent;
in vec3 in_kd;
in vec3 in_ks;
in float in_shininess;
in float in_texture_set;
in float in_normal_mapped;

out vec3 world_position;
out vec3 normal;
out vec2 atlas_uv;
out vec2 mesh_uv;
out vec4 tangent;
flat out vec3 kd;
flat out vec3 ks;
flat out float shininess;
flat out int texture_set;
flat out int normal_mapped;

void main() {
    world_position = in_position;  // scenes are stored in world space
    normal = in_normal;
    atlas_uv = in_atlas_uv;
    mesh_uv = in_mesh_uv;
    tangent = in_tangent;
    kd = in_kd;
    ks = in_ks;
    shininess = in_shininess;
    texture_set = int(in_texture_set + 0.5);
    normal_mapped = in_normal_mapped > 0.5 ? 1 : 0;
    gl_Position = clip_from_world * vec4(in_position, 1.0);
}
