#version 330 core
// Pass 1 (paper §4, Figure 8): every face drawn with its 1-based id and camera depth.
uniform mat4 view;        // world -> camera (vebuild.camera.view_matrix)
uniform mat4 projection;  // camera -> clip (vebuild.camera.gl_projection)
in vec3 in_position;
in float in_face;
flat out float v_face;
out float v_depth;
void main() {
    vec4 x_cam = view * vec4(in_position, 1.0);
    v_depth = x_cam.z;
    v_face = in_face;
    gl_Position = projection * x_cam;
}
