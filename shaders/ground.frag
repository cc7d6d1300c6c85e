#version 330 core
// Ground plane: a faint checkerboard (to read motion and scale) lit by the key light, fading into
// the background with distance from the scene centre so the horizon does not alias.

uniform vec3 u_light_dir;
uniform float u_light_intensity;
uniform float u_ambient;
uniform vec3 u_color;            // linear RGB
uniform vec3 u_background;       // linear RGB
uniform vec3 u_centre;           // scene centre on the plane [m]
uniform vec3 u_axis_u;           // in-plane unit axes
uniform vec3 u_axis_v;
uniform float u_cell;            // checker cell size [m]
uniform float u_fade_radius;     // distance where the plane has faded out [m]
uniform float u_alpha_out;       // 1: fade into transparency (premultiplied), 0: into the background
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
    vec3 d = v_position - u_centre;
    vec2 uv = vec2(dot(d, u_axis_u), dot(d, u_axis_v)) / u_cell;
    float checker = mod(floor(uv.x) + floor(uv.y), 2.0);
    vec3 N = normalize(v_normal);
    float diffuse = abs(dot(N, u_light_dir));
    vec3 albedo = u_color * mix(0.85, 1.0, checker);
    float key = u_light_intensity;
#ifdef SHADOWS
    key *= key_light_visibility(v_position, N);
#endif
    float ambient = u_ambient;
#ifdef FILL
    ambient += u_fill_intensity * (0.5 + 0.5 * dot(N, u_fill_dir));
#endif
    vec3 color = albedo * (ambient + key * diffuse);
    float fade = smoothstep(0.35 * u_fade_radius, u_fade_radius, length(d));
    if (u_alpha_out > 0.5) {
        f_color = to_target(vec4(color * (1.0 - fade), 1.0 - fade));
    } else {
        f_color = to_target(vec4(mix(color, u_background, fade), 1.0));
    }
}
