// The blend band of the far field (fraytool.render.farfield): where yarns blend into the far-field
// surface, each pixel's MSAA samples are split between the two. With far weight w (0: yarns only,
// 1: surface only), the surface takes the first n = floor(w S + d) of the S samples and the yarns the
// others; d is a 4 x 4 ordered dither (Bayer) of the pixel, so over a 4 x 4 block the split has 16 S
// levels. Where both draws see the same n, every sample is drawn by exactly one of them and the
// resolve gives (1 - w) yarns + w surface, each with its own coverage; their w differ a little (the
// yarns' from their crossings, the surface's over its quads), so a few samples go to both or neither.
// Needs GL_ARB_sample_shading (gl_SampleMask, gl_NumSamples; core in GL 4.0), enabled by the FAR_BAND
// define. S is the framebuffer's own count, gl_NumSamples (1 without MSAA), not the count asked for: a
// driver may give more samples than asked (llvmpipe makes 2 into 4), and a mask of the first 2 of 4
// left half of each pixel undrawn, the cloth see-through.

int band_surface_samples(float far) {
    ivec2 p = ivec2(gl_FragCoord.xy) & 3;
    const float bayer[16] = float[16](0.0, 8.0, 2.0, 10.0, 12.0, 4.0, 14.0, 6.0,
                                      3.0, 11.0, 1.0, 9.0, 15.0, 7.0, 13.0, 5.0);
    float d = (bayer[p.y * 4 + p.x] + 0.5) / 16.0;
    return clamp(int(floor(far * float(gl_NumSamples) + d)), 0, gl_NumSamples);
}

int band_surface_mask(float far) {
    return (1 << band_surface_samples(far)) - 1;
}

int band_yarn_mask(float far) {
    return ((1 << min(gl_NumSamples, 31)) - 1) & ~band_surface_mask(far);
}
