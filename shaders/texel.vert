#version 330 core
// Pass 2 (paper §4): the scene drawn in atlas space, one fragment per texel of a face's chart.
uniform vec2 page_size;     // the render target's size in atlas texels (before atlas_scale)
uniform float atlas_scale;  // 1 for the full atlas, < 1 for a reduced copy (exposure statistics)
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
}
