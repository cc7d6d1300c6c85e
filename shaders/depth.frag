#version 330 core
// Shadow-map pass: depth only (no colour attachment). With SURFACE the far-field surface casts only
// where it is most of the picture (far weight at least a half, band.glsl): in the blend band the
// yarns are drawn too and cast their own shadows, and a sheet cast beside them would shade their gaps.

#ifdef SURFACE
in float v_far;
#endif

void main() {
#ifdef SURFACE
    if (v_far < 0.5)
        discard;
#endif
}
