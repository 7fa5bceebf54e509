#version 330 core
// Dear ImGui's draw lists (viewer/gui.py): positions in window pixels, origin top-left.
uniform vec2 display_size;
in vec2 in_position;
in vec2 in_uv;
in vec4 in_colour;
out vec2 v_uv;
out vec4 v_colour;
void main() {
    v_uv = in_uv;
    v_colour = in_colour;
    gl_Position = vec4(in_position.x / display_size.x * 2.0 - 1.0, 1.0 - in_position.y / display_size.y * 2.0,
                       0.0, 1.0);
}
