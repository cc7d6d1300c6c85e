#version 330 core
// Wireframe springs (Fig. 8): one flag per end, 0 at a base-model crossing, 1 at yarn level.

uniform mat4 u_view_proj;

in vec3 in_position;
in float in_yarn_level;

out float v_yarn_level;

void main() {
    v_yarn_level = in_yarn_level;
    gl_Position = u_view_proj * vec4(in_position, 1.0);
}
