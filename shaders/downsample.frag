#version 330 core
// Supersampling ([render] supersample = k, fraytool.render.renderer): each output pixel is the mean of
// the k x k drawn pixels it covers, a box filter, taken in linear light (the resolved image is drawn in
// float when supersampled: colour premultiplied by alpha, unclamped, and alpha). Into an 8-bit sRGB
// output GL_FRAMEBUFFER_SRGB encodes the mean on the write.
uniform sampler2D u_source;
uniform int u_factor;
out vec4 f_color;

void main() {
    ivec2 origin = ivec2(gl_FragCoord.xy) * u_factor;
    vec4 sum = vec4(0.0);
    for (int y = 0; y < u_factor; ++y)
        for (int x = 0; x < u_factor; ++x)
            sum += texelFetch(u_source, origin + ivec2(x, y), 0);
    f_color = sum / float(u_factor * u_factor);
}
