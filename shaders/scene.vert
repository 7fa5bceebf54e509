#version 330 core
// The scene for display (renderer.py): world position, normal, atlas coordinate, base colour.
uniform mat4 view;        // world -> camera (vebuild.camera.view_matrix)
uniform mat4 projection;  // camera -> clip (vebuild.camera.gl_projection)
in vec3 in_position;
in vec3 in_normal;
in vec2 in_uv;            // atlas coordinate on this face's page, [0, 1], row 0 at the top
in vec3 in_colour;        // linear base colour where the face has no texture
in float in_node;         // index of the node the face belongs to (highlighting)
out vec3 v_world;
out vec3 v_normal;
out vec2 v_uv;
out vec3 v_colour;
flat out int v_node;
void main() {
    v_world = in_position;
    v_normal = in_normal;
    v_uv = in_uv;
    v_colour = in_colour;
    v_node = int(in_node + 0.5);
    gl_Position = projection * (view * vec4(in_position, 1.0));
}
