"""`simulate --json` reports the cloth's pieces and the strain where it is still woven, over the
whole shot and across a resume; a strain limit that did not hold is said once on stderr."""
from __future__ import annotations

import json

import numpy as np

from helpers import pulled_strip_text

from fraytool.commands.main import main
from fraytool.kinds import STRUCT_WARP, STRUCT_WEFT
from fraytool.scene import parse_scene
from fraytool.sim import Simulation
from fraytool.sim.pieces import woven_strain


def _run(tmp_path, capsys, args):
    rc = main(args)
    out, err = capsys.readouterr()
    assert rc == 0, err
    return (json.loads(out.strip().splitlines()[-1]) if out.strip() else None), err


def test_json_reports_pieces_and_woven_strain_and_resume_keeps_them(tmp_path, capsys):
    scene = tmp_path / "strip.toml"
    scene.write_text(pulled_strip_text(yarn_level=True))
    whole, err = _run(tmp_path, capsys, ["simulate", str(scene), "-o", str(tmp_path / "a"), "--json"])
    for key in ("pieces", "largest_piece_fractions", "small_pieces", "small_pieces_max", "max_woven_strain",
                "strain_cap_hits"):
        assert key in whole, key
    assert whole["broken_springs"] > 0 and whole["pieces"] >= 2  # the strip is torn through
    assert len(whole["largest_piece_fractions"]) == 2 and sum(whole["largest_piece_fractions"]) <= 1.0 + 1e-12
    # stop half way and resume: the shot figures are the same as the unbroken run's
    spec = parse_scene(scene.read_text(), str(scene))
    half = spec.time.frames // 2
    _run(tmp_path, capsys, ["simulate", str(scene), "-o", str(tmp_path / "b"), "--frames", str(half)])
    resumed, err2 = _run(tmp_path, capsys, ["simulate", str(scene), "-o", str(tmp_path / "b"), "--resume", "--json"])
    assert resumed.pop("resumed_at_frame") == half and whole.pop("resumed_at_frame") is None
    assert resumed == whole
    # the warning appears once, and only when the woven strain away from grips and bodies passed
    # limit + 0.01 under a hard limit (the strip's is hard, pulled by a grip: no warning)
    warned = whole["max_woven_strain_away"] > whole["strain_limit"] + 0.01
    assert err.count("strain limiting did not hold where the cloth is woven") == (1 if warned else 0)


def _hard_limit_sim():
    """A strip held at its left edge, pulled at its right edge; the hard strain limit (the default)."""
    return Simulation(parse_scene(pulled_strip_text(yarn_level=True), "strip.toml"))


