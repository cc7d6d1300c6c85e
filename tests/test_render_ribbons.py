"""Yarns drawn as view-facing ribbons shaded as tubes ([render] yarn_shape = "ribbon",
fraytool/render/ribbon.py): the strips' geometry, and that they draw what the tubes draw (coverage,
colour, depth) with a sixth of the triangles."""
from __future__ import annotations

import dataclasses

import numpy as np

from fraytool.render.geometry import GeometryBuilder, YarnStyle
from fraytool.render.renderer import Renderer
from fraytool.render.ribbon import (across, ribbon_shadow_positions, ribbon_triangles, ribbon_vertices,
                                    shadow_casters, translucent_ribbon_triangles)


def test_strips_face_the_eye_and_are_as_wide_as_the_yarn():
    rng = np.random.default_rng(4)
    x = rng.normal(size=(50, 3))
    t = rng.normal(size=(50, 3))
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    eye = np.array([0.3, 2.0, 5.0])
    v = ribbon_vertices(x, t, 0.01, np.ones(50, np.float32), np.zeros(50, np.float32), eye).astype(np.float64)
    left, right = v[0::2, :3], v[1::2, :3]
    s = (right - left) / 0.02
    np.testing.assert_allclose(np.linalg.norm(right - left, axis=1), 0.02, rtol=1e-5)   # the yarn's width
    np.testing.assert_allclose(0.5 * (left + right), x, atol=1e-6)                      # through the axis
    np.testing.assert_allclose(np.einsum("ij,ij->i", s, t), 0.0, atol=1e-5)             # across the yarn
    to_eye = (eye - x) / np.linalg.norm(eye - x, axis=1, keepdims=True)
    np.testing.assert_allclose(np.einsum("ij,ij->i", s, to_eye), 0.0, atol=2e-5)        # facing the eye
    np.testing.assert_allclose(v[1::2, 3:6], s, atol=1e-5)                              # signed across
    np.testing.assert_allclose(v[0::2, 3:6], -s, atol=1e-5)
    light = np.array([-0.5, 1.0, 0.6])
    p = ribbon_shadow_positions(x, t, 0.01, light).astype(np.float64)
    np.testing.assert_allclose(np.einsum("ij,j->i", p[1::2] - p[0::2], light), 0.0, atol=1e-6)  # faces the light
    # looking exactly along a yarn: still a unit vector across it
    s = across(np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]), eye_m=np.array([0.0, 0.0, 3.0]))
    assert abs(np.linalg.norm(s) - 1) < 1e-12 and abs(s[0, 2]) < 1e-12


def test_strip_triangles_and_the_fading_ones():
    offsets = np.array([0, 3, 3, 5])              # pieces of 3, 0 and 2 samples
    tri = ribbon_triangles(offsets)
    assert tri.dtype == np.uint32 and tri.shape == (2 * (2 + 1), 3)
    assert tri.tolist() == [[0, 1, 2], [1, 3, 2], [2, 3, 4], [3, 5, 4], [6, 7, 8], [7, 9, 8]]
    alpha = np.array([1, 1, 0.5, 1, 1], np.float32)
    assert translucent_ribbon_triangles(offsets, alpha).tolist() == [False, False, True, True, False, False]


def test_shadow_casters_run_through_every_other_sample_and_leave_out_fading_spans():
    """Straight pieces of 5, 2 and 4 samples: kept samples 0, 2, 4 | 5, 6 | 7, 9, 10; strips join kept
    samples of one piece only; a strip is dropped when a sample on its span fades, the skipped one
    included; a sample bent off the chord by more than a quarter radius is kept."""
    x = np.zeros((11, 3))
    x[:, 0] = 0.01 * np.arange(11)
    t = np.tile([1.0, 0.0, 0.0], (11, 1))
    offsets = np.array([0, 5, 7, 11])
    light = np.array([0.3, 1.0, 0.2])
    keep = [0, 2, 4, 5, 6, 7, 9, 10]
    alpha = np.ones(11, np.float32)
    pos, tri = shadow_casters(x, t, offsets, alpha, 0.01, light)
    np.testing.assert_array_equal(pos, ribbon_shadow_positions(x[keep], t[keep], 0.01, light))
    assert tri.tolist() == ribbon_triangles(np.array([0, 3, 5, 8])).tolist()
    alpha[8] = 0.5                                                # the sample skipped between 7 and 9
    _, tri = shadow_casters(x, t, offsets, alpha, 0.01, light)
    assert len(tri) == 2 * (2 + 1 + 1) and [10, 11, 12] not in tri.tolist() and [11, 13, 12] not in tri.tolist()
    alpha[:] = 1.0
    x[3, 1] = 0.0024                                              # within a quarter radius: still skipped
    assert len(shadow_casters(x, t, offsets, alpha, 0.01, light)[0]) == 2 * 8
    x[3, 1] = 0.0026                                              # a kink: sample 3 casts too
    pos, tri = shadow_casters(x, t, offsets, alpha, 0.01, light)
    np.testing.assert_array_equal(pos, ribbon_shadow_positions(x[[0, 2, 3, 4] + keep[3:]], t[:9], 0.01, light))
    assert tri.tolist() == ribbon_triangles(np.array([0, 4, 6, 9])).tolist()


