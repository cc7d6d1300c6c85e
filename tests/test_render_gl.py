"""The GL renderer: context errors, image layout and gamma, MSAA clamping, transparency, wireframe."""
from __future__ import annotations

import dataclasses

import moderngl
import numpy as np
import pytest

from fraytool.errors import RunError
from fraytool.render import context as context_module
from fraytool.render.color import linear_to_srgb, srgb_to_linear
from fraytool.render.geometry import GeometryBuilder, YarnStyle
from fraytool.render.renderer import Renderer, clamp_samples, panels


def _render(ctx, pc, record, size=(160, 120), wireframe="off", render=None, camera=None, edit=None, alpha=False):
    render = render or pc.spec.render
    renderer = Renderer(ctx, size, render.samples, render, camera or pc.spec.camera, pc.topology, wireframe,
                        alpha=alpha)
    try:
        builder = GeometryBuilder(pc.topology, YarnStyle.from_spec(render, pc.topology), renderer.camera, size[1])
        geom = builder.build(record, yarns=wireframe != "only", lines=wireframe != "off")
        if edit is not None:
            geom = edit(geom)
        return renderer.render(geom).copy(), geom
    finally:
        renderer.release()


def test_context_failure_is_a_clear_run_error(monkeypatch):
    def fail(**kwargs):
        raise Exception("eglGetDisplay failed")

    monkeypatch.setattr(context_module.moderngl, "create_context", fail)
    with pytest.raises(RunError) as info:
        context_module.create_context()
    text = str(info.value)
    for needle in ("eglGetDisplay failed", "libegl1", "libgl1-mesa-dri", "EGL_PLATFORM=surfaceless",
                   "LIBGL_ALWAYS_SOFTWARE", "MESA_LOADER_DRIVER_OVERRIDE=llvmpipe"):
        assert needle in text
    assert info.value.exit_code == 1


def test_gl_error_check_names_the_step(gl_ctx):
    from fraytool.render.context import check_gl_error

    check_gl_error(gl_ctx, "nothing")          # clean state passes
    gl_ctx.disable_direct(0x0DE1 + 0xFFFF)     # an invalid enum sets GL_INVALID_ENUM
    with pytest.raises(RunError, match="after provoking"):
        check_gl_error(gl_ctx, "provoking")
    assert gl_ctx.error == "GL_NO_ERROR"       # reading the flag cleared it


def test_samples_are_clamped_to_the_context(gl_ctx):
    assert clamp_samples(gl_ctx, 0) == 0 and clamp_samples(gl_ctx, 1) == 0
    assert clamp_samples(gl_ctx, 64) == gl_ctx.max_samples
    assert clamp_samples(gl_ctx, 2) == min(2, gl_ctx.max_samples)


def test_image_is_top_row_first_with_exact_srgb_background(gl_ctx, posed_cloth):
    """The ground plane fills the bottom of the frame and the sky the top: a missing vertical flip
    would swap them. The background is the scene's sRGB colour to within rounding, so lighting in
    linear light with sRGB encoding on write is wired correctly (no double or missing gamma)."""
    level = dataclasses.replace(posed_cloth.spec.camera, position_m=(0.0, 0.04, 0.3), target_m=(0.0, 0.03, 0.0))
    image, _ = _render(gl_ctx, posed_cloth, posed_cloth.copy(), camera=level)
    assert image.shape == (120, 160, 3) and image.dtype == np.uint8
    expected = np.round(255 * np.asarray(posed_cloth.spec.render.background)).astype(int)
    top = image[0].astype(int)
    assert np.abs(top - expected).max() <= 1
    assert np.abs(image[-1].astype(int) - expected).max() > 20


