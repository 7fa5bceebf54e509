#version 330 core
// The merge (vebuild/texture/__init__.py, "Merge"): one page's sums -> 8-bit sRGB colour and
// a coverage map. Unseen texels come out with alpha 0 and are filled on the CPU.
uniform sampler2D low_sum;      // (sum w l/g, sum w) over kept views
uniform sampler2D detail_sum;   // (sum w^s (c - l)/g, sum w^s) over kept views
uniform sampler2D dropped_sum;  // (sum v c/g, sum v) over dropped views, v = w / best weight
uniform sampler2D counts;       // (kept views, dropped views)
uniform sampler2D geometry;     // face id (MODE 3 of texel.frag into one channel)
uniform float exposure_scale;
uniform vec4 coverage_unseen;
uniform vec4 coverage_dropped_only;
uniform vec4 coverage_views[4];
layout(location = 0) out vec4 out_colour;
layout(location = 1) out vec4 out_coverage;

vec3 to_srgb(vec3 c) {
    c = clamp(c, 0.0, 1.0);
    return mix(12.92 * c, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), c));
}

void main() {
    ivec2 ij = ivec2(gl_FragCoord.xy);
    vec4 low = texelFetch(low_sum, ij, 0);
    vec4 detail = texelFetch(detail_sum, ij, 0);
    vec4 dropped = texelFetch(dropped_sum, ij, 0);
    float kept = texelFetch(counts, ij, 0).r;
    bool on_face = texelFetch(geometry, ij, 0).r > 0.0;
    vec3 c = vec3(0.0);
    bool seen = true;
    if (low.a > 0.0) {
        c = low.rgb / low.a + (detail.a > 0.0 ? detail.rgb / detail.a : vec3(0.0));
    } else if (dropped.a > 0.0) {
        c = dropped.rgb / dropped.a;
    } else {
        seen = false;
    }
    out_colour = vec4(to_srgb(c * exposure_scale), seen ? 1.0 : 0.0);
    if (!on_face) out_coverage = vec4(0.0);
    else if (!seen) out_coverage = coverage_unseen;
    else if (kept < 0.5) out_coverage = coverage_dropped_only;
    else out_coverage = coverage_views[int(clamp(kept + 0.5, 1.0, 4.0)) - 1];
}