def test_the_woven_strain_warning_names_strain_away_from_grips_only():
    """Strain past the hard limit next to a grip is the grip's doing: figure, no warning. The same strain
    in the middle of the cloth, with no grip or body near, is the limit's failure: a warning that says
    where and what to change."""
    from fraytool.sim.pieces import crossings_near_grips, woven_strain_away

    sim = _hard_limit_sim()
    m, s = sim.model, sim.state
    assert m.strain_stiffness_n_per_m == 0.0 and m.attachment_count > 0
    near = crossings_near_grips(m)
    held = m.attachment_particle[0] % m.crossing_count
    W = m.warp_yarns
    j, i = divmod(int(held), W)
    # stretch the weft spring next to the held crossing by 30 %: near the grip
    spring = int(m.weft_structural_spring[j, min(i, W - 2)])
    a, b = s.spring_particle_a[spring], s.spring_particle_b[spring]
    s.particle_position_m[b] = s.particle_position_m[a] + 1.3 * (s.particle_position_m[b] - s.particle_position_m[a])
    strain, _ = woven_strain_away(m, s, near)
    assert strain < 0.2
    sim._observe()
    assert sim.shot.max_woven_strain > 0.25 and sim.woven_strain_warning() is None
    # the same in the middle, farther than NEAR_SPACINGS from every held crossing
    free = np.flatnonzero(~near)
    c = int(free[len(free) // 2])
    spring = int(m.weft_structural_spring[c // W, min(c % W, W - 2)])
    a, b = s.spring_particle_a[spring], s.spring_particle_b[spring]
    assert not (near[m.spring_crossing_a[spring]] or near[m.spring_crossing_b[spring]])
    s.particle_position_m[b] = s.particle_position_m[a] + 1.3 * (s.particle_position_m[b] - s.particle_position_m[a])
    sim._observe()
    warning = sim.woven_strain_warning()
    assert warning is not None and "away from grips and bodies" in warning and f"spring {spring}" in warning


def test_woven_strain_is_the_largest_over_live_springs_between_woven_crossings():
    spec = parse_scene(pulled_strip_text(yarn_level=True), "strip.toml")
    sim = Simulation(spec)
    m, s = sim.model, sim.state
    W = m.warp_yarns
    x = s.particle_position_m
    # stretch one weft spring by 30 %: it is between base-level (woven) crossings
    spring = int(m.weft_structural_spring[4, 10])
    x[4 * W + 11:5 * W, 0] += 0.30 * m.spacing_m
    strain, where = woven_strain(m, s)
    assert where == spring and np.isclose(strain, 0.30)
    # once one end is a disconnected couple, that spring no longer counts
    sim.solver.tearing.split(s, [4 * W + 11])
    sim.solver.tearing.disconnect(s, 4 * W + 11)
    strain2, where2 = woven_strain(m, s)
    assert where2 != spring and strain2 < 0.30
    # against numpy over the selection, written out (the kernel is one pass that skips the others)
    structural = (m.spring_kind == STRUCT_WEFT) | (m.spring_kind == STRUCT_WARP)
    woven = ~s.crossing_yarn_level | s.couple_connected
    sel = np.flatnonzero(structural & s.spring_alive & woven[m.spring_crossing_a] & woven[m.spring_crossing_b])
    d = x[s.spring_particle_b[sel]] - x[s.spring_particle_a[sel]]
    ref = np.linalg.norm(d, axis=1) / s.spring_rest_length_m[sel] - 1.0
    assert where2 == sel[np.argmax(ref)] and np.isclose(strain2, ref.max(), rtol=0, atol=1e-15)


def test_near_a_grip_on_a_grid_narrower_than_the_reach():
    """The grid dilation that marks crossings near a grip works on a cloth narrower than its reach
    (heavy_strip_one_iteration is 2 yarns wide): every crossing of a 2 x 3 grid is within 4 steps."""
    from fraytool.sim.multires import dilate

    marked = np.zeros(6, bool)
    marked[0] = True
    assert dilate(marked, 2, 3, 4).all()
    assert dilate(marked, 2, 3, 1).tolist() == [True, True, True, True, False, False]


def test_strain_next_to_a_colliding_body_is_the_body_s_doing():
    """woven_strain_away leaves out springs within 4 spacings of a colliding body's surface (the signed
    distance of rigid contact's `surface_contact`): a spring stretched 30 % on the ball's top does not
    count, the same stretch at a far corner does."""
    from helpers import BALL, small_scene
    from fraytool.sim.pieces import woven_strain_away

    sim = Simulation(small_scene(BALL))
    m, s = sim.model, sim.state
    none = np.zeros(m.crossing_count, bool)
    W = m.warp_yarns
    for j, i, counted in ((W // 2, W // 2, False), (0, 0, True)):
        state = s.copy()
        spring = int(m.weft_structural_spring[j, i])
        a, b = state.spring_particle_a[spring], state.spring_particle_b[spring]
        x = state.particle_position_m
        x[b] = x[a] + 1.3 * (x[b] - x[a])
        strain, where = woven_strain_away(m, state, none)
        assert bool(where == spring and np.isclose(strain, 0.3)) is counted, (strain, where)
