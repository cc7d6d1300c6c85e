"""The far field (fraytool.render.farfield): intact cloth whose yarns are under a few pixels apart on
screen is drawn as one weave-shaded surface, with a blend band to the yarns.

Checked against independent references: the projection's own arithmetic (footprints), the weave's
analytic coverage a - a^2/2 per family (texture, view table), and the same frame drawn with yarns only
at 4x the resolution in each axis, box-filtered (shares of each family, aliasing error)."""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from conftest import PosedCloth
from fraytool.render.aliasing import FACTOR, blurred_rms, box_downsample, gaussian_blur
from fraytool.render.camera import Camera
from fraytool.render.color import srgb_to_linear
from fraytool.render.farfield import FAR_PX, NEAR_PX, _covered, band_weight
from fraytool.render.geometry import GeometryBuilder, YarnStyle
from fraytool.render.renderer import Renderer
from fraytool.render.weave_texture import coverage_tile
from fraytool.render.weave_visibility import NORMAL_BINS, bin_angles, view_tables, visibility_table

FLAT = Path(__file__).parent / "scenes" / "flat_weave.toml"
PLAIN = np.array([[True, False], [False, True]])


@pytest.fixture(scope="module")
def flat():
    return PosedCloth(FLAT)


def _view(spec, elevation_deg: float, azimuth_deg: float, footprint_px: float, height_px: int):
    """The spec with its camera looking at the cloth's centre from elevation / azimuth (from the weft,
    +x) at the distance where one yarn spacing spans `footprint_px` pixels (isotropic measure)."""
    spacing = spec.cloth.spacing_m
    d = spacing * height_px / (2.0 * math.tan(math.radians(spec.camera.fov_deg) / 2.0) * footprint_px)
    e, a = math.radians(elevation_deg), math.radians(azimuth_deg)
    pos = (d * math.cos(e) * math.cos(a), d * math.sin(e), d * math.cos(e) * math.sin(a))
    up = (0.0, 1.0, 0.0) if elevation_deg < 89.0 else (1.0, 0.0, 0.0)
    return dataclasses.replace(spec, camera=dataclasses.replace(spec.camera, position_m=pos, target_m=(0.0, 0.0, 0.0),
                                                                up=up))


def _with(spec, **render):
    return dataclasses.replace(spec, render=dataclasses.replace(spec.render, **render))


def _draw(ctx, spec, pc, record, size, target="srgb8", alpha=False, depth=False, wireframe="off"):
    r = Renderer(ctx, size, spec.render.samples, spec.render, spec.camera, pc.topology, wireframe, alpha=alpha,
                 target=target, depth=depth)
    try:
        geom = r.geometry_builder(pc.topology).build(record, yarns=wireframe != "only", lines=wireframe != "off")
        r.draw(geom)
        out = r.read() if target == "srgb8" else r.read_linear()
        z = r.read_depth_m() if depth else None
        return out.copy(), geom, z
    finally:
        r.release()


def _reference(ctx, spec, pc, record, size):
    """Yarns only, at FACTOR x the size, box-filtered in linear light: (H, W, 3) 8-bit sRGB."""
    big = (size[0] * FACTOR, size[1] * FACTOR)
    linear, _, _ = _draw(ctx, _with(spec, far_field=False), pc, record, big, target="float")
    return box_downsample(linear)


# -- without GL ------------------------------------------------------------------------------------

def test_band_weight_is_zero_above_one_below_and_smooth_between():
    w = band_weight(np.array([10.0, NEAR_PX, 0.5 * (NEAR_PX + FAR_PX), FAR_PX, 0.2]))
    assert w[0] == 0.0 and w[1] == 0.0 and w[3] == 1.0 and w[4] == 1.0
    assert w[2] == pytest.approx(0.5)
    x = np.linspace(0.5, 4.0, 200)
    assert (np.diff(band_weight(x)) <= 0).all()


