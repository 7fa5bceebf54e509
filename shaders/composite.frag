#version 330 core
// Final pass (renderer.py): a resolved linear image (or a stereo pair) to sRGB 8-bit output.
// mode 0: one image; mode 1: red-cyan anaglyph from the left and right images through
// least-squares colour matrices (applied in linear light).
uniform sampler2D left;
uniform sampler2D right;
uniform int mode;
uniform mat3 anaglyph_left;
uniform mat3 anaglyph_right;
uniform ivec2 origin;   // lower-left corner of the viewport in the target
uniform int flip;       // 1 for a window: image row 0 at the top of the screen
layout(location = 0) out vec4 out_colour;

vec3 to_srgb(vec3 c) {
    c = clamp(c, 0.0, 1.0);
    return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), c));
}

void main() {
    ivec2 size = textureSize(left, 0);
    ivec2 p = ivec2(gl_FragCoord.xy) - origin;
    if (flip == 1) p.y = size.y - 1 - p.y;
    vec3 c = texelFetch(left, p, 0).rgb;
    if (mode == 1) c = anaglyph_left * c + anaglyph_right * texelFetch(right, p, 0).rgb;
    out_colour = vec4(to_srgb(c), 1.0);
}
