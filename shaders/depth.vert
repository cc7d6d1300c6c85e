#version 330 core
// Shadow-map pass: positions only, into the key light's orthographic depth map. With SURFACE (the
// far-field surface, fraytool.render.shadow_pass) also each vertex's far weight, for depth.frag.

uniform mat4 u_light_view_proj;
uniform mat4 u_model;

in vec3 in_position;
#ifdef SURFACE
in float in_far;
out float v_far;
#endif

void main() {
#ifdef SURFACE
    v_far = in_far;
#endif
    gl_Position = u_light_view_proj * u_model * vec4(in_position, 1.0);
}
