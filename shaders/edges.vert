#version 330 core
// Erosion of the ID buffer: face borders and silhouettes drawn `half_width` pixels either side.
uniform mat4 view;
uniform mat4 projection;
uniform float shrink;  // < 1: moves the edge toward the camera along its own ray (same pixel, nearer)
in vec3 in_position;
out float g_depth;
void main() {
    vec3 x_cam = (view * vec4(in_position, 1.0)).xyz * shrink;
    g_depth = x_cam.z;
    gl_Position = projection * vec4(x_cam, 1.0);
}
