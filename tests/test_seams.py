"""Several panels and the seams between them (docs/panels.md "Several panels", "Seams"), checked against
the geometry of the scene itself and against Hooke's law, not against the builder's own tables."""
from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest

from fraytool.kinds import STITCH
from fraytool.scene import parse_scene
from fraytool.sim import Simulation
from fraytool.sim.builder import ModelBuilder, ModelBuilderError, build_model
from fraytool.sim.kernels.forces import accumulate_spring_forces

S = 0.004
PANEL = """
[[cloth]]
name = "{name}"
warp_yarns = {w}
weft_yarns = {h}
spacing_m = 0.004
thickness_m = 0.0006
mass_per_crossing_kg = {mass}
origin_m = {origin}
plane = "xz"
weave = "{weave}"
{extra}
[cloth.springs]
structural_n_per_m = 40.0
bend_n_per_m = 1.0
shear_n_per_m = 5.0
damping = 0.02
"""
HEAD = """
[scene]
name = "seams"
seed = 2
[time]
step_s = 0.00020833333333333335
steps_per_frame = 20
frames = {frames}
"""
TEARING = """
[cloth.tearing]
enabled = true
break_strain = 0.18
break_strain_spread = 0.0
"""


def panel(name, origin, w=10, h=8, mass=5e-6, weave="plain", extra=""):
    return PANEL.format(name=name, origin=list(origin), w=w, h=h, mass=mass, weave=weave, extra=extra)


def seam(a="a", sa=1, b="b", sb=3, spacing=S, k=40.0, strain=0.2, reverse="true"):
    return (f'[[seams]]\npanel_a = "{a}"\nsegment_a = {sa}\npanel_b = "{b}"\nsegment_b = {sb}\nreverse = {reverse}\n'
            f"stitch_spacing_m = {spacing}\nstiffness_n_per_m = {k}\nbreak_strain = {strain}\n")


def two_panels(seams: str = "", frames: int = 2, tearing: str = TEARING) -> str:
    """Panel a (10 x 8) and panel b (10 x 8, twill, twice the mass) side by side along x, one spacing apart."""
    return (HEAD.format(frames=frames) + panel("a", (0.0, 0.0, 0.0)) + tearing
            + panel("b", (10 * S, 0.0, 0.0), mass=1e-5, weave="twill") + seams)


def test_panels_keep_their_own_weave_mass_and_place():
    model = build_model(parse_scene(two_panels(), "p.toml"))
    assert model.panel_names == ("a", "b")
    a, b = model.crossing_panel == 0, model.crossing_panel == 1
    assert a.sum() == b.sum() == 80
    np.testing.assert_allclose(model.crossing_mass_kg[a], 5e-6)
    np.testing.assert_allclose(model.crossing_mass_kg[b], 1e-5)
    x = model.crossing_rest_position_m
    assert x[a, 0].max() == pytest.approx(9 * S) and x[b, 0].min() == pytest.approx(10 * S)
    # no spring joins the two panels without a seam
    assert (model.crossing_panel[model.spring_crossing_a] == model.crossing_panel[model.spring_crossing_b]).all()
    # the twill's weft floats over two warps in panel b only
    top_b = model.crossing_weft_on_top[b].reshape(8, 10)
    assert (top_b[0, :3] == [True, True, False]).all() or (top_b[0, :3] == [False, True, True]).all() \
        or (top_b[0, :3] == [True, False, True]).all()
    assert not np.array_equal(model.crossing_weft_on_top[a].reshape(8, 10), top_b)