def _draw(ctx, pc, record, shape, shadows=False, size=(160, 120), ground=False, alpha=True, depth=True):
    render = dataclasses.replace(pc.spec.render, yarn_shape=shape, ground_plane=ground, shadows=shadows, samples=0,
                                 light_direction=(0.6, 1.0, 0.2))
    renderer = Renderer(ctx, size, 0, render, pc.spec.camera, pc.topology, alpha=alpha, target="float", depth=depth)
    try:
        builder = GeometryBuilder(pc.topology, YarnStyle.from_spec(render, pc.topology), renderer.camera, size[1])
        geom = builder.build(record)
        renderer.draw(geom)
        return renderer.read_linear().copy(), (renderer.read_depth_m().copy() if depth else None), geom.yarns
    finally:
        renderer.release()


def test_ribbons_draw_the_tubes_coverage_colour_and_depth(gl_ctx, posed_cloth):
    """The torn posed cloth drawn both ways, one sample per pixel: the same pixels covered (a 6-sided
    tube's outline is up to 13 % narrower than the circle's, 4.5 % on average), the same colours, and
    the depth of the round surface: where the ray meets the circle, never behind the 6-sided tube
    inscribed in it (the ray meets the circle first) and close to it; with a sixth of the triangles."""
    rec = posed_cloth.torn()
    radius = YarnStyle.from_spec(posed_cloth.spec.render, posed_cloth.topology).radius_m
    for shadows in (False, True):
        tube, z_tube, mesh_tube = _draw(gl_ctx, posed_cloth, rec, "tube", shadows)
        ribbon, z_ribbon, mesh_ribbon = _draw(gl_ctx, posed_cloth, rec, "ribbon", shadows)
        a, b = tube[..., 3] > 0.5, ribbon[..., 3] > 0.5
        assert a.sum() > 500
        iou = (a & b).sum() / (a | b).sum()
        assert iou > 0.9, iou
        both = a & b
        colour = np.abs(tube[..., :3] - ribbon[..., :3])[both].mean()
        assert colour < 0.03, colour
        solid = both & np.isfinite(z_tube) & np.isfinite(z_ribbon)   # fading ends write no depth
        assert solid.sum() > 0.8 * both.sum()
        dz = z_ribbon[solid] - z_tube[solid]
        assert np.median(np.abs(dz)) < 0.1 * radius, (np.median(np.abs(dz)), radius)
        assert np.percentile(dz, 90) < 0.02 * radius, np.percentile(dz, 90)   # nearer than the facets
        tri_tube = len(mesh_tube.opaque) + len(mesh_tube.translucent)
        tri_ribbon = len(mesh_ribbon.opaque) + len(mesh_ribbon.translucent)
        assert tri_ribbon * 5 < tri_tube


def test_ribbons_cast_the_tubes_shadows_on_the_ground(gl_ctx, posed_cloth):
    """With the ground and key-light shadows, the ground darkened by shadows (against the same view
    without shadows) is the same region for tubes and ribbons (the shadow map gets the strips turned
    to the light), and the ground differs between them far less than shadows change it."""
    rec = posed_cloth.torn()
    covered = ((_draw(gl_ctx, posed_cloth, rec, "tube", depth=False)[0][..., 3] > 0)
               | (_draw(gl_ctx, posed_cloth, rec, "ribbon", depth=False)[0][..., 3] > 0))
    ground = ~covered

    def lum(shape, shadows):
        image = _draw(gl_ctx, posed_cloth, rec, shape, shadows, ground=True, alpha=False, depth=False)[0]
        return image[..., :3].mean(axis=2)

    lit, tube, ribbon = lum("tube", False), lum("tube", True), lum("ribbon", True)
    shade_tube = (lit - tube > 0.02) & ground
    shade_ribbon = (lit - ribbon > 0.02) & ground
    assert shade_tube.sum() > 300
    assert (shade_tube & shade_ribbon).sum() / (shade_tube | shade_ribbon).sum() > 0.9
    assert np.abs(ribbon - tube)[ground].mean() < 0.2 * np.abs(lit - tube)[ground].mean()


