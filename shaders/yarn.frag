#version 330 core
// Yarn shading: Kajiya-Kay on the yarn tangent combined with Lambert on the tube normal.
//
// Kajiya & Kay 1989, "Rendering fur with three dimensional textures", SIGGRAPH: a thin fibre with
// tangent T lit from L seen from E has
//   diffuse   sin(T, L)
//   specular  cos(thetaL - thetaE)^p = ((T.Li)(T.E) + sin(T, Li) sin(T, E))^p
// where Li = -L is the direction the light travels (their convention), so the highlight lies on
// the cone of mirror directions around the fibre (both terms come from yarn.vert). A yarn is a
// tube of many fibres, so Lambert on the tube normal adds the round shape (one side lit, one in
// shade); the two diffuse terms are mixed by u_kajiya_weight, and the highlight fades out on the
// side facing away from the light (a self-shadowing term, as in Scheuermann 2004). All maths in
// linear RGB; output.glsl encodes to sRGB for the 8-bit target.

uniform vec3 u_light_dir;        // unit vector towards the key light
uniform float u_light_intensity;
uniform float u_ambient;
uniform float u_specular;
uniform float u_kajiya_weight;   // 0: Lambert only, 1: Kajiya-Kay diffuse only
#ifdef FILL
uniform float u_fill_intensity;  // soft fill: hemisphere light around u_fill_dir
uniform vec3 u_fill_dir;
#endif
#ifdef SHADOWS
#include "shadow.glsl"
#endif
#ifdef RIBBON
// Ribbons (fraytool.render.ribbon): the strip through the yarn's axis faces the eye; v_normal is
// v S, v in [-1, 1] across it. The ray from the eye through this pixel's point P of the strip meets
// the tube at P + r sqrt(1 - v^2) / sin(theta) E (E towards the eye, theta between E and the yarn),
// where the tube's normal is v S + sqrt(1 - v^2) V (V: E square to the yarn, normalised): the normal
// shades the pixel, the point is looked up in the shadow map and its depth is written, so the strip
// draws as the round tube. The depth is one per pixel for all its samples (gl_FragDepth), so it is
// found at the centroid of the samples the strip covers, not at the pixel's centre: at the strip's
// edge the centre lies outside it (|v| > 1, the tube's deepest, its axis), and the yarn behind took
// the samples the strip covers there, a rim of the other family around every yarn's silhouette.
uniform mat4 u_view_proj;
uniform vec3 u_eye;
uniform float u_yarn_radius;     // [m]
in vec3 v_tangent;
// Straight steps (fraytool.render.ribbon; yarn.vert): the tangent and Kajiya-Kay terms along a step
// are its ends' blend plus 4 t (1 - t) times its middle's departure from it, t from 0 at the step's
// start to 1 at its end (clamped: MSAA evaluates at a pixel's centre, which may lie past the step).
in float v_step;
flat in float v_step_start;
flat in vec3 v_step_bend;
flat in vec2 v_step_kajiya;
#endif

in vec3 v_normal;
in vec2 v_kajiya;
in vec4 v_albedo;
#if defined(SHADOWS) || defined(RIBBON)
in vec3 v_position;
#endif

#include "output.glsl"
#ifdef FAR_BAND
#include "band.glsl"
in float v_far;
#endif

out vec4 f_color;

#ifdef RIBBON
// The point where the ray through `position` (on the strip, `across` = v S there) enters the tube,
// and the tube's normal there, not normalised (module comment above).
vec3 tube_entry(vec3 position, vec3 across, vec3 tangent, out vec3 n) {
    vec3 T = normalize(tangent);
    vec3 E = normalize(u_eye - position);
    vec3 across_view = E - dot(E, T) * T;          // length sin(theta)
    float sin_theta = max(length(across_view), 0.2); // looking (nearly) along the yarn: bounded
    float bulge = sqrt(1.0 - min(dot(across, across), 1.0));
    n = across + bulge * (across_view / sin_theta);
    return position + (u_yarn_radius * bulge / sin_theta) * E;
}
#endif

#ifdef RIBBON
float step_bump(float step) {
    float t = clamp(step - v_step_start, 0.0, 1.0);
    return 4.0 * t * (1.0 - t);
}
#endif

void main() {
#ifdef RIBBON
    float bump = step_bump(v_step);
    vec2 kajiya = v_kajiya + bump * v_step_kajiya;
    vec3 n;
    vec3 surface = tube_entry(v_position, v_normal, v_tangent + bump * v_step_bend, n);
    vec3 N = dot(n, n) > 1e-12 ? normalize(n) : normalize(u_eye - v_position);  // seen exactly end-on: face the eye
    vec3 unused;
    vec3 covered = tube_entry(interpolateAtCentroid(v_position), interpolateAtCentroid(v_normal),
                              interpolateAtCentroid(v_tangent)
                              + step_bump(interpolateAtCentroid(v_step)) * v_step_bend, unused);
    vec4 clip = u_view_proj * vec4(covered, 1.0);
    gl_FragDepth = clamp(0.5 * clip.z / clip.w + 0.5, 0.0, 1.0);
#else
    vec3 N = normalize(v_normal);
    vec2 kajiya = v_kajiya;
#endif
#if defined(SHADOWS) && !defined(RIBBON)
    vec3 surface = v_position;
#endif
    float n_l = dot(N, u_light_dir);
    float diffuse = mix(max(n_l, 0.0), kajiya.x, u_kajiya_weight);
    float highlight = u_specular * kajiya.y * smoothstep(-0.2, 0.3, n_l);
    float key = u_light_intensity;
#ifdef SHADOWS
    key *= key_light_visibility(surface, N);
#endif
    float ambient = u_ambient;
#ifdef FILL
    ambient += u_fill_intensity * (0.5 + 0.5 * dot(N, u_fill_dir));
#endif
    vec3 color = v_albedo.rgb * (ambient + key * diffuse) + vec3(key * highlight);
    // Clamped as a fixed-point target clamps before blending, so a float target blends the same:
    // with MSAA, attributes are evaluated at the pixel centre, which may lie outside the triangle,
    // and the fade alpha extrapolated there can leave [0, 1].
#ifdef FAR_BAND
    gl_SampleMask[0] = band_yarn_mask(v_far);
#endif
    f_color = to_target(vec4(max(color, 0.0), clamp(v_albedo.a, 0.0, 1.0)));
}