def test_a_seam_stitches_the_nearest_border_crossings_every_stitch_spacing():
    """Panel a's right edge (segment 1) to panel b's left edge (segment 3, reversed: bottom to bottom) every
    2 spacings: on panels of 9 weft yarns the edge is 8 spacings long (the rectangle's outline runs through
    its corner crossings), so 5 stitches at heights 0, 2, 4, 6, 8 spacings, each from the crossing of a's
    last column to the one of b's first column at the same height."""
    text = two_panels(seam(spacing=2 * S)).replace("weft_yarns = 8", "weft_yarns = 9")
    model = build_model(parse_scene(text, "p.toml"))
    st = np.flatnonzero(model.spring_kind == STITCH)
    edge = 8 * S
    count = round(edge / (2 * S)) + 1
    assert st.size == count
    x = model.crossing_rest_position_m
    a, b = x[model.spring_crossing_a[st]], x[model.spring_crossing_b[st]]
    np.testing.assert_allclose(a[:, 0], 9 * S)
    np.testing.assert_allclose(b[:, 0], 10 * S)
    np.testing.assert_allclose(a[:, 2], b[:, 2])  # straight across: bottom sewn to bottom
    heights = np.sort(a[:, 2])
    want = np.arange(count) * 2 * S
    np.testing.assert_allclose(heights, want, atol=1e-12)
    np.testing.assert_allclose(model.spring_rest_length_m[st], S)  # stitch_length_m 0: the spacing


def test_a_stitch_pulls_by_hookes_law_and_never_pushes():
    model = build_model(parse_scene(two_panels(seam()), "p.toml"))
    state = model.state()
    st = int(np.flatnonzero(model.spring_kind == STITCH)[0])
    k = model.spring_base_stiffness_n_per_m[st]
    a, b = state.spring_particle_a[st], state.spring_particle_b[st]
    only = np.zeros(model.spring_count, bool)
    only[st] = True
    x = state.particle_position_m
    for stretch in (0.3, -0.3):  # 30 % longer, 30 % shorter than rest
        x[b] = x[a] + np.array([S * (1 + stretch), 0.0, 0.0])
        f = np.zeros_like(x)
        accumulate_spring_forces(model.spring_kind, state.spring_rest_length_m, x, state.spring_particle_a,
                                 state.spring_particle_b, only, state.spring_stiffness_n_per_m, f)
        want = k * S * stretch if stretch > 0 else 0.0
        assert f[a, 0] == pytest.approx(want) and f[b, 0] == pytest.approx(-want)


def test_stitches_break_one_by_one_the_most_strained_first():
    spec = parse_scene(two_panels(seam(strain=0.2)), "p.toml")
    sim = Simulation(spec)
    state, model = sim.state, sim.model
    st = np.flatnonzero(model.spring_kind == STITCH)
    b = model.crossing_panel == 1
    # pull panel b away so that every stitch is past its break strain, by amounts that do not follow the
    # stitches' order along the seam (so "the first past its limit" would break them in another order)
    n = model.crossing_count
    x = state.particle_position_m
    z = model.crossing_rest_position_m[:, 2]
    x[:n][b, 0] += 0.5 * S + 0.3 * S * np.abs(np.sin(5.0 * z[b] / z.max() + 0.3))
    stage = next(s for s in sim.solver._plan.stages if s.name == "seams")
    strains = lambda: np.linalg.norm(x[model.spring_crossing_b[st]] - x[model.spring_crossing_a[st]], axis=1) / S - 1
    assert (strains() > 0.2).all()
    order = []
    for _ in range(st.size):
        before = state.spring_alive[st].copy()
        stage.run(state, sim.solver.context, spec.time.step_s)
        gone = np.flatnonzero(before & ~state.spring_alive[st])
        assert gone.size == 1
        order.append(int(gone[0]))
    assert order != sorted(order)  # the test can tell "furthest past" from "first past"
    np.testing.assert_array_equal(order, np.argsort(-strains(), kind="stable"))
    assert stage.summary(state) == {"stitches": st.size, "broken_stitches": st.size}


def test_stitches_take_the_seams_break_strain_stiffness_and_length():
    """With no spread, every stitch's break strain is the seam's exactly, its stiffness the seam's and its rest
    length the yarn spacing (stitch_length_m unset)."""
    model = build_model(parse_scene(two_panels(seam(strain=0.2, k=40.0)), "p.toml"))
    st = model.spring_kind == STITCH
    assert st.sum() == 8
    np.testing.assert_array_equal(model.spring_break_strain[st], 0.2)
    np.testing.assert_array_equal(model.spring_base_stiffness_n_per_m[st], 40.0)
    np.testing.assert_allclose(model.spring_rest_length_m[st], S, rtol=1e-15)


