#version 330 core
// A photo camera's render through its lens (renderer.py): the scene drawn as the pinhole image
// that covers the photo's undistorted bounds (vebuild/texture/lens.py) is resampled onto the
// photo's pixels. Each pixel centre, as the lens put it, is undistorted in closed form by the
// division model of vebuild/camera.py, x_u = x_d / (1 + k1 r^2 + k2 r^4) with x_d = (u - c) / f, r = |x_d|, and the
// pinhole image is sampled there bilinearly, in linear light (its texels hold sRGB codes).
uniform sampler2D pinhole;  // RGBA8: sRGB-encoded colour, coverage in alpha; image order (row 0 at the top)
uniform float focal;        // f of the photo's K, pixels
uniform vec2 principal;     // c of the photo's K, pixels
uniform float k1;
uniform float k2;
uniform vec2 cover_origin;  // the pinhole image's pixel corner (0, 0) in the photo's pinhole pixels
uniform vec2 size;          // the photo's size, pixels (the viewport's)
uniform vec2 origin;        // lower-left corner of the viewport in the target
uniform int flip;           // 1 for a window: image row 0 at the top of the screen
layout(location = 0) out vec4 out_colour;

vec3 to_srgb(vec3 c) {
    c = clamp(c, 0.0, 1.0);
    return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), c));
}

vec3 to_linear(vec3 s) {
    return mix(s / 12.92, pow((s + 0.055) / 1.055, vec3(2.4)), step(vec3(0.04045), s));
}

vec4 fetch(ivec2 i) {
    vec4 t = texelFetch(pinhole, clamp(i, ivec2(0), textureSize(pinhole, 0) - 1), 0);
    return vec4(to_linear(t.rgb), t.a);
}

void main() {
    vec2 p = gl_FragCoord.xy - origin;  // the pixel's centre, rows counted from the viewport's first
    if (flip == 1) p.y = size.y - p.y;
    vec2 xd = (p - principal) / focal;
    float r2 = dot(xd, xd);
    vec2 q = principal + focal * xd / (1.0 + k1 * r2 + k2 * r2 * r2) - cover_origin;
    vec2 t = q - 0.5;  // texel centres at half-integers
    ivec2 i = ivec2(floor(t));
    vec2 w = t - vec2(i);
    vec4 c = mix(mix(fetch(i), fetch(i + ivec2(1, 0)), w.x), mix(fetch(i + ivec2(0, 1)), fetch(i + ivec2(1, 1)), w.x),
                 w.y);
    out_colour = vec4(to_srgb(c.rgb), c.a);
}
