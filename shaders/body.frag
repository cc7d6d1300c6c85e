#version 330 core
// Rigid bodies: Lambert plus a soft Blinn-Phong highlight under the key light, linear RGB.

uniform vec3 u_eye;
uniform vec3 u_light_dir;
uniform float u_light_intensity;
uniform float u_ambient;
uniform vec3 u_color;            // linear RGB
#ifdef FILL
uniform float u_fill_intensity;  // soft fill: hemisphere light around u_fill_dir
uniform vec3 u_fill_dir;
#endif
#ifdef SHADOWS
#include "shadow.glsl"
#endif

in vec3 v_position;
in vec3 v_normal;

#include "output.glsl"

out vec4 f_color;

void main() {
    vec3 N = normalize(v_normal);
    vec3 E = normalize(u_eye - v_position);
    if (dot(N, E) < 0.0) N = -N;    // planes are seen from both sides
    vec3 L = u_light_dir;
    vec3 H = normalize(L + E);
    float diffuse = max(dot(N, L), 0.0);
    float highlight = 0.15 * pow(max(dot(N, H), 0.0), 32.0) * step(0.0, dot(N, L));
    float key = u_light_intensity;
#ifdef SHADOWS
    key *= key_light_visibility(v_position, N);
#endif
    float ambient = u_ambient;
#ifdef FILL
    ambient += u_fill_intensity * (0.5 + 0.5 * dot(N, u_fill_dir));
#endif
    vec3 color = u_color * (ambient + key * diffuse) + vec3(key * highlight);
    f_color = to_target(vec4(color, 1.0));
}
