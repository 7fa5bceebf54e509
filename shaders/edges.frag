#version 330 core
in float v_depth;
layout(location = 0) out vec2 out_id_depth;
void main() {
    out_id_depth = vec2(0.0, v_depth);  // id 0: "nothing" -- no texel is taken here
}