def test_small_ribbons_keep_their_depth_at_the_silhouette(gl_ctx):
    """Ribbons 5 px apart, lit: the 1x frame against the same drawn at 4x and box-filtered is within 5.6
    levels (blurred RMS, fraytool.render.aliasing). The strip's depth is one per pixel; taken at the pixel's
    centre, which at the strip's edge lies outside it (the tube's deepest), the yarn behind won the rim of
    every silhouette and these frames were 6.2 and 6.9 levels off, darker."""
    import math
    from pathlib import Path

    from conftest import PosedCloth
    from fraytool.render.aliasing import FACTOR, blurred_rms, box_downsample

    flat = PosedCloth(Path(__file__).parent / "scenes" / "flat_weave.toml")
    size = (320, 180)
    for elevation, azimuth, footprint in ((45.0, 10.0, 5.0), (90.0, 0.0, 5.0)):
        spec = flat.spec
        d = spec.cloth.spacing_m * size[1] / (2.0 * math.tan(math.radians(spec.camera.fov_deg) / 2.0) * footprint)
        e, a = math.radians(elevation), math.radians(azimuth)
        camera = dataclasses.replace(spec.camera, position_m=(d * math.cos(e) * math.cos(a), d * math.sin(e),
                                                              d * math.cos(e) * math.sin(a)),
                                     target_m=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0) if elevation < 89 else (1.0, 0.0, 0.0))
        render = dataclasses.replace(spec.render, far_field=False)

        def draw(wh, target):
            r = Renderer(gl_ctx, wh, render.samples, render, camera, flat.topology, target=target)
            try:
                b = GeometryBuilder(flat.topology, YarnStyle.from_spec(render, flat.topology), r.camera, wh[1],
                                    image_width=r.shaded_width)
                r.draw(b.build(flat.rest))
                return (r.read() if target == "srgb8" else r.read_linear()).copy()
            finally:
                r.release()

        one = draw(size, "srgb8")
        ref = box_downsample(draw((size[0] * FACTOR, size[1] * FACTOR), "float"))
        assert blurred_rms(one, ref) <= 5.6, (elevation, azimuth, blurred_rms(one, ref))


def test_straight_steps_keep_the_yarns_tilt_between_crossings(gl_ctx, monkeypatch):
    """The flat weave 6 px apart, lit: ribbons drawn with one straight step per segment
    (lod.RIBBON_STRAIGHT_PX) against the same yarns sampled at every segment's middle too (the straight
    steps off), with at least a quarter fewer triangles: within 3.0 levels (RMS after the 2 px blur,
    fraytool.render.aliasing; measured 2.3). A straight step carries its middle's tangent to the pixels
    (fraytool.render.ribbon, "Straight steps"); without it (the middles' tangents left out) the step
    keeps only its ends' tangents, the weave's tilt between crossings is lost and the frame is over 4.5
    levels off (measured 5.2)."""
    import math
    from pathlib import Path

    import fraytool.render.geometry as geometry
    import fraytool.render.lod as lod
    from conftest import PosedCloth
    from fraytool.render import ribbon as ribbon_module
    from fraytool.render.aliasing import blurred_rms

    flat = PosedCloth(Path(__file__).parent / "scenes" / "flat_weave.toml")
    size = (320, 180)
    spec = flat.spec
    d = spec.cloth.spacing_m * size[1] / (2.0 * math.tan(math.radians(spec.camera.fov_deg) / 2.0) * 6.0)
    e, a = math.radians(50.0), math.radians(30.0)
    camera = dataclasses.replace(spec.camera, position_m=(d * math.cos(e) * math.cos(a), d * math.sin(e),
                                                          d * math.cos(e) * math.sin(a)),
                                 target_m=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0))
    render = dataclasses.replace(spec.render, far_field=False)

    def draw():
        r = Renderer(gl_ctx, size, render.samples, render, camera, flat.topology)
        try:
            b = GeometryBuilder(flat.topology, YarnStyle.from_spec(render, flat.topology), r.camera, size[1],
                                image_width=r.shaded_width)
            geom = b.build(flat.rest)
            r.draw(geom)
            return r.read().copy(), len(geom.yarns.opaque)
        finally:
            r.release()

    steps, tri_steps = draw()
    full_curves = ribbon_module.ribbon_curves

    def without_middles(*args):
        curves, tangents, steps = full_curves(*args)
        steps[:, 3:6] = 0.0
        return curves, tangents, steps

    monkeypatch.setattr(geometry, "ribbon_curves", without_middles)
    ends_only, _ = draw()
    monkeypatch.setattr(geometry, "ribbon_curves", full_curves)
    monkeypatch.setattr(lod, "RIBBON_STRAIGHT_PX", 0.0)
    reference, tri_reference = draw()
    assert tri_steps * 4 < tri_reference * 3, (tri_steps, tri_reference)
    with_middles, ends = blurred_rms(steps, reference), blurred_rms(ends_only, reference)
    assert with_middles <= 3.0, with_middles
    assert ends > 4.5, ends
