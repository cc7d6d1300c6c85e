#version 330 core
// The far-field surface over the crossing grid (fraytool.render.farfield): world-space vertices at
// the crossings' centres. The yarn model, averaged over each yarn family, is evaluated here per
// vertex (it depends on the yarn directions, the view and the light, all smooth over the cloth; a
// surface quad spans a few pixels at most); farfield.frag adds the weave texture and the shadow.
//
// Coverage: the shares of the weft and the warp that a view sees (the rest is gap) come from a table
// over view directions ray cast through the yarns' own geometry (fraytool.render.weave_visibility),
// relative to the shares straight above (the weave texture's, which farfield.frag filters).
// Shading: yarn.frag's model (Lambert on the tube normal mixed with Kajiya-Kay's sin(T, L), the
// Kajiya-Kay highlight faded on the shaded side, the fill light) averaged over the part of each
// family's yarn the view sees: the same table holds, per view, how the seen normals spread around the
// yarn (8 bins of the angle phi from the cloth's normal, positive towards the eye's side of the yarn,
// and the normals' mean tilt along the yarn where it rises and falls; ray cast as the shares), and
// the model is evaluated at each bin's normal, weighted by its share.
// The yarn nearer the light shades all but the upper 1 / k_L of the next as the light sees it (k_L:
// the family's cover seen from the light), so a grazing light leaves the yarns' flanks in shadow.

uniform mat4 u_view_proj;
uniform vec3 u_eye;
uniform vec3 u_light_dir;
uniform float u_ambient;
uniform float u_specular;
uniform float u_shininess;
uniform float u_kajiya_weight;
uniform vec3 u_yarn_colors[32];
uniform vec4 u_mean_cover[16];   // per panel layer: the weave texture's mean weft, warp coverage, front then back
uniform sampler2DArray u_visibility;  // per panel, VISIBILITY_LAYERS layers (fraytool.render.renderer) by
                                      // view (azimuth, sin elevation): weft, warp shares, front (RG) and
                                      // back (BA); then the seen normals (weft front, warp front, weft
                                      // back, warp back): their shares per bin, their mean part along the
                                      // yarn towards the eye per bin (2 RGBA layers each)
const int VISIBILITY_LAYERS = 17;
const int NORMAL_BINS = 8;        // fraytool.render.weave_visibility.NORMAL_BINS
uniform int u_layers;
uniform float u_visibility_rows;
uniform float u_visibility_columns;
uniform float u_yarn_diameter_m;
uniform float u_undulation;      // pi T / (2 s): the yarn's largest slope out of the cloth
#ifdef FILL
uniform float u_fill_intensity;
uniform vec3 u_fill_dir;
#endif

in vec3 in_position;
in vec3 in_normal;
in vec3 in_weft_edge;            // local spacing vector along the weft yarns [m]
in vec3 in_warp_edge;            // ... along the warp yarns [m]
in vec2 in_grid;                 // (i, j): warp and weft yarn index, the weave texture's coordinates
in float in_far;                 // far weight (the blend band, band.glsl)
in float in_panel;

out vec3 v_position;
out vec3 v_normal;               // the cloth normal, towards the eye
out vec2 v_grid;
out float v_far;
out vec2 v_share;                // view factor of the weft and warp shares (1 at normal view)
flat out int v_layer;            // the panel's weave (texture layer)
flat out int v_back;             // 1: the eye sees the cloth's back, where the other yarn is on top
out vec3 v_weft_ambient;         // each family's colour: ambient + key light x (shadow) x key part
out vec3 v_weft_key;
out vec3 v_warp_ambient;
out vec3 v_warp_key;

