#version 330 core
// A registered laser scan drawn as GL points (vebuild.gl.points): each point its own colour.
uniform mat4 view;        // world -> camera (vebuild.camera.view_matrix)
uniform mat4 projection;  // camera -> clip (vebuild.camera.gl_projection)
uniform float point_size; // pixels
uniform float depth_pull; // share of its distance a point is pulled toward the eye along its ray (its pixel
                          // unchanged), so that a point on a face is not hidden by that face
in vec3 in_position;
in vec3 in_colour;        // sRGB, 0..1
out vec3 v_colour;
void main() {
    vec4 x_cam = view * vec4(in_position, 1.0);
    x_cam.xyz *= 1.0 - depth_pull;
    gl_Position = projection * x_cam;
    gl_PointSize = point_size;
    v_colour = in_colour;
}
