#version 330 core
// Pass 2 (paper §4): the scene drawn in atlas space, one fragment per texel of a face's chart.
//
// Each texel's world position is affine in its atlas position on a (planar) triangle, so planes
// in the world clip the chart: MODES 0-2 (vebuild/texture/gpu.py enables gl_ClipDistance[0..4]
// for them) draw only the part of a face that projects into the ID buffer's frame, widened by
// CLIP_MARGIN pixels, and in front of the camera. texel.frag discards every texel outside it
// anyway; the GPU then never runs its fragments. MODE 3 (geometry) draws whole charts.
#define CLIP_MARGIN 2.0
uniform vec2 page_size;     // the render target's size in atlas texels (before atlas_scale)
uniform float atlas_scale;  // 1 for the full atlas, < 1 for a reduced copy (exposure statistics)
uniform mat3 K;
uniform mat3 R;
uniform vec3 C;
uniform vec2 id_origin;
uniform vec2 id_size;
in vec3 in_position;
in vec3 in_normal;
in vec2 in_atlas;
in float in_face;
in vec3 in_eu;
in vec3 in_ev;
out vec3 v_position;
out vec3 v_normal;
flat out float v_face;
flat out vec3 v_eu;
flat out vec3 v_ev;
void main() {
    v_position = in_position;
    v_normal = in_normal;
    v_face = in_face;
    v_eu = in_eu / atlas_scale;
    v_ev = in_ev / atlas_scale;
    gl_Position = vec4(in_atlas / page_size * 2.0 - 1.0, 0.0, 1.0);
#if MODE != 3
    vec3 x = R * (in_position - C);
    vec3 h = K * x;  // h.z = x.z: K's last row is (0, 0, 1)
    vec2 lo = id_origin - CLIP_MARGIN, hi = id_origin + id_size + CLIP_MARGIN;
    gl_ClipDistance[0] = h.x - lo.x * h.z;
    gl_ClipDistance[1] = hi.x * h.z - h.x;
    gl_ClipDistance[2] = h.y - lo.y * h.z;
    gl_ClipDistance[3] = hi.y * h.z - h.y;
    gl_ClipDistance[4] = x.z;
#endif
}
