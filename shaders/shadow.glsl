// Key-light shadow lookup (fraytool.render.shadow), included by the yarn, body and ground fragment
// shaders when [render] shadows = true. The map holds the depth of the nearest caster seen from
// the light (orthographic); a sampler2DShadow with GL_LINEAR compares 2 x 2 texels and blends the
// results (percentage-closer filtering, Reeves et al. 1987). Receivers that can be small on screen
// next to fine shadow detail (the ground, bodies) take four such lookups 1.5 texels apart, a 4 x 4
// texel footprint; with SHADOW_ONE_TAP (the yarns: the map is fitted to them, so a texel is about a
// pixel of a yarn in the framings we ship) one lookup, a 2 x 2 footprint, at a quarter of the cost.

uniform sampler2DShadow u_shadow_map;
uniform mat4 u_light_view_proj;   // world -> light clip space
uniform float u_shadow_texel;     // 1 / map size
uniform float u_shadow_offset_m;  // receivers are looked up this far along their normal [m]

float key_light_visibility(vec3 position, vec3 normal) {
    vec4 clip = u_light_view_proj * vec4(position + u_shadow_offset_m * normal, 1.0);
    vec3 q = clip.xyz * 0.5 + 0.5;
    q.z = clamp(q.z, 0.0, 1.0);
#ifdef SHADOW_ONE_TAP
    return texture(u_shadow_map, q);
#else
    float d = 0.75 * u_shadow_texel;
    float lit = texture(u_shadow_map, vec3(q.xy + vec2(-d, -d), q.z))
              + texture(u_shadow_map, vec3(q.xy + vec2( d, -d), q.z))
              + texture(u_shadow_map, vec3(q.xy + vec2(-d,  d), q.z))
              + texture(u_shadow_map, vec3(q.xy + vec2( d,  d), q.z));
    return 0.25 * lit;
#endif
}
