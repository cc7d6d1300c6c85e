#version 330 core
// The far-field surface: the weave aggregated over each pixel (fraytool.render.farfield).
// The weave texture (fraytool.render.weave_texture) gives the weft and warp shares of the pixel's
// footprint at normal view, filtered by its mipmaps; farfield.vert's view factor scales them and
// gives each family's colour. The uncovered share is alpha: what lies behind shows through.

uniform float u_light_intensity;
uniform sampler2DArray u_weave;  // per panel layer: weft, warp coverage of one weave repeat, front (RG) and back (BA)
uniform vec2 u_weave_period;     // crossings per repeat along i and j
uniform float u_yarn_top_m;      // the yarns' tops above the cloth's middle: radius + thickness / 2
#ifdef SHADOWS
#include "shadow.glsl"
#endif
#include "band.glsl"
#include "output.glsl"

in vec3 v_position;
in vec3 v_normal;
in vec2 v_grid;
in float v_far;
in vec2 v_share;
flat in int v_layer;
flat in int v_back;
in vec3 v_weft_ambient;
in vec3 v_weft_key;
in vec3 v_warp_ambient;
in vec3 v_warp_key;

out vec4 f_color;

// Trilinear filtering takes the mip level from the longer axis of the pixel's footprint and blends it
// with the next coarser one: the weave comes out about twice as blurred as the 1-pixel box a camera
// (and the supersampled reference) integrates over, and the weave's pixel-scale contrast, which is
// part of the cloth's look at 1-2 px per crossing, goes with it (a flat weave at 1.2-1.6 px: 45-55 %
// of the box-filtered yarns' per-pixel spread). Half a level sharper keeps 62-70 % of it with no
// visible beat; a whole level keeps 90 % but beats where the view grazes (docs/rendering.md,
// "Coverage"). The cost is the same: one lookup.
const float WEAVE_LOD_BIAS = -0.5;

void main() {
    vec4 texel = texture(u_weave, vec3((v_grid + 0.5) / u_weave_period, float(v_layer)), WEAVE_LOD_BIAS);
    vec2 share = (v_back == 1 ? texel.ba : texel.rg) * v_share;
    float cover = share.x + share.y;
    if (cover > 1.0) {
        share /= cover;
        cover = 1.0;
    }
    if (cover < 0.5 / 255.0)   // less than an 8-bit alpha step (a magnified gap): nothing to draw
        discard;
    float key = u_light_intensity;
#ifdef SHADOWS
    // looked up at the yarns' tops, not the cloth's middle: the yarns (and, in the blend band, the
    // yarns drawn as yarns) must not shade the surface that stands for them; their own shading is in
    // the key part (farfield.vert)
    vec3 n = normalize(v_normal);
    key *= key_light_visibility(v_position + u_yarn_top_m * n, n);
#endif
    vec3 weft = v_weft_ambient + key * v_weft_key;
    vec3 warp = v_warp_ambient + key * v_warp_key;
    gl_SampleMask[0] = band_surface_mask(v_far);
    f_color = to_target(vec4(max((share.x * weft + share.y * warp) / cover, 0.0), cover));
}
