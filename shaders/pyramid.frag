#version 330 core
// One level of the photo's box pyramid (vebuild.texture): the mean of the 2x2 source texels
// {2i, min(2i+1, W-1)} x {2j, min(2j+1, H-1)}, as one bilinear fetch at their shared corner.
uniform sampler2D source;    // linear filtering, clamp to edge
uniform vec2 source_size;    // the source level's size in texels
uniform float source_y0;     // the source level's first row in its texture
uniform vec2 source_texture; // the source texture's size
uniform float target_y0;     // this level's first row in the target
layout(location = 0) out vec4 out_colour;
void main() {
    vec2 ij = floor(gl_FragCoord.xy) - vec2(0.0, target_y0);
    vec2 q = clamp(2.0 * ij + 1.0, vec2(0.5), source_size - 0.5);
    out_colour = vec4(texture(source, (q + vec2(0.0, source_y0)) / source_texture).rgb, 1.0);
}