def test_msaa_resolve_averages_in_linear_light(gl_ctx):
    """The renderer's target set-up (SRGB8_ALPHA8 multisampled; shaders write encoded colour with
    GL_FRAMEBUFFER_SRGB off, and it is on for the resolve blit): a pixel half covered by white over
    black resolves to sRGB(0.5) = 188, not 128 as averaging the encoded values would give."""
    from fraytool.render.renderer import GL_FRAMEBUFFER_SRGB, GL_SRGB8_ALPHA8

    ctx = gl_ctx
    ms = ctx.texture((8, 8), 4, samples=4, internal_format=GL_SRGB8_ALPHA8)
    out = ctx.texture((8, 8), 4, internal_format=GL_SRGB8_ALPHA8)
    fbo_ms, fbo_out = ctx.framebuffer([ms]), ctx.framebuffer([out])
    prog = ctx.program(vertex_shader="#version 330 core\nin vec2 p; void main() { gl_Position = vec4(p, 0, 1); }",
                       fragment_shader="#version 330 core\nout vec4 c; void main() { c = vec4(1.0); }")
    buf = ctx.buffer(np.array([-1, -1, -1, 1, 1, 1], "f4"))         # the half above the diagonal
    vao = ctx.vertex_array(prog, [(buf, "2f", "p")])
    try:
        fbo_ms.use()
        fbo_ms.clear(0, 0, 0, 1)
        vao.render(moderngl.TRIANGLES)
        ctx.enable_direct(GL_FRAMEBUFFER_SRGB)
        ctx.copy_framebuffer(fbo_out, fbo_ms)
        ctx.disable_direct(GL_FRAMEBUFFER_SRGB)
        a = np.frombuffer(fbo_out.read(components=1), np.uint8).reshape(8, 8)
    finally:
        ctx.detect_framebuffer(0).use()
        for obj in (vao, buf, prog, fbo_ms, fbo_out, ms, out):
            obj.release()
    assert np.abs(np.diagonal(a).astype(int) - 188).max() <= 2
    assert a[7, 0] == 255 and a[0, 7] == 0


def test_the_shaders_encoding_is_srgb(gl_ctx):
    """shaders/output.glsl with ENCODE_SRGB (what the 8-bit target stores): a ramp of linear values,
    drawn into an 8-bit buffer, reads back as linear_to_srgb of them to rounding; with u_encode = 0
    (the blended pass) the values pass through as they are."""
    from fraytool.render.renderer import _preprocess

    ctx = gl_ctx
    frag = _preprocess("#version 330 core\n#include \"output.glsl\"\nout vec4 c;\n"
                       "void main() { c = to_target(vec4(vec3(floor(gl_FragCoord.x) / 63.0), 1.0)); }\n",
                       ("ENCODE_SRGB",))
    prog = ctx.program(vertex_shader="#version 330 core\nin vec2 p; void main() { gl_Position = vec4(p, 0, 1); }",
                       fragment_shader=frag)
    out = ctx.texture((64, 1), 4)
    fbo = ctx.framebuffer([out])
    buf = ctx.buffer(np.array([-1, -1, 3, -1, -1, 3], "f4"))
    vao = ctx.vertex_array(prog, [(buf, "2f", "p")])
    linear = np.arange(64) / 63.0
    try:
        fbo.use()
        got = {}
        for encode in (1.0, 0.0):
            prog["u_encode"].value = encode
            fbo.clear(0, 0, 0, 0)
            vao.render(moderngl.TRIANGLES)
            got[encode] = np.frombuffer(fbo.read(components=1), np.uint8).astype(int)
    finally:
        ctx.detect_framebuffer(0).use()
        for obj in (vao, buf, prog, fbo, out):
            obj.release()
    assert np.abs(got[1.0] - np.rint(255 * linear_to_srgb(linear))).max() <= 1
    assert np.abs(got[0.0] - np.rint(255 * linear)).max() <= 1
    assert got[1.0][16] - got[0.0][16] > 60                   # encoded mid-greys are much lighter


def test_srgb_helpers_round_trip():
    c = np.linspace(0, 1, 101)
    np.testing.assert_allclose(linear_to_srgb(srgb_to_linear(c)), c, atol=1e-12)
    assert srgb_to_linear(0.5) == pytest.approx(0.214, abs=1e-3)


def test_fading_ends_do_not_touch_opaque_pixels(gl_ctx, posed_cloth):
    """Translucent triangles are blended after the opaque pass without writing depth: with their
    alpha at 0 the image is exactly the image without them."""
    rec = posed_cloth.torn()
    base, geom = _render(gl_ctx, posed_cloth, rec)
    mesh = geom.yarns
    assert len(mesh.translucent) > 0 and len(mesh.opaque) > 0

    def without(g):
        return dataclasses.replace(g, yarns=dataclasses.replace(g.yarns, translucent=g.yarns.translucent[:0],
                                                                centroid=g.yarns.centroid[:0]))

    def invisible(g):
        v = g.yarns.vertices.copy()
        v[np.unique(g.yarns.translucent), 9] = 0.0       # opaque triangles ignore alpha (no blending)
        return dataclasses.replace(g, yarns=dataclasses.replace(g.yarns, vertices=v))

    no_tips, _ = _render(gl_ctx, posed_cloth, rec, edit=without)
    clear_tips, _ = _render(gl_ctx, posed_cloth, rec, edit=invisible)
    assert np.array_equal(no_tips, clear_tips)
    assert not np.array_equal(base, no_tips)        # the fading ends do show


