#version 330 core
layout(lines) in;
layout(triangle_strip, max_vertices = 4) out;
uniform vec2 viewport;     // framebuffer size in pixels
uniform float half_width;  // pixels
in float g_depth[];
out float v_depth;
void main() {
    vec4 a = gl_in[0].gl_Position, b = gl_in[1].gl_Position;  // both in front (clipped on the CPU)
    vec2 sa = a.xy / a.w * 0.5 * viewport, sb = b.xy / b.w * 0.5 * viewport;
    vec2 d = sb - sa;
    float len = length(d);
    d = len > 1e-6 ? d / len : vec2(1.0, 0.0);
    vec2 n = vec2(-d.y, d.x) * half_width;
    vec2 e = d * half_width;
    vec2 corners[4] = vec2[4](sa - e - n, sa - e + n, sb + e - n, sb + e + n);
    for (int i = 0; i < 4; ++i) {
        vec4 c = i < 2 ? a : b;
        gl_Position = vec4(corners[i] / (0.5 * viewport) * c.w, c.z, c.w);
        v_depth = g_depth[i < 2 ? 0 : 1];
        EmitVertex();
    }
    EndPrimitive();
}
