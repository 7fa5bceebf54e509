#version 330 core
flat in float v_face;
in float v_depth;
layout(location = 0) out vec2 out_id_depth;  // (face id, camera depth); cleared to (0, +large)
void main() {
    out_id_depth = vec2(v_face, v_depth);
}
