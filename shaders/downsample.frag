#version 330 core
// Supersampling ([render] supersample = k, fraytool.render.renderer): each output pixel is the mean of
// the k x k drawn pixels it covers, a box filter. Fetched from the resolved image: an sRGB texture is
// decoded to linear light by the fetch (the mean is taken in linear light, of colour premultiplied by
// alpha, and alpha), a float one holds linear light already; GL_FRAMEBUFFER_SRGB encodes the mean on
// the write into an sRGB target.
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
