#version 330 core
// Yarn tubes (fraytool.render.geometry): world-space vertices, normals and yarn tangents.
// The Kajiya-Kay terms depend only on the tangent, the light and the view direction, which are
// smooth along a yarn and constant around it, so they are evaluated here per vertex (cheaper on a
// software rasteriser: fewer interpolated values); Lambert, which needs the normal across the
// tube, is evaluated per fragment. See yarn.frag for the model. With RIBBON the vertices are on
// view-facing strips and in_normal is the signed direction across the strip (fraytool.render.ribbon).

uniform mat4 u_view_proj;
uniform vec3 u_eye;              // camera position [m]
uniform vec3 u_light_dir;        // unit vector towards the key light
uniform float u_shininess;
uniform vec3 u_yarn_colors[32];  // linear RGB by colour index (fraytool.render.color.yarn_palette)

in vec3 in_position;
in vec3 in_normal;
in vec3 in_tangent;
in float in_alpha;
in float in_warp;                // colour index: 2 panel + (0 weft, 1 warp); 2 P a seam's thread
#ifdef FAR_BAND
in float in_far;                 // far weight: the yarn blends into the far-field surface (band.glsl)
out float v_far;
#endif

out vec3 v_normal;
out vec2 v_kajiya;               // (diffuse sin(T, L), specular cos(thetaL - thetaE)^p)
out vec4 v_albedo;               // linear RGB and alpha
#if defined(SHADOWS) || defined(RIBBON)
out vec3 v_position;             // world position [m], for the shadow lookup (ribbons: on the strip)
#endif
#ifdef RIBBON
out vec3 v_tangent;              // yarn tangent, to rebuild the tube's normal per pixel
// Straight steps (fraytool.render.ribbon): at a step's end vertex, its start's tangent and its middle's
// (zero: not a straight step), and the sample's index along the piece. The step's own values are
// flat, from its provoking vertex (its end's left edge): the middle's departure from the blend of the
// two ends, in the tangent and in the Kajiya-Kay terms; yarn.frag adds them times 4 t (1 - t).
in vec3 in_step_start;
in vec3 in_step_middle;
in float in_step;
out float v_step;
flat out float v_step_start;     // the step's start sample index (its end's minus one)
flat out vec3 v_step_bend;
flat out vec2 v_step_kajiya;
#endif

// Kajiya & Kay 1989: with Li = -L the direction the light travels,
// cos(thetaL - thetaE) = (T.Li)(T.E) + sin(T, Li) sin(T, E); returns (sin(T, L), cos(...)^p).
vec2 kajiya_kay(vec3 T, vec3 E) {
    float tl = dot(T, -u_light_dir);
    float te = dot(T, E);
    float sin_tl = sqrt(max(0.0, 1.0 - tl * tl));
    float sin_te = sqrt(max(0.0, 1.0 - te * te));
    float cos_cone = max(tl * te + sin_tl * sin_te, 0.0);
    return vec2(sin_tl, pow(cos_cone, u_shininess));
}

void main() {
    vec3 T = normalize(in_tangent);
    vec3 E = normalize(u_eye - in_position);
    v_kajiya = kajiya_kay(T, E);
    v_normal = in_normal;
    v_albedo = vec4(u_yarn_colors[int(in_warp + 0.5)], in_alpha);
#if defined(SHADOWS) || defined(RIBBON)
    v_position = in_position;
#endif
#ifdef RIBBON
    v_tangent = T;
    v_step = in_step;
    v_step_start = in_step - 1.0;
    v_step_bend = vec3(0.0);
    v_step_kajiya = vec2(0.0);
    if (dot(in_step_middle, in_step_middle) > 0.0) {
        vec3 T0 = normalize(in_step_start);
        vec3 Tm = normalize(in_step_middle);
        v_step_bend = Tm - 0.5 * (T0 + T);
        v_step_kajiya = kajiya_kay(Tm, E) - 0.5 * (kajiya_kay(T0, E) + v_kajiya);
    }
#endif
#ifdef FAR_BAND
    v_far = in_far;
#endif
    gl_Position = u_view_proj * vec4(in_position, 1.0);
}
