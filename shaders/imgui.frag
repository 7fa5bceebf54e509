#version 330 core
uniform sampler2D tex;
in vec2 v_uv;
in vec4 v_colour;
layout(location = 0) out vec4 out_colour;
void main() {
    out_colour = v_colour * texture(tex, v_uv);
}
