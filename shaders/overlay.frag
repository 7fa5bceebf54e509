#version 330 core
// A photo laid over the view from its own camera (viewer/app.py), in a window (image row 0 at the
// top of the viewport), with the user's opacity. Values are blended as stored (sRGB).
uniform sampler2D photo;
uniform float opacity;
uniform vec2 origin;  // lower-left corner of the viewport, window pixels
uniform vec2 size;    // viewport size
layout(location = 0) out vec4 out_colour;
void main() {
    vec2 p = (gl_FragCoord.xy - origin) / size;
    out_colour = vec4(texture(photo, vec2(p.x, 1.0 - p.y)).rgb, opacity);
}
