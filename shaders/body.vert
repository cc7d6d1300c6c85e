#version 330 core
// Rigid bodies and the ground plane: a unit mesh placed by a model matrix.

uniform mat4 u_view_proj;
uniform mat4 u_model;
uniform mat3 u_normal_matrix;

in vec3 in_position;
in vec3 in_normal;

out vec3 v_position;
out vec3 v_normal;

void main() {
    vec4 world = u_model * vec4(in_position, 1.0);
    v_position = world.xyz;
    v_normal = u_normal_matrix * in_normal;
    gl_Position = u_view_proj * world;
}