def test_alpha_render_is_straight_alpha_that_composites_back_to_the_opaque_render(gl_ctx, posed_cloth):
    """--alpha: transparent background (alpha 0), opaque yarn (255), the fading broken ends partial;
    composited over the background colour in linear light the RGBA image gives the ordinary render back
    (to a few levels where alpha is small: 8-bit colour divided by a small alpha)."""
    from fraytool.render.color import over_background

    rec = posed_cloth.torn()
    for ground in (False, True):  # with the ground plane, its fade into the background becomes alpha
        render = dataclasses.replace(posed_cloth.spec.render, ground_plane=ground)
        rgb, _ = _render(gl_ctx, posed_cloth, rec, render=render)
        rgba, _ = _render(gl_ctx, posed_cloth, rec, render=render, alpha=True)
        assert rgba.shape == rgb.shape[:2] + (4,)
        a = rgba[..., 3]
        if not ground:
            assert a[0, 0] == 0 and (a == 0).mean() > 0.3      # background
        assert (a == 255).sum() > 200                           # the cloth
        partial = (a > 0) & (a < 255)
        assert partial.sum() > 20                               # fading ends, anti-aliased edges
        back = over_background(rgba, render.background).astype(int)
        diff = np.abs(back - rgb.astype(int)).max(axis=2)
        assert diff[a == 255].max() <= 1 and diff[a == 0].max(initial=0) <= 1
        assert np.percentile(diff[partial], 95) <= 3, (ground, np.percentile(diff[partial], 95))


def test_translucent_triangles_are_drawn_far_to_near(gl_ctx, posed_cloth):
    from fraytool.render.camera import Camera

    rec = posed_cloth.torn()
    _, geom = _render(gl_ctx, posed_cloth, rec)
    cam = Camera(posed_cloth.spec.camera)
    depth = cam.view_depth(geom.yarns.centroid)
    order = np.argsort(depth, kind="stable")
    assert np.all(np.diff(depth[order]) >= 0)       # the renderer's order: most negative z first
    assert depth[order][0] < depth[order][-1]


def test_wireframe_beside_and_colours(gl_ctx, posed_cloth):
    size = (160, 120)
    assert [(p.view, p.x, p.width) for p in panels(161, "beside")] == [("shaded", 0, 80), ("wireframe", 80, 81)]
    torn = posed_cloth.torn()
    beside, _ = _render(gl_ctx, posed_cloth, torn, size, "beside")
    shaded_half, _ = _render(gl_ctx, posed_cloth, torn, (80, 120), "off")
    assert beside.shape == (120, 160, 3)
    assert np.abs(beside[:, :80].astype(int) - shaded_half.astype(int)).max() <= 2   # left panel = shaded view
    right = beside[:, 80:].astype(int)
    blue = (right[..., 2] > right[..., 0] + 60) & (right[..., 2] > right[..., 1] + 20)
    purple = (right[..., 0] > right[..., 1] + 40) & (right[..., 2] > right[..., 1] + 40)
    assert blue.sum() > 20 and purple.sum() > 100     # yarn-level springs blue, base-model purple
    flat_only, _ = _render(gl_ctx, posed_cloth, posed_cloth.copy(), size, "only")
    f = flat_only.astype(int)
    assert not ((f[..., 2] > f[..., 0] + 60) & (f[..., 2] > f[..., 1] + 20)).any()   # nothing at yarn level


def test_renderers_can_be_made_and_released_repeatedly(gl_ctx, posed_cloth):
    for samples in (0, 4, 2):
        render = dataclasses.replace(posed_cloth.spec.render, samples=samples)
        image, _ = _render(gl_ctx, posed_cloth, posed_cloth.copy(), (64, 48), render=render)
        assert image.shape == (48, 64, 3)
    assert gl_ctx.error == "GL_NO_ERROR"


def test_renderer_rejects_unknown_wireframe_mode(gl_ctx, posed_cloth):
    with pytest.raises(ValueError):
        Renderer(gl_ctx, (32, 32), 0, posed_cloth.spec.render, posed_cloth.spec.camera, posed_cloth.topology, "on")
    assert isinstance(gl_ctx, moderngl.Context)
