#version 330 core
// Red-cyan anaglyph (renderer.py): the left and right eyes' sRGB images, decoded to linear light,
// mixed through least-squares colour matrices, encoded to sRGB again.
uniform sampler2D left;
uniform sampler2D right;
uniform mat3 anaglyph_left;
uniform mat3 anaglyph_right;
uniform ivec2 origin;   // lower-left corner of the viewport in the target
uniform int flip;       // 1 for a window: image row 0 at the top of the screen
layout(location = 0) out vec4 out_colour;

vec3 to_srgb(vec3 c) {
    c = clamp(c, 0.0, 1.0);
    return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), c));
}

vec3 to_linear(vec3 s) {
    return mix(s / 12.92, pow((s + 0.055) / 1.055, vec3(2.4)), step(vec3(0.04045), s));
}

void main() {
    ivec2 size = textureSize(left, 0);
    ivec2 p = ivec2(gl_FragCoord.xy) - origin;
    if (flip == 1) p.y = size.y - 1 - p.y;
    vec3 l = to_linear(texelFetch(left, p, 0).rgb);
    vec3 r = to_linear(texelFetch(right, p, 0).rgb);
    out_colour = vec4(to_srgb(anaglyph_left * l + anaglyph_right * r), 1.0);
}