// The seen normals of one family, side and panel at this view's table texel: per bin (8), their share
// and their mean part along the yarn towards the eye.
void normal_bins(vec3 at, int first_layer, out float share[8], out float along[8]) {
    vec4 t[4];
    for (int k = 0; k < 4; ++k)
        t[k] = texture(u_visibility, vec3(at.xy, float(first_layer + k)));
    share = float[8](t[0].x, t[0].y, t[0].z, t[0].w, t[1].x, t[1].y, t[1].z, t[1].w);
    along = float[8](t[2].x, t[2].y, t[2].z, t[2].w, t[3].x, t[3].y, t[3].z, t[3].w);
}

float family_cover(vec3 along, vec3 stacked, vec3 E) {
    vec3 a = along - dot(along, E) * E;
    vec3 b = stacked - dot(stacked, E) * E;
    float la = length(a);
    vec3 an = la > 1e-12 ? a / la : vec3(0.0);
    float d = length(b - dot(b, an) * an);
    return u_yarn_diameter_m / max(d, 1e-9);
}

// Kajiya-Kay's terms (diffuse sin(T, L), highlight cos(thetaL - thetaE)^p) averaged along a yarn that
// runs over and under the other family: its tangent tilts out of the cloth by psi with
// tan psi = m sin(theta) (a sinusoid of amplitude T/2 over one spacing s: m = pi T / (2 s)), theta
// uniform over the yarn; 8 samples, +-psi. The tilt spreads the narrow highlight over more views.
vec2 kajiya_along(vec3 T0, vec3 N, vec3 E) {
    vec2 sum = vec2(0.0);
    for (int q = 0; q < 8; ++q) {
        float slope = u_undulation * sin(1.5707963 * (float(q / 2) + 0.5) / 4.0) * (q % 2 == 0 ? 1.0 : -1.0);
        vec3 T = normalize(T0 + slope * N);
        float tl = dot(T, -u_light_dir);
        float te = dot(T, E);
        float sin_tl = sqrt(max(0.0, 1.0 - tl * tl));
        float sin_te = sqrt(max(0.0, 1.0 - te * te));
        sum += vec2(sin_tl, pow(max(tl * te + sin_tl * sin_te, 0.0), u_shininess));
    }
    return sum * 0.125;
}

void family(vec3 T, vec3 E, vec3 N, float weights[8], float along[8], float k_light, vec3 albedo,
            out vec3 ambient_part, out vec3 key_part) {
    float tl = dot(T, -u_light_dir);
    vec2 kajiya = kajiya_along(T, N, E);
    float sin_tl = kajiya.x;
    float spec = kajiya.y;
    // the yarn's cross-section: up (the cloth normal square to the yarn) and B across it, towards the eye
    vec3 up = normalize(N - dot(N, T) * T);
    vec3 B = E - dot(E, T) * T - dot(E, up) * up;
    float lb = length(B);
    B = lb > 1e-6 ? B / lb : normalize(cross(up, T));
    vec3 A = dot(E, T) < 0.0 ? -T : T;                      // along the yarn, towards the eye
    // The light's own view of the yarn: across it, S_L (turned away from the cloth); the neighbour
    // towards the light shades all but the upper 1 / k_light of it.
    vec3 across_l = u_light_dir - tl * -T;
    float ll = length(across_l);
    vec3 S_L = ll > 1e-6 ? cross(T, across_l / ll) : B;
    S_L = dot(S_L, N) < 0.0 ? -S_L : S_L;
    float shade_below = 1.0 - 2.0 / max(k_light, 1.0);
    float lambert = 0.0;
    float lit = 0.0;
    float sun = 0.0;
    float fill = 0.0;
    float total = 0.0;
    for (int q = 0; q < NORMAL_BINS; ++q) {
        float phi = (float(q) + 0.5) * 3.14159265 / float(NORMAL_BINS) - 1.5707963;
        float m = clamp(along[q], -1.0, 1.0);
        vec3 n = sqrt(1.0 - m * m) * (cos(phi) * up + sin(phi) * B) + m * A;
        float w = weights[q];
        float nl = dot(n, u_light_dir);
        float unshaded = smoothstep(shade_below - 0.1, shade_below + 0.1, dot(n, S_L));
        total += w;
        sun += w * unshaded;
        lambert += w * max(nl, 0.0) * unshaded;
        lit += w * smoothstep(-0.2, 0.3, nl) * unshaded;
#ifdef FILL
        fill += w * (0.5 + 0.5 * dot(n, u_fill_dir));
#endif
    }
    float norm = 1.0 / max(total, 1e-6);
    float ambient = u_ambient;
#ifdef FILL
    ambient += u_fill_intensity * fill * norm;
#endif
    float diffuse = mix(lambert * norm, sin_tl * sun * norm, u_kajiya_weight);
    ambient_part = albedo * ambient;
    key_part = albedo * diffuse + vec3(u_specular * spec * lit * norm);
}

