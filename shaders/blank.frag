#version 330 core
// Writes nothing of note and samples nothing (with fullscreen.vert): drawn into a 1x1 target so
// that the driver lets go of the textures the previous draw sampled (vebuild/texture/gpu.py,
// Extractor._unbind).
layout(location = 0) out vec4 out_colour;
void main() {
    out_colour = vec4(0.0);
}