@pytest.mark.parametrize("past", [0.002, -0.002])
def test_a_stitch_breaks_as_soon_as_it_passes_its_break_strain(past):
    """One stitch stretched to its break strain + 0.002 breaks in the next step; at - 0.002 it holds."""
    spec = parse_scene(two_panels(seam(strain=0.2)), "p.toml")
    sim = Simulation(spec)
    state, model = sim.state, sim.model
    st = np.flatnonzero(model.spring_kind == STITCH)
    s = st[3]
    a, b = model.spring_crossing_a[s], model.spring_crossing_b[s]
    x = state.particle_position_m
    direction = (x[b] - x[a]) / np.linalg.norm(x[b] - x[a])
    x[b] = x[a] + (1.0 + 0.2 + past) * S * direction
    stage = next(g for g in sim.solver._plan.stages if g.name == "seams")
    stage.run(state, sim.solver.context, spec.time.step_s)
    assert state.spring_alive[s] == (past < 0)
    assert state.spring_alive[st].sum() == st.size - (past > 0)


def test_a_seams_figures_name_its_first_and_last_break_frames():
    from fraytool.sim.tear_control_figures import tear_control_figures, tracked_springs

    spec = parse_scene(two_panels(seam(strain=0.2) + seam(sa=3, sb=1, strain=0.3)), "p.toml")
    model = build_model(spec)
    tracked = tracked_springs(model)
    assert tracked.size == (model.spring_kind == STITCH).sum()
    broken = np.zeros(model.spring_count, bool)
    frames = np.full(tracked.size, -1)
    first_seam = np.flatnonzero(model.spring_seam[tracked] == 0)
    broken[tracked[first_seam[[1, 4, 6]]]] = True
    frames[first_seam[[1, 4, 6]]] = [9, 3, 7]
    figures = tear_control_figures(model, broken, frames, spec)
    assert figures["seams"][0] == {"index": 0, "panels": ["a", "b"], "stitches": first_seam.size, "broken": 3,
                                   "first_break_frame": 3, "last_break_frame": 9}
    assert figures["seams"][1]["broken"] == 0 and figures["seams"][1]["first_break_frame"] is None