void main() {
    vec3 E = normalize(u_eye - in_position);
    vec3 N = normalize(in_normal);
    bool back = dot(N, E) < 0.0;    // the crossing normals point to the front (docs/method.md §5)
    N = back ? -N : N;
    // the shares this view sees (fraytool.render.weave_visibility): elevation and azimuth from the weft
    vec3 weft_dir = normalize(in_weft_edge - dot(in_weft_edge, N) * N);
    vec3 side = cross(N, weft_dir);
    float azimuth = atan(dot(E, side), dot(E, weft_dir));          // -pi .. pi; the table repeats every pi
    azimuth = back ? -azimuth : azimuth;                           // from the back, side is -j: turn it back
    float elevation = clamp(dot(E, N), 0.0, 1.0);
    int panel = int(in_panel + 0.5);
    int layer = min(panel, u_layers - 1);
    int base = layer * VISIBILITY_LAYERS;
    vec3 at = vec3(azimuth / 3.14159265 + 0.5 / u_visibility_columns,
                   elevation - 0.5 / u_visibility_rows,   // texel centres: rows, columns
                   float(base));
    vec4 table = texture(u_visibility, at);
    vec4 mean = u_mean_cover[layer];
    v_share = back ? table.ba / mean.ba : table.rg / mean.rg;
    v_layer = layer;
    v_back = back ? 1 : 0;
    vec3 L = u_light_dir;
    float lf = family_cover(in_weft_edge, in_warp_edge, L);    // the same as the light sees it
    float lw = family_cover(in_warp_edge, in_weft_edge, L);
    int bins = base + 1 + (back ? 4 * NORMAL_BINS / 4 : 0);     // weft, then warp, of the side seen
    float share[8], along[8];
    normal_bins(at, bins, share, along);
    family(normalize(in_weft_edge), E, N, share, along, lf, u_yarn_colors[2 * panel], v_weft_ambient, v_weft_key);
    normal_bins(at, bins + 2 * NORMAL_BINS / 4, share, along);
    family(normalize(in_warp_edge), E, N, share, along, lw, u_yarn_colors[2 * panel + 1], v_warp_ambient, v_warp_key);
#ifdef SHADOWS
    // The cloth is opaque: with the key light behind its plane only the yarns' tops still catch it, a
    // few degrees on flat cloth, further where the cloth curves away from the light. The shadow map
    // holds that horizon, but not smoothly: the surface casts as quads of SURFACE_STEP crossings
    // (fraytool.render.farfield), and a receiver the light grazes stretches each map texel along it,
    // so the shadow's edge there ran in stairs. The key part fades out instead, from 3 to 15 degrees
    // behind the plane (N.L from -0.05 to -0.25), where the map's edge then falls.
    float facing = smoothstep(-0.25, -0.05, dot(N, u_light_dir));
    v_weft_key *= facing;
    v_warp_key *= facing;
#endif
    v_position = in_position;
    v_normal = N;
    v_grid = in_grid;
    v_far = in_far;
    gl_Position = u_view_proj * vec4(in_position, 1.0);
}