def _centre_footprint(flat, elevation: float, azimuth: float, footprint: float, H: int = 90):
    """(the centre crossing's footprint [px], spacing in pixels at its distance by the projection's own
    arithmetic, spacing x H / (2 d tan(fov / 2)))."""
    spec = _view(flat.spec, elevation, azimuth, footprint, H)
    b = GeometryBuilder(flat.topology, YarnStyle.from_spec(spec.render, flat.topology), Camera(spec.camera), H,
                        image_width=160)
    field = b.far_field(flat.rest)
    d = float(np.linalg.norm(np.asarray(spec.camera.position_m)))
    spacing_px = flat.spec.cloth.spacing_m * H / (2.0 * d * math.tan(math.radians(spec.camera.fov_deg) / 2.0))
    return float(field.footprint_px[(flat.H // 2) * flat.W + flat.W // 2]), spacing_px


def test_covered_links_are_those_with_surface_cells_on_both_sides():
    """farfield._covered against a loop over the links: a link along grid row j between places i and
    i + 1 lies between cell rows j - 1 and j (none beyond the grid's border); it is covered where both
    cells exist and their blocks (c x c cells, the last row and column of blocks shorter) are surface."""
    rng = np.random.default_rng(7)
    for H, W, c in [(2, 2, 4), (5, 5, 4), (6, 7, 4), (9, 8, 4), (12, 12, 4), (7, 3, 2), (4, 6, 1), (13, 10, 5)]:
        Hb, Wb = -(-(H - 1) // c), -(-(W - 1) // c)
        block = rng.random((Hb, Wb)) < 0.7
        slow = np.zeros((H, W - 1), dtype=bool)
        for j in range(H):
            for i in range(W - 1):
                sides = [r for r in (j - 1, j) if 0 <= r <= H - 2]
                slow[j, i] = len(sides) == 2 and all(block[r // c, i // c] for r in sides)
        assert np.array_equal(_covered(block, H, W, c), slow), (H, W, c)


def test_weave_tiles_keeps_each_cloths_own(flat):
    """weave_tiles keeps its last cloth's tiles: asked again for it, the same read-only array; asked for
    another cloth in between (its weave turned over), that cloth's own, as computed afresh."""
    from fraytool.render import weave_texture

    topo = dict(flat.topology)
    turned = dict(topo, crossing_weft_on_top=~np.asarray(topo["crossing_weft_on_top"], dtype=bool))
    first = weave_texture.weave_tiles(topo)
    assert weave_texture.weave_tiles(topo) is first and not first.flags.writeable
    other = weave_texture.weave_tiles(turned)
    assert np.array_equal(other, weave_texture._weave_tiles(turned)) and not np.array_equal(other, first)
    again = weave_texture.weave_tiles(topo)
    assert np.array_equal(again, weave_texture._weave_tiles(topo))


def test_footprint_seen_head_on_is_the_spacing_in_pixels(flat):
    """Straight above, the centre crossing's footprint is its spacing in pixels."""
    got, spacing_px = _centre_footprint(flat, 90.0, 0.0, 1.7)
    assert spacing_px == pytest.approx(1.7)
    assert got == pytest.approx(spacing_px, rel=0.02)


def test_footprint_at_a_grazing_view_is_the_mean_of_both_directions(flat):
    """Seen at 20 degrees along the weft, a crossing's weft edge is foreshortened by sin(20) and its warp
    edge is not: the footprint is their geometric mean, spacing x sqrt(sin 20) in pixels."""
    got, spacing_px = _centre_footprint(flat, 20.0, 0.0, 2.0)
    assert got == pytest.approx(spacing_px * math.sqrt(math.sin(math.radians(20.0))), rel=0.05)


def test_each_panel_keeps_its_own_weave():
    """seam_rip sews a plain panel to a twill one: the far field's weave layers are the two patterns,
    each as the topology has it at every crossing of its panel."""
    from fraytool.render.weave_texture import weave_tiles
    from fraytool.render.yarns import crossing_places
    from fraytool.scene import load_scene
    from fraytool.sim.builder import build_model

    topo = build_model(load_scene(Path(__file__).parent.parent / "scenes" / "seam_rip.toml")).arrays()
    tiles = weave_tiles(topo)
    assert tiles.shape[0] == 2
    W = int(np.asarray(topo["warp_yarns"]).item())
    jj, ii = np.divmod(crossing_places(topo), W)
    panel = np.asarray(topo["crossing_panel"])
    on_top = np.asarray(topo["crossing_weft_on_top"], bool)
    py, px = tiles.shape[1:]
    assert np.array_equal(tiles[panel, jj % py, ii % px], on_top)
    assert not np.array_equal(tiles[0], tiles[1])


def test_a_twill_seamed_to_a_satin_keeps_both_weaves(tmp_path):
    """seam_rip with a 3/1 twill panel sewn to a 5-shaft satin: the two repeat every 4 and 5 crossings,
    so the layers share a repeat of 20 (over the old limit of 16, where both panels fell back to the
    plain weave), each holding its own pattern at every crossing of its panel; the coverage texture
    keeps 12 texels a crossing (240 a side) and its mean stays the weave's a - a^2/2 per family."""
    from fraytool.render.weave_texture import texels_per_crossing, weave_tiles
    from fraytool.render.yarns import crossing_places
    from fraytool.scene import load_scene
    from fraytool.sim.builder import build_model

    text = (Path(__file__).parent.parent / "scenes" / "seam_rip.toml").read_text()
    text = text.replace('weave = "plain"', 'weave = "twill"\ntwill = "3/1"', 1)
    text = text.replace('weave = "twill"\nwarp_color', 'weave = "satin"\nsatin_shafts = 5\nwarp_color', 1)
    path = tmp_path / "twill_satin.toml"
    path.write_text(text)
    topo = build_model(load_scene(path)).arrays()
    tiles = weave_tiles(topo)
    assert tiles.shape == (2, 20, 20)
    W = int(np.asarray(topo["warp_yarns"]).item())
    jj, ii = np.divmod(crossing_places(topo), W)
    panel = np.asarray(topo["crossing_panel"])
    on_top = np.asarray(topo["crossing_weft_on_top"], bool)
    assert np.array_equal(tiles[panel, jj % 20, ii % 20], on_top)
    assert sorted(tiles.reshape(2, -1).mean(axis=1)) == pytest.approx([0.75, 0.8])  # weft over 3 in 4, 4 in 5
    n = texels_per_crossing(tiles.shape[1:])
    assert n == 12
    a = 2 * 0.00065 / 0.002
    cover = coverage_tile(tiles[1], a, n).astype(float) / 255.0
    assert cover.shape == (240, 240, 2)
    assert cover.mean(axis=(0, 1)).sum() == pytest.approx(2 * a - a * a, abs=0.01)


def test_a_weave_with_no_short_repeat_is_drawn_yarn_by_yarn(tmp_path):
    """A weave table repeating every 70 crossings on a 140 x 140 cloth has no repeat the far field can
    hold (at most 64): weave_tiles says so and the yarn style turns the far field off, rather than
    drawing the plain weave's coverage; the same cloth woven 4 x 4 keeps it."""
    from fraytool.render.weave_texture import weave_tiles
    from fraytool.scene import load_scene
    from fraytool.sim.builder import build_model

    rng = np.random.default_rng(5)
    rows = rng.integers(0, 2, size=(70, 70))
    text = FLAT.read_text().replace("warp_yarns = 96", "warp_yarns = 140").replace("weft_yarns = 96", "weft_yarns = 140")
    styles = {}
    for name, table in (("long", rows), ("short", rows[:4, :4])):
        body = "[" + ", ".join("[" + ", ".join(str(int(v)) for v in r) + "]" for r in table) + "]"
        path = tmp_path / f"{name}.toml"
        path.write_text(text.replace('weave = "plain"', f'weave = "table"\ntable = {body}'))
        spec = load_scene(path)
        topo = build_model(spec).arrays()
        styles[name] = (weave_tiles(topo), YarnStyle.from_spec(spec.render, topo))
    assert styles["long"][0] is None and not styles["long"][1].far_field
    assert styles["short"][0].shape[1:] == (4, 4) and styles["short"][1].far_field


def test_coverage_texture_holds_the_weaves_analytic_coverage():
    for a in (0.4, 0.65, 0.9):
        tile = coverage_tile(PLAIN, a).astype(float) / 255.0
        assert tile[..., 0].mean() == pytest.approx(a - a * a / 2.0, abs=0.01)   # weft
        assert tile[..., 1].mean() == pytest.approx(a - a * a / 2.0, abs=0.01)   # warp
    tile = coverage_tile(PLAIN, 0.65, texels=16)
    assert tuple(tile[8, 8]) == (255, 0) and tuple(tile[8, 24]) == (0, 255)   # the on-top yarn covers its crossing
    assert tuple(tile[0, 0]) == (0, 0)                                          # a gap between four yarns


def test_view_table_straight_above_and_grazing():
    a = 2 * 0.00065 / 0.002
    t = visibility_table(PLAIN, 0.00065, 0.002, 0.0003)
    assert t[-1, :, 0] == pytest.approx(a - a * a / 2.0, abs=0.01)
    assert t[-1, :, 1] == pytest.approx(a - a * a / 2.0, abs=0.01)
    # low over the cloth, looking along the weft: the warp runs across the view and stands in front
    weft, warp = t[1, 0]
    assert warp > 0.6 and weft < 0.4 and weft + warp == pytest.approx(1.0, abs=0.02)
    # a plain weave seen along the warp is the same with the families swapped
    assert tuple(t[1, t.shape[1] // 2]) == pytest.approx((warp, weft), abs=0.02)


def test_surface_leaves_torn_cloth_and_mass_couples_to_the_yarns(flat):
    """A flat cloth with weft springs cut down a column and the crossings beside the cut at yarn level,
    every intact crossing far (far_field_px 64): no surface quad holds a yarn-level crossing or a cut
    spring, the tear's yarns are still drawn (their broken ends fade) and so is the cloth's border."""
    from fraytool.kinds import STRUCT_WARP, STRUCT_WEFT

    rec = flat.copy()
    cut_i, rows = 47, range(20, 70)
    for j in rows:
        rec.spring_alive[flat.topology["weft_structural_spring"][j, cut_i]] = False
        for i in range(cut_i - 1, cut_i + 3):
            rec.crossing_yarn_level[flat.crossing(i, j)] = True
    spec = _with(_view(flat.spec, 60.0, 30.0, 1.0, 90), far_field_px=64.0)
    b = GeometryBuilder(flat.topology, YarnStyle.from_spec(spec.render, flat.topology), Camera(spec.camera), 90,
                        image_width=160)
    geom = b.build(rec)
    field = geom.surface
    assert field is not None and field.quads > 0
    step = round(float(np.abs(np.diff(field.vertices[field.triangles[0], 12])).max()))   # grid cells per quad side
    level = np.asarray(rec.crossing_yarn_level)
    dead = ~np.asarray(rec.spring_alive) & np.isin(np.asarray(flat.topology["spring_kind"]), (STRUCT_WEFT, STRUCT_WARP))
    ends = np.stack([np.asarray(flat.topology["spring_crossing_a"])[dead],
                     np.asarray(flat.topology["spring_crossing_b"])[dead]], axis=1)
    for corner in field.triangles[0::2, 0]:
        jq, iq = divmod(int(corner), flat.W)
        block = np.array([(jq + dj) * flat.W + iq + di for dj in range(step + 1) for di in range(step + 1)
                          if jq + dj < flat.H and iq + di < flat.W])
        assert not level[block].any()
        assert not np.isin(ends, block).all(axis=1).any()
    assert len(geom.yarns.translucent) > 0                      # the cut's broken ends, fading
    # the cut's yarns and the border's are yarns: the hidden links are none of theirs
    assert not field.hidden_weft[20:70, cut_i - 1:cut_i + 3].any()
    assert not field.hidden_weft[0].any() and not field.hidden_warp[0].any()
    # the far border too; the last quads take the 3 cells left over (95 = 4 x 23 + 3), so the surface
    # reaches the border yarns, and the links beside them are the surface's alone
    assert not field.hidden_weft[-1].any() and not field.hidden_warp[-1].any()
    j, i = np.divmod(np.unique(field.triangles), flat.W)
    assert j.max() == flat.H - 1 and i.max() == flat.W - 1
    assert field.hidden_weft[-2, 10:40].all() and field.hidden_warp[-2, 10:40].all()


def test_seen_normals_straight_above_and_grazing():
    """The seen normals of round yarns. From straight above the rays land evenly across each yarn, so the
    angle phi of the normal they meet has density cos(phi) / 2: a bin holds (sin(hi) - sin(lo)) / 2 of
    the hits, and the normals lean neither way along the yarn. Low over the cloth, looking along the
    weft, the warp runs across the view and shows the eye its near flank: most hits have phi > 0."""
    shares, normals = view_tables(PLAIN, 0.00065, 0.002, 0.0003)
    edges = np.linspace(-0.5 * math.pi, 0.5 * math.pi, NORMAL_BINS + 1)
    want = 0.5 * (np.sin(edges[1:]) - np.sin(edges[:-1]))
    for family in range(2):
        np.testing.assert_allclose(normals[-1, :, 0, family, :], np.broadcast_to(want, (shares.shape[1], NORMAL_BINS)),
                                   atol=0.025)      # 24 rays per spacing: 15 across a yarn
        np.testing.assert_allclose(normals[-1, :, 1, family, :], 0.0, atol=0.02)
    np.testing.assert_allclose(normals[:, :, 0].sum(axis=-1), 1.0, atol=1e-5)        # every family is seen
    np.testing.assert_allclose(bin_angles(), 0.5 * (edges[1:] + edges[:-1]))
    warp_low = normals[1, 0, 0, 1, :]
    assert warp_low[NORMAL_BINS // 2:].sum() > 0.8, warp_low


def test_the_surface_shader_has_the_tables_layout():
    """shaders/farfield.vert reads the view table with the renderer's layout and bin count."""
    from fraytool.render.renderer import VISIBILITY_LAYERS
    from fraytool.resources import shader_source
    source = shader_source("farfield.vert")
    assert f"const int NORMAL_BINS = {NORMAL_BINS};" in source
    assert f"const int VISIBILITY_LAYERS = {VISIBILITY_LAYERS};" in source


# -- with GL --------------------------------------------------------------------------------------

def _shares(ctx, pc, elevation: float, azimuth: float, monkeypatch):
    """(far field, reference) shares of warp, weft and gap mid-frame: pure red warp, green weft, blue
    background, ambient light only, so a pixel's linear colour is the share of each; the far field
    with yarns about 0.7 px apart, the reference round tubes (24 sides: the level of detail's facet
    limit lifted) drawn at 4x and box-filtered."""
    import fraytool.render.lod as lod

    monkeypatch.setattr(lod, "FACET_PX", 0.05)
    size = (160, 90)
    spec = _with(_view(pc.spec, elevation, azimuth, 0.7, size[1]), warp_color=(1.0, 0.0, 0.0),
                 weft_color=(0.0, 1.0, 0.0), background=(0.0, 0.0, 1.0), ambient=1.0, light_intensity=0.0,
                 specular=0.0, fill_intensity=0.0, shadows=False, yarn_shape="tube", tube_sides=24)
    far, geom, _ = _draw(ctx, spec, pc, pc.rest, size)
    assert geom.surface is not None and geom.surface.quads > 0
    ref = _reference(ctx, spec, pc, pc.rest, size)
    middle = (slice(39, 51), slice(50, 110))

    def shares(img):  # each pixel decoded, then averaged: a share is a mean in linear light
        return srgb_to_linear(img[middle].reshape(-1, 3).astype(float) / 255.0).mean(axis=0)

    return shares(far), shares(ref)


@pytest.mark.parametrize("elevation, azimuth", [(90.0, 0.0), (35.0, 0.0), (15.0, 0.0), (15.0, 20.0), (35.0, 60.0)])
def test_far_field_shows_the_families_as_supersampled_tubes_do(gl_ctx, flat, elevation, azimuth, monkeypatch):
    """A plain weave from straight above down to 15 degrees: the far field's warp, weft and gap shares
    are the round tubes', within 0.03 (_shares)."""
    got, want = _shares(gl_ctx, flat, elevation, azimuth, monkeypatch)
    assert got == pytest.approx(want, abs=0.03), (got, want)


@pytest.mark.parametrize("elevation, azimuth", [(30.0, 0.0), (30.0, 40.0), (45.0, 10.0), (90.0, 0.0)])
def test_far_field_is_lit_as_supersampled_tubes(gl_ctx, flat, elevation, azimuth, monkeypatch):
    """Lambert alone on the tube normal (the key light, no ambient, no highlight): the surface shades each
    family at the normals the view meets (the seen-normal table), and its mean colour mid-frame is that of
    round tubes (24 sides, smooth along) drawn at 4x, within 4.5 levels per channel. Shading the yarns'
    upper part as if seen evenly across, the far field was 11 levels darker at 30 degrees. (The tubes
    are 4 px wide at 4x; thinner, their edges darken under MSAA and the reference is not converged.)"""
    import fraytool.render.lod as lod
    import fraytool.render.renderer as renderer

    monkeypatch.setattr(lod, "FACET_PX", 0.05)        # round tubes, smooth along: no level of detail
    monkeypatch.setattr(lod, "SAMPLE_PX", 1.0)
    monkeypatch.setattr(lod, "STRAIGHT_PX", 0.0)
    monkeypatch.setattr(renderer, "KAJIYA_WEIGHT", 0.0)
    size = (160, 90)
    spec = _with(_view(flat.spec, elevation, azimuth, 1.5, size[1]), ambient=0.0, specular=0.0,
                 fill_intensity=0.0, shadows=False, yarn_shape="tube", tube_sides=24)
    far, geom, _ = _draw(gl_ctx, spec, flat, flat.rest, size)
    assert geom.surface is not None and geom.surface.quads > 0
    ref = _reference(gl_ctx, spec, flat, flat.rest, size)
    middle = (slice(39, 51), slice(50, 110))
    got, want = (img[middle].reshape(-1, 3).astype(float).mean(axis=0) for img in (far, ref))
    assert np.abs(got - want).max() <= 4.5, (got, want)


@pytest.fixture(scope="module")
def twill(tmp_path_factory):
    """The flat cloth woven as a 3/1 twill: the weft shows on three crossings in four from the front,
    on one from the back."""
    path = tmp_path_factory.mktemp("twill") / "flat_twill.toml"
    path.write_text(FLAT.read_text().replace('weave = "plain"', 'weave = "twill"\ntwill = "3/1"'))
    return PosedCloth(path)


@pytest.mark.parametrize("elevation", [70.0, -70.0, 30.0, -30.0])
def test_an_uneven_weave_shows_its_own_shares_from_either_side(gl_ctx, twill, elevation, monkeypatch):
    """A 3/1 twill seen from either side: from its front (below: an "xz" cloth's crossing normals point
    down, -y) the weft floats over three crossings in four and leads, from its back (above) the warp
    does. The far field's shares against round tubes drawn at 4x, within 0.05 (_shares)."""
    got, want = _shares(gl_ctx, twill, elevation, 30.0, monkeypatch)
    assert got == pytest.approx(want, abs=0.05), (got, want)
    warp, weft = got[0], got[1]
    assert (weft > warp + 0.1) if elevation < 0 else (warp > weft + 0.1), got


def test_far_field_removes_the_moire_of_a_grazing_weave(gl_ctx, flat, monkeypatch):
    """A weave seen at 20 degrees with yarns about a pixel apart: drawn as ribbons it beats against the
    pixel grid; the far field stays within 4 levels (blurred RMS) of round tubes (24 sides) drawn at 4x,
    under half the ribbons' own error. (Supersampled ribbons are themselves 2 levels from the tubes
    here: at grazing views their per-pixel cylinder misses the yarn's bend, docs/rendering.md.)"""
    import fraytool.render.lod as lod

    size = (160, 90)
    spec = _view(flat.spec, 20.0, 30.0, 1.2, size[1])
    with monkeypatch.context() as m:
        m.setattr(lod, "FACET_PX", 0.05)
        ref = _reference(gl_ctx, _with(spec, yarn_shape="tube", tube_sides=24), flat, flat.rest, size)
    far, geom, _ = _draw(gl_ctx, spec, flat, flat.rest, size)
    yarns, _, _ = _draw(gl_ctx, _with(spec, far_field=False), flat, flat.rest, size)
    assert geom.surface is not None
    e_far, e_yarns = blurred_rms(far, ref), blurred_rms(yarns, ref)
    assert e_far <= 4.0 and e_far < 0.5 * e_yarns, (e_far, e_yarns)


@pytest.mark.parametrize("elevation, azimuth, footprint", [(90.0, 0.0, 1.6), (40.0, 30.0, 1.4), (20.0, 30.0, 1.2)])
def test_far_field_keeps_the_weaves_pixel_scale_contrast(gl_ctx, flat, elevation, azimuth, footprint, monkeypatch):
    """At 1.2-1.6 px a crossing a camera's pixel (a 1 px box) still sees the weave: pixel to pixel, round
    tubes (24 sides) drawn at 4x and box-filtered vary by 15-35 levels in green (the weft's channel).
    Plain trilinear filtering of the weave texture kept 45-55 % of that spread; with its half-level bias
    (shaders/farfield.frag) the surface keeps 62-70 %. Under 58 % the weave is washed out; over 100 % it
    is sharper than the box (a level and a half of bias gives 130-200 %, and beats)."""
    import fraytool.render.lod as lod

    size = (160, 90)
    spec = _view(flat.spec, elevation, azimuth, footprint, size[1])
    with monkeypatch.context() as m:
        m.setattr(lod, "FACET_PX", 0.05)
        ref = _reference(gl_ctx, _with(spec, yarn_shape="tube", tube_sides=24), flat, flat.rest, size)
    far, geom, _ = _draw(gl_ctx, spec, flat, flat.rest, size)
    assert geom.surface is not None      # footprints under FAR_PX (2 px): the surface alone
    middle = np.s_[25:65, 50:110, 1]
    ratio = far[middle].astype(float).std() / ref[middle].astype(float).std()
    assert 0.58 <= ratio <= 1.0, ratio


def test_large_yarns_draw_exactly_as_without_the_far_field(gl_ctx, flat):
    """The whole cloth in view from straight above with its yarns 5.7 px apart in the middle (over 5 px
    at the corners): no surface is built and the frame is bit-identical to the far field off."""
    size = (960, 540)
    spec = _view(flat.spec, 90.0, 0.0, 5.7, size[1])
    on, geom, _ = _draw(gl_ctx, spec, flat, flat.rest, size)
    off, _, _ = _draw(gl_ctx, _with(spec, far_field=False), flat, flat.rest, size)
    assert geom.surface is None and geom.yarns.far is None
    assert np.array_equal(on, off)


def test_wireframe_view_is_unchanged(gl_ctx, flat):
    size = (160, 90)
    spec = _view(flat.spec, 50.0, 30.0, 1.0, size[1])
    on, _, _ = _draw(gl_ctx, spec, flat, flat.rest, size, wireframe="only")
    off, _, _ = _draw(gl_ctx, _with(spec, far_field=False), flat, flat.rest, size, wireframe="only")
    assert np.array_equal(on, off)


def test_surface_depth_and_alpha(gl_ctx, flat):
    """Straight above, yarns 0.7 px apart: the float target's alpha is the weave's coverage
    1 - (1 - a)^2 (the gaps show what is behind) and the depth is the cloth's distance."""
    size = (160, 90)
    spec = _view(flat.spec, 90.0, 0.0, 0.7, size[1])
    rgba, geom, z = _draw(gl_ctx, spec, flat, flat.rest, size, target="float", alpha=True, depth=True)
    assert geom.surface is not None and geom.yarns.far is None      # all far: no band
    a = 2 * 0.00065 / 0.002
    middle = (slice(35, 55), slice(60, 100))
    assert rgba[middle][..., 3].mean() == pytest.approx(1.0 - (1.0 - a) ** 2, abs=0.02)
    d = float(np.linalg.norm(np.asarray(spec.camera.position_m)))
    assert np.abs(z[middle] - d).max() < 1e-3 * d


@pytest.mark.parametrize("samples", [2, 4])
@pytest.mark.parametrize("footprint", [0.7, 2.2])
def test_every_msaa_count_covers_the_weave(gl_ctx, flat, footprint, samples):
    """Whatever MSAA count a scene asks for, the surface alone (0.7 px apart) and the band (2.2 px, yarns
    and surface each on their share of the samples) cover the weave's 1 - (1 - a)^2 of each pixel. The
    split takes the framebuffer's own count: llvmpipe gives 4 samples where 2 are asked, and a split
    of 2 left half of each pixel undrawn (alpha 0.44, the floor showing through the cloth)."""
    size = (160, 90)
    spec = _with(_view(flat.spec, 90.0, 0.0, footprint, size[1]), samples=samples)
    rgba, geom, _ = _draw(gl_ctx, spec, flat, flat.rest, size, target="float", alpha=True)
    assert geom.surface is not None and (geom.yarns.far is not None) == (footprint > 1.0)
    a = 2 * 0.00065 / 0.002
    assert rgba[35:55, 60:100, 3].mean() == pytest.approx(1.0 - (1.0 - a) ** 2, abs=0.02)


def test_a_dolly_through_the_band_does_not_pop(gl_ctx, flat):
    """A camera moving away until the yarns go from 4 px to 0.9 px apart crosses the blend band. Each
    frame-to-frame change is measured beyond the true one, the change of the same two frames drawn at 4x
    and box-filtered (mean absolute difference of the blurred steps): a pop or a flicker is that excess.
    With the far field it is at most 1.1 times the yarns-only draw's at every step (the first steps are
    still all yarns, whose own flicker it inherits), and every frame is nearer its 4x picture than the
    yarns-only frame is."""
    size = (160, 90)
    footprints = np.geomspace(4.0, 0.9, 14)

    def frames(kind: str) -> list:
        out = []
        for fp in footprints:
            spec = _view(flat.spec, 55.0, 30.0, float(fp), size[1])
            img = _reference(gl_ctx, spec, flat, flat.rest, size) if kind == "ref" else \
                _draw(gl_ctx, _with(spec, far_field=kind == "band"), flat, flat.rest, size)[0]
            out.append(gaussian_blur(img.astype(float)))
        return out

    ref, band, yarns = frames("ref"), frames("band"), frames("yarns")

    def excess(f: list) -> np.ndarray:
        return np.array([np.abs((f[k + 1] - f[k]) - (ref[k + 1] - ref[k])).mean() for k in range(len(f) - 1)])

    def error(f: list) -> np.ndarray:
        return np.array([np.sqrt(((a - b) ** 2).mean()) for a, b in zip(f, ref)])

    assert (excess(band) <= 1.1 * excess(yarns)).all(), (excess(band), excess(yarns))
    assert (error(band) <= error(yarns)).all(), (error(band), error(yarns))


def test_sewn_panels_far_away_keep_their_seam_and_colours(gl_ctx):
    """seam_rip's two panels (plain and twill, each its own colours) and the seam between them, drawn at
    160x90 where their yarns are about a pixel apart: each panel is surface, the stitches stay yarns,
    and the frame agrees with the same frame drawn with yarns only at 4x (blurred RMS within 6 levels,
    under the yarns' own error at 1x)."""
    pc = PosedCloth(Path(__file__).parent.parent / "scenes" / "seam_rip.toml")
    size = (160, 90)
    spec = pc.spec
    far, geom, _ = _draw(gl_ctx, spec, pc, pc.rest, size)
    assert geom.surface is not None and geom.surface.quads > 0
    panel = np.asarray(pc.topology["crossing_panel"])
    corners = np.unique(geom.surface.triangles)
    from fraytool.render.yarns import crossing_places

    place_panel = np.full(pc.W * pc.H, -1)
    place_panel[crossing_places(pc.topology)] = panel
    assert set(place_panel[corners]) == {0, 1}                 # both panels drawn as surface
    from fraytool.kinds import STITCH
    from fraytool.render.yarns import yarn_pieces

    field = geom.surface
    pieces = yarn_pieces(pc.topology, pc.rest.particle_position_m, pc.rest.crossing_yarn_level, pc.rest.spring_alive,
                         hidden=(field.hidden_weft, field.hidden_warp))
    live_stitches = int(((np.asarray(pc.topology["spring_kind"]) == STITCH) & pc.rest.spring_alive).sum())
    assert live_stitches > 0 and int((pieces.yarn == -1).sum()) == live_stitches   # every stitch a yarn piece
    ref = _reference(gl_ctx, spec, pc, pc.rest, size)
    yarns, _, _ = _draw(gl_ctx, _with(spec, far_field=False), pc, pc.rest, size)
    e_far, e_yarns = blurred_rms(far, ref), blurred_rms(yarns, ref)
    assert e_far <= 6.0 and e_far < e_yarns, (e_far, e_yarns)


def test_a_seam_ripping_far_away_keeps_its_tear_in_yarns(gl_ctx):
    """seam_rip far away (160x90) with its seam half ripped: half the stitches dead, the structural
    springs beside them cut and those crossings at yarn level (and 40 couples elsewhere). The dead stitches are not drawn, every live one
    is a yarn piece, no surface quad holds a yarn-level crossing or both ends of a cut spring, the torn
    yarns fade out, and the frame still agrees with the same frame drawn with yarns only at 4x (blurred
    RMS within 6 levels, under the yarns' own error at 1x)."""
    from fraytool.kinds import STITCH, STRUCT_WARP, STRUCT_WEFT
    from fraytool.render.yarns import crossing_places, yarn_pieces

    pc = PosedCloth(Path(__file__).parent.parent / "scenes" / "seam_rip.toml")
    topo = pc.topology
    kind = np.asarray(topo["spring_kind"])
    a, b = np.asarray(topo["spring_crossing_a"]), np.asarray(topo["spring_crossing_b"])
    rec = pc.copy()
    stitches = np.flatnonzero(kind == STITCH)
    ripped = stitches[: len(stitches) // 2]
    rec.spring_alive[ripped] = False
    torn = np.unique(np.concatenate([a[ripped], b[ripped]]))
    rec.crossing_yarn_level[torn] = True
    structural = np.isin(kind, (STRUCT_WEFT, STRUCT_WARP))
    cut = np.flatnonzero(structural & (np.isin(a, torn) | np.isin(b, torn)))
    rec.spring_alive[cut] = False
    # and, away from the seam, crossings already turned into mass couples with their springs whole
    rng = np.random.default_rng(3)
    rec.crossing_yarn_level[rng.choice(np.flatnonzero(~np.isin(np.arange(len(rec.crossing_yarn_level)), torn)),
                                       40, replace=False)] = True
    size = (160, 90)
    far, geom, _ = _draw(gl_ctx, pc.spec, pc, rec, size)
    field = geom.surface
    assert field is not None and field.quads > 0
    places = crossing_places(topo)
    level_places = places[np.asarray(rec.crossing_yarn_level)]
    cut_ends = np.stack([places[a[cut]], places[b[cut]]], axis=1)
    step = round(float(np.abs(np.diff(field.vertices[field.triangles[0], 12])).max()))
    for corner in field.triangles[0::2, 0]:
        jq, iq = divmod(int(corner), pc.W)
        block = np.array([(jq + dj) * pc.W + iq + di for dj in range(step + 1) for di in range(step + 1)])
        assert not np.isin(level_places, block).any()
        assert not np.isin(cut_ends, block).all(axis=1).any()
    pieces = yarn_pieces(topo, rec.particle_position_m, rec.crossing_yarn_level, rec.spring_alive,
                         hidden=(field.hidden_weft, field.hidden_warp))
    live = int(((kind == STITCH) & rec.spring_alive).sum())
    assert 0 < live < len(stitches) and int((pieces.yarn == -1).sum()) == live
    assert len(geom.yarns.translucent) > 0                      # the cut yarns' broken ends fade
    assert np.isfinite(far.astype(float)).all()
    ref = _reference(gl_ctx, pc.spec, pc, rec, size)
    yarns, _, _ = _draw(gl_ctx, _with(pc.spec, far_field=False), pc, rec, size)
    e_far, e_yarns = blurred_rms(far, ref), blurred_rms(yarns, ref)
    assert e_far <= 6.0 and e_far < e_yarns, (e_far, e_yarns)


def _folded_over_an_edge(pc, radius_m: float):
    """The flat cloth (in y = 0) folded over an edge along z at x = 0: flat for x < 0, a quarter circle
    of `radius_m`, then hanging straight down; each crossing's height above the plane kept along the
    normal. Returns (record, unit normals of the crossings)."""
    rec = pc.copy(1)
    x = rec.particle_position_m.astype(np.float64)
    u, h = x[:, 0], x[:, 1]
    arc_end = radius_m * math.pi / 2.0
    angle = np.clip(u, 0.0, arc_end) / radius_m
    nx = np.where(u < 0.0, 0.0, np.sin(angle))
    ny = np.where(u < 0.0, 1.0, np.cos(angle))
    px = np.where(u < 0.0, u, np.where(u <= arc_end, radius_m * np.sin(angle), radius_m))
    py = np.where(u < 0.0, 0.0, np.where(u <= arc_end, radius_m * (np.cos(angle) - 1.0), -radius_m - (u - arc_end)))
    rec.particle_position_m[:, 0] = px + h * nx
    rec.particle_position_m[:, 1] = py + h * ny
    normals = np.stack([nx, ny, np.zeros_like(nx)], axis=1)[: pc.C]
    return rec, normals


def test_the_light_leaves_a_fold_smoothly_as_the_yarns_show(gl_ctx, flat):
    """Cloth folded over an edge, the key light grazing it from behind the fold, shadows on, every
    crossing far. Where the light passes behind the cloth's plane (N.L from -0.3 to 0.05), the far
    field is within 13 levels (blurred RMS at the crossings) of the yarns drawn at 4x; before the key
    part faded there (shaders/farfield.vert) the surface's own shadow cut it off in steps, 18 levels."""
    size = (320, 180)
    rec, normals = _folded_over_an_edge(flat, 0.02)
    light = np.array([-1.0, 0.3, 0.35])
    spec = _with(_view(flat.spec, 35.0, 20.0, 1.25, size[1]), far_field_px=64.0, fill_intensity=0.0,
                 light_direction=tuple(light))
    assert spec.render.shadows
    far, geom, _ = _draw(gl_ctx, spec, flat, rec, size)
    assert geom.surface is not None and geom.yarns.far is None
    ref = _reference(gl_ctx, spec, flat, rec, size)
    n_l = normals @ (light / np.linalg.norm(light))
    points = rec.particle_position_m[: flat.C].astype(np.float64)
    band = (n_l > -0.3) & (n_l < 0.05) & (np.abs(points[:, 2]) < 0.07)   # away from the cloth's ends
    view_proj = Camera(spec.camera).view_proj(size[0] / size[1])
    clip = points[band] @ view_proj[:, :3].T + view_proj[:, 3]
    x = ((0.5 + 0.5 * clip[:, 0] / clip[:, 3]) * size[0]).astype(int)
    y = ((0.5 - 0.5 * clip[:, 1] / clip[:, 3]) * size[1]).astype(int)
    assert band.sum() > 200 and (x >= 0).all() and (x < size[0]).all() and (y >= 0).all() and (y < size[1]).all()
    d = (gaussian_blur(far.astype(float)) - gaussian_blur(ref.astype(float)))[y, x]
    assert float(np.sqrt(np.mean(d * d))) <= 13.0


def _shadow_map(ctx, spec, pc, size) -> tuple[np.ndarray, object]:
    """The key light's depth map after drawing the rest pose, and the frame's geometry."""
    r = Renderer(ctx, size, spec.render.samples, spec.render, spec.camera, pc.topology)
    try:
        b = GeometryBuilder(pc.topology, YarnStyle.from_spec(spec.render, pc.topology), r.camera, size[1],
                            image_width=r.shaded_width)
        geom = b.build(pc.rest)
        r.draw(geom)
        return np.frombuffer(r.shadow.texture.read(), np.float32).copy(), geom
    finally:
        r.release()


def test_the_surface_casts_only_where_it_is_most_of_the_picture(gl_ctx, flat):
    """In the blend band the yarns are drawn and cast their shadows; the surface casts only where its far
    weight is at least a half (shaders/depth.frag). Yarns 3.4 px apart (weight 0.22 all over): the key
    light's map is the same, texel for texel, as with the far field off; 1 px apart (weight 1, the yarns
    left out) the surface casts, an opaque sheet that closes the weave's gaps."""
    size = (160, 90)
    spec = _with(_view(flat.spec, 90.0, 0.0, 3.4, size[1]), shadow_map_size=512)
    assert spec.render.shadows
    band, geom = _shadow_map(gl_ctx, spec, flat, size)
    yarns, _ = _shadow_map(gl_ctx, _with(spec, far_field=False), flat, size)
    assert geom.surface is not None and geom.surface.quads > 0
    assert 0.1 < geom.surface.weight.max() < 0.5
    assert np.array_equal(band, yarns)
    spec = _with(_view(flat.spec, 90.0, 0.0, 1.0, size[1]), shadow_map_size=512)
    far, geom = _shadow_map(gl_ctx, spec, flat, size)
    yarns, _ = _shadow_map(gl_ctx, _with(spec, far_field=False), flat, size)
    assert geom.surface.weight.min() == 1.0
    assert (far < 0.999).sum() > (yarns < 0.999).sum() * 1.03     # more of the map in shadow
