#version 330 core
// Shadow-map pass: positions only, into the key light's orthographic depth map.

uniform mat4 u_light_view_proj;
uniform mat4 u_model;

in vec3 in_position;

void main() {
    gl_Position = u_light_view_proj * u_model * vec4(in_position, 1.0);
}
