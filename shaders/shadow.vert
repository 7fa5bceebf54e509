#version 330 core
// Depth of the scene seen from a light, into one tile of the shadow atlas (renderer.py).
uniform mat4 light_matrix;  // world -> the tile's clip space
in vec3 in_position;
void main() {
    gl_Position = light_matrix * vec4(in_position, 1.0);
}
