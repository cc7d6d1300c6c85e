// What the shaded fragment shaders write (fraytool.render.renderer): linear RGB for the float target;
// with ENCODE_SRGB (the 8-bit target) its sRGB encoding (IEC 61966-2-1), once per fragment, stored as
// it comes (GL_FRAMEBUFFER_SRGB off while drawing; on, GL would convert every sample of every write).
// Alpha stays linear. The multisample resolve decodes, averages in linear light and encodes again.
// u_encode = 0 turns the encoding off for a pass drawn with GL_FRAMEBUFFER_SRGB on (the blended,
// fading yarn ends: GL then blends in linear light).

#ifdef ENCODE_SRGB
uniform float u_encode;
#endif

vec4 to_target(vec4 c) {
#ifdef ENCODE_SRGB
    vec3 x = clamp(c.rgb, 0.0, 1.0);
    vec3 encoded = mix(1.055 * pow(x, vec3(1.0 / 2.4)) - 0.055, 12.92 * x, lessThanEqual(x, vec3(0.0031308)));
    return vec4(mix(c.rgb, encoded, u_encode), c.a);
#else
    return c;
#endif
}
