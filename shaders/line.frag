#version 330 core
// Base-model springs purple, yarn-level springs blue (docs/method.md §6, Fig. 8), linear RGB.

uniform vec3 u_base_color;
uniform vec3 u_yarn_color;

in float v_yarn_level;

#include "output.glsl"

out vec4 f_color;

void main() {
    f_color = to_target(vec4(mix(u_base_color, u_yarn_color, step(0.5, v_yarn_level)), 1.0));
}