def test_simulate_json_reports_stitches_and_broken_stitches(tmp_path):
    """Two panels pulled apart by bars on their outer edges: the weak seam opens (stitches break),
    and --json says how many of how many."""
    text = two_panels(seam(strain=0.1), frames=30) + """
[[bodies]]
name = "l"
shape = "box"
half_extents_m = [0.002, 0.002, 0.02]
motion = "kinematic"
velocity_m_s = [-0.5, 0.0, 0.0]
collide = false
[[bodies]]
name = "r"
shape = "box"
half_extents_m = [0.002, 0.002, 0.02]
position_m = [0.076, 0.0, 0.0]
motion = "kinematic"
velocity_m_s = [0.5, 0.0, 0.0]
collide = false
[[attachments]]
body = "l"
panel = "a"
edge = "left"
[[attachments]]
body = "r"
panel = "b"
edge = "right"
"""
    (tmp_path / "s.toml").write_text(text)
    run = subprocess.run([sys.executable, "-m", "fraytool", "simulate", str(tmp_path / "s.toml"), "-o",
                          str(tmp_path / "out"), "--json", "--progress", "none"], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    import json

    out = json.loads(run.stdout)
    assert out["stitches"] == 8 and 0 < out["broken_stitches"] <= 8  # a stitch at every crossing of the edge
    assert out["all_finite"]
    # broken_springs counts the cloth's own springs (docs/panels.md): from the frame records, the springs
    # alive at the start and not at the end, less the stitches

    from fraytool.io.frame_store import FrameStore
    from fraytool.scene import load_scene
    from fraytool.kinds import STITCH
    from fraytool.sim.simulation import Simulation

    store = FrameStore(tmp_path / "out")
    first, last = store.load_frame(0).spring_alive, store.load_frame(store.frames_complete() - 1).spring_alive
    gone = first & ~last
    stitch = Simulation(load_scene(tmp_path / "s.toml")).model.spring_kind == STITCH
    assert int(gone[stitch].sum()) == out["broken_stitches"]
    assert out["broken_springs"] == int(gone[~stitch].sum()), (out, int(gone[~stitch].sum()))
    # per seam: its stitches, how many broke and the frames of its first and last break, read off the records
    alive = np.array([store.load_frame(f).spring_alive[stitch].sum() for f in range(store.frames_complete())])
    fell = np.flatnonzero(np.diff(alive) < 0) + 1
    assert out["seams"] == [{"index": 0, "stitches": 8, "panels": ["a", "b"], "broken": out["broken_stitches"],
                             "first_break_frame": int(fell[0]), "last_break_frame": int(fell[-1])}], out["seams"]
    check = subprocess.run([sys.executable, "-m", "fraytool", "check", str(tmp_path / "s.toml")],
                           capture_output=True, text=True)
    assert "seam 0 (a - b): 8 stitches" in check.stdout, check.stdout


def test_a_weak_line_reports_the_springs_it_weakened_in_its_own_panel_only():
    """The weakened springs are those whose break strain the line changed (the same scene without it draws the
    same numbers): all in its panel, none in the panel beside it, as `check` lists them."""
    from fraytool.scene import parse_scene
    from fraytool.sim.builder import build_model
    from fraytool.sim.tear_control_figures import tear_control_figures

    line = '\n[[weak_lines]]\npanel = "a"\npoints_m = [[0.0, 0.0], [0.04, 0.04]]\nwidth_m = 0.006\nfactor = 0.5\n'
    plain = build_model(parse_scene(two_panels(), "plain.toml"))
    weak_spec = parse_scene(two_panels() + line, "weak.toml")
    weak = build_model(weak_spec)
    changed = np.flatnonzero(weak.spring_break_strain != plain.spring_break_strain)
    assert changed.size > 0
    panel_of = weak.crossing_panel[weak.spring_crossing_a[changed]]
    assert set(panel_of.tolist()) == {weak.panel_names.index("a")}
    figures = tear_control_figures(weak, spec=weak_spec)
    assert figures["weak_lines"] == [{"index": 0, "springs_weakened": int(changed.size), "panel": "a", "broken": None,
                                      "first_break_frame": None, "last_break_frame": None}]
    assert figures["seams"] == []


def test_panels_collide_with_each_other_through_self_collision():
    """Panel "top" falls onto panel "bottom", held at its four edges: with self-collision every top crossing
    stays above the bottom panel (over its nearest crossing there); without, it falls through."""
    def run(self_collision: bool) -> float:
        text = (HEAD.format(frames=25) + panel("bottom", (0.0, 0.0, 0.0), w=14, h=14)
                + panel("top", (0.012, 0.004, 0.012), w=6, h=6)
                + f"[self_collision]\nenabled = {str(self_collision).lower()}\n"
                + "".join(f'[[bodies]]\nname = "g{k}"\nshape = "sphere"\nradius_m = 0.001\ncollide = false\n'
                          f'[[attachments]]\nbody = "g{k}"\npanel = "bottom"\nedge = "{e}"\n'
                          for k, e in enumerate(("left", "right", "bottom", "top"))))
        sim = Simulation(parse_scene(text, "c.toml"))
        for _ in range(24):
            sim.advance_frame()
        n = sim.model.crossing_count
        top = sim.model.crossing_panel == 1
        x = sim.state.particle_position_m[:n]
        # the top panel's height over the bottom panel's crossing nearest below each of its own (in x, z)
        d = np.linalg.norm(x[top][:, None, [0, 2]] - x[~top][None, :, [0, 2]], axis=2)
        return float((x[top, 1] - x[~top][d.argmin(axis=1), 1]).min())
    assert run(True) > 0.0
    assert run(False) < -0.003


def test_a_panel_wrapped_round_a_cylinder_and_sewn_to_itself_is_a_tube():
    """A 16 x 6 panel wrapped with radius 16 spacings / 2 pi: its crossings lie on the cylinder, and a seam
    from its left edge to its right edge closes it."""
    r = 16 * S / (2 * math.pi)
    text = (HEAD.format(frames=2) + panel("sleeve", (0.0, 0.0, 0.0), w=16, h=6,
                                          extra=f"wrap_radius_m = {r!r}\nplane = \"xy\"").replace(
        'plane = "xz"\n', "", 1)
            + seam("sleeve", 3, "sleeve", 1, spacing=S, reverse="true"))
    model = build_model(parse_scene(text, "t.toml"))
    x = model.crossing_rest_position_m
    # plane xy: u along x, v along y, the cylinder's axis along y through (0, ., -r) (bends towards x cross y = +z)
    np.testing.assert_allclose(np.hypot(x[:, 0], x[:, 2] - r), r, atol=1e-12)
    st = np.flatnonzero(model.spring_kind == STITCH)
    assert st.size == 6
    gap = np.linalg.norm(x[model.spring_crossing_a[st]] - x[model.spring_crossing_b[st]], axis=1)
    np.testing.assert_allclose(gap, 2 * r * math.sin(math.pi / 16), rtol=1e-9)  # one chord: the tube closes


BAD = {
    "lengths differ": (seam(sb=0), "within 25 %"),
    "unknown panel": (seam(b="c"), 'panel_b = "c": must name one of the [[cloth]] panels'),
    "segment out of range": (seam(sa=4), "has segments 0 to 3"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_a_bad_seam_is_one_clear_line_and_exit_2(case, tmp_path):
    text, fragment = BAD[case]
    # panel b 10 x 4 so that its bottom (9 spacings) and panel a's right edge (7) differ by more than 25 %
    scene = two_panels(text).replace("weft_yarns = 8\nspacing_m = 0.004\nthickness_m = 0.0006\nmass_per_crossing_kg = 1e-05",
                                     "weft_yarns = 4\nspacing_m = 0.004\nthickness_m = 0.0006\nmass_per_crossing_kg = 1e-05")
    (tmp_path / "s.toml").write_text(scene)
    run = subprocess.run([sys.executable, "-m", "fraytool", "check", str(tmp_path / "s.toml")],
                         capture_output=True, text=True)
    lines = [x for x in run.stderr.splitlines() if x.strip()]
    assert run.returncode == 2 and len(lines) == 1 and fragment in lines[0] and "[seams.0]" in lines[0], run.stderr


def test_panels_share_spacing_and_solver_settings():
    bad = two_panels().replace("origin_m = [0.04, 0.0, 0.0]\nplane", "origin_m = [0.04, 0.0, 0.0]\nplane", 1)
    bad = bad.replace('name = "b"\nwarp_yarns = 10\nweft_yarns = 8\nspacing_m = 0.004',
                      'name = "b"\nwarp_yarns = 10\nweft_yarns = 8\nspacing_m = 0.005')
    with pytest.raises(Exception, match="every panel shares the first panel's spacing_m"):
        parse_scene(bad, "p.toml")
    b = ModelBuilder()
    b.add_cloth(warp_yarns=4, weft_yarns=4, spacing_m=S, thickness_m=0.0006, mass_per_crossing_kg=5e-6,
                structural_n_per_m=40.0)
    with pytest.raises(ModelBuilderError, match="thickness_m"):
        b.add_panel("p", warp_yarns=4, weft_yarns=4, spacing_m=S, thickness_m=0.0005, mass_per_crossing_kg=5e-6,
                    structural_n_per_m=40.0)
    b.add_panel("p", warp_yarns=4, weft_yarns=4, spacing_m=S, thickness_m=0.0006, mass_per_crossing_kg=5e-6,
                structural_n_per_m=40.0, origin_m=(0.05, 0.0, 0.0))
    b.add_seam(panel_a="cloth", segment_a=1, panel_b="p", segment_b=3, reverse=True, stitch_spacing_m=S,
               stiffness_n_per_m=10.0, break_strain=0.3)
    model = b.finalize()
    assert (model.spring_kind == STITCH).sum() == 4 and model.panel_names == ("cloth", "p")


def test_panels_draw_in_their_own_colours_and_live_stitches_as_threads():
    from fraytool.render.color import THREAD_SRGB, yarn_palette
    from fraytool.render.yarns import yarn_pieces

    text = two_panels(seam()).replace('weave = "twill"\n', 'weave = "twill"\nwarp_color = [0.1, 0.2, 0.9]\n')
    spec = parse_scene(text, "p.toml")
    model = build_model(spec)
    state = model.state()
    topo = model.arrays()
    pieces = yarn_pieces(topo, state.particle_position_m, state.crossing_yarn_level, state.spring_alive)
    stitch = pieces.yarn == -1
    assert stitch.sum() == 8  # one thread per live stitch, of two points
    np.testing.assert_array_equal(np.diff(pieces.offsets)[stitch], 2)
    panel = model.crossing_panel[pieces.first_crossing]
    yarn = ~stitch
    np.testing.assert_array_equal(pieces.color[yarn], 2 * panel[yarn] + pieces.kind[yarn])
    palette = yarn_palette(spec.render, spec.all_panels)
    np.testing.assert_allclose(palette[3], [0.1, 0.2, 0.9])                   # panel b's warp: its own
    np.testing.assert_allclose(palette[2], spec.render.weft_color)           # its weft: [render]'s
    np.testing.assert_allclose(palette[int(pieces.color[stitch][0])], THREAD_SRGB)
    st = np.flatnonzero(model.spring_kind == STITCH)
    state.spring_alive[st[:3]] = False  # three stitches broken: three threads fewer
    fewer = yarn_pieces(topo, state.particle_position_m, state.crossing_yarn_level, state.spring_alive)
    assert (fewer.yarn == -1).sum() == 5


def test_the_studies_variants_of_panel_scenes_build():
    """fraytool study edits the first panel (damping per step, tearing off): the panels follow it, and the
    tearing-off variant drops the scissors (they cut in the tearing stage)."""
    import dataclasses as dc

    from fraytool.scene import load_scene
    from fraytool.study.accuracy import without_tearing

    seams = load_scene("seam_rip")
    edited = dc.replace(seams, cloth=dc.replace(seams.cloth, springs=dc.replace(seams.cloth.springs, damping=0.01)))
    assert build_model(edited).damping == 0.01
    perforated = without_tearing(load_scene("perforated_tear"))
    model = build_model(perforated)
    assert not model.tearing and not np.isfinite(model.spring_cut_time_s).any()


def test_the_shipped_seams_start_at_rest():
    """seam_rip's panels lie one spacing apart: every stitch joins two crossings straight across, at its rest
    length (a stitch paired with a diagonal neighbour would start 41 % stretched and break at once)."""
    from fraytool.scene import load_scene

    model = build_model(load_scene("seam_rip"))
    st = np.flatnonzero(model.spring_kind == STITCH)
    x = model.crossing_rest_position_m
    gap = np.linalg.norm(x[model.spring_crossing_b[st]] - x[model.spring_crossing_a[st]], axis=1)
    np.testing.assert_allclose(gap, model.spring_rest_length_m[st], rtol=1e-12)
    uv = model.crossing_plane_uv_m  # straight across: the same place along the seam (v)
    np.testing.assert_allclose(uv[model.spring_crossing_a[st], 1], uv[model.spring_crossing_b[st], 1])
    # one stitch at every crossing of the left panel's sewn edge (its column of largest u), none twice: the
    # two seams' outlines run half a spacing outside the crossings, and points placed along them fell midway
    # between two crossings, leaving 3 of the 40 unstitched
    left = np.flatnonzero(model.crossing_panel == model.panel_names.index("left"))
    edge = left[np.isclose(uv[left, 0], uv[left, 0].max())]
    assert edge.size == 40
    assert sorted(model.spring_crossing_a[st].tolist()) == sorted(edge.tolist())


@pytest.mark.parametrize("sb, reverse, strain, torn, longest", [
    (3, "false", 0.2, 8, math.sqrt(50)), (3, "true", 0.2, 0, 0), (3, "false", 10.0, 0, 0), (1, "false", 0.2, 8, 10)])
def test_stitches_that_start_past_their_break_strain_are_a_warning_naming_the_seam(sb, reverse, strain, torn, longest,
                                                                                   tmp_path):
    """Panel a's right edge runs up, panel b's left edge (segment 3) down: sewn without `reverse`, a's
    crossing at height k spacings meets b's at 7 - k, so the 8 stitches start sqrt(1 + (7 - 2k)^2) spacings
    long, every one past 1.2 spacings (break strain 0.2, no spread), the longest sqrt(50) x 4 mm = 28.3 mm;
    the warning says that reverse would fix it. With reverse, or a break strain of 10 (44 mm), none is: no
    warning. Sewn to b's right edge (segment 1, 10 spacings away) every stitch starts 10 spacings long,
    either way round: the warning names the edges and the panels' places. The scene is valid in every case."""
    (tmp_path / "s.toml").write_text(two_panels(seam(sb=sb, reverse=reverse, strain=strain)))
    run = subprocess.run([sys.executable, "-m", "fraytool", "check", str(tmp_path / "s.toml")],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    warnings = [x for x in run.stderr.splitlines() if x.startswith("fraytool: warning:")]
    if not torn:
        assert warnings == [], run.stderr
        return
    assert len(warnings) == 1, run.stderr
    line = warnings[0]
    assert f"[seams.0] panel 'a' segment 1 to panel 'b' segment {sb}" in line
    assert f"{torn} of 8 stitches start past their break strain" in line
    assert f"up to {longest * 4:.3g} mm, rest 4 mm" in line
    if sb == 3:
        assert "with reverse = true every stitch would start within it" in line
    else:
        assert "reverse = true" not in line and "the two edges lie apart" in line and "origin_m" in line


@pytest.mark.parametrize("grain", [0.0, 30.0, 45.0])
def test_a_seam_stitches_each_border_crossing_along_its_edge_once_at_any_grain(grain):
    """Two 28 mm squares cut by outline_m, their weave turned by `grain` (45: a bias cut), a's right edge
    sewn to b's left every yarn spacing: each of a's border crossings within a spacing of the right edge's
    line (u = 28 mm; the outline excludes crossings on it, so they lie up to a spacing inside, in a
    staircase when the weave is turned) gets one stitch, and no other crossing does."""
    def square(name, origin):
        extra = f"outline_m = [[0.0, 0.0], [0.028, 0.0], [0.028, 0.028], [0.0, 0.028]]\ngrain_deg = {grain}\n"
        return panel(name, origin, extra=extra).replace("warp_yarns = 10\nweft_yarns = 8\n", "")
    model = build_model(parse_scene(HEAD.format(frames=2) + square("a", (0.0, 0.0, 0.0))
                                    + square("b", (0.032, 0.0, 0.0)) + seam(spacing=S), "p.toml"))
    st = np.flatnonzero(model.spring_kind == STITCH)
    uv = model.crossing_plane_uv_m
    border = (model.crossing_weft_springs < 0).any(axis=1) | (model.crossing_warp_springs < 0).any(axis=1)
    along = np.flatnonzero(border & (model.crossing_panel == 0) & (0.028 - uv[:, 0] <= S + 1e-12))
    assert along.size >= 5
    assert sorted(model.spring_crossing_a[st].tolist()) == sorted(along.tolist())


def test_with_several_panels_the_first_panels_problems_name_it_cloth_0():
    """[[cloth]] twice: a problem in the first panel is in [cloth.0] (and its springs in [cloth.0.springs]), as
    one in the second is in [cloth.1] and as --set names them; a single [cloth] keeps its name."""
    from fraytool.errors import SceneError

    text = two_panels().replace('name = "a"\n', 'name = "a"\nspacng_m = 1\n', 1)
    text = text.replace("structural_n_per_m = 40.0", "structural_n_per_m = -4.0", 1)
    text = text.replace('name = "b"\n', 'name = "b"\nspacng_m = 1\n', 1)
    with pytest.raises(SceneError) as err:
        parse_scene(text, "p.toml")
    lines = str(err.value)
    assert "[cloth.0] spacng_m = 1: unknown key; did you mean spacing_m?" in lines
    assert "[cloth.0.springs] structural_n_per_m = -4.0" in lines and "[cloth.1] spacng_m = 1" in lines
    assert "[cloth] " not in lines and "[cloth.springs]" not in lines
