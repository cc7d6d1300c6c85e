"""Cuts (§3.4 random break limits, §4.1) and the fray metric."""
from __future__ import annotations

import numpy as np
import pytest

from fraytool.scene import parse_scene
from fraytool.sim.builder import build_model
from fraytool.kinds import BEND_WARP, BEND_WEFT, SHEAR, SHEAR_TWIN, STRUCT_WARP, STRUCT_WEFT
from fraytool.sim.solver import SolverExplicitPBD
from fraytool.sim.tearing import YarnTearing, fray_lengths, topology_problems
from tearing_reference import free_end_lengths_reference, state_dict

SCENE = """
[scene]
name = "cut"
seed = {seed}
[time]
step_s = 2e-4
steps_per_frame = 1
frames = 2
fps = 24
[cloth]
warp_yarns = 8
weft_yarns = 6
spacing_m = 0.004
thickness_m = 0.0006
mass_per_crossing_kg = 5e-6
origin_m = [0.0, 0.0, 0.0]
plane = "xy"
weave = "plain"
[cloth.springs]
structural_n_per_m = 40.0
bend_n_per_m = 1.0
shear_n_per_m = 5.0
damping = 0.0
[cloth.tearing]
enabled = true
yarn_level = {yarn_level}
transition_strain = 0.12
break_strain = 0.2
break_strain_spread = {spread}
ineffective_length = {ineffective}
"""


def make(seed=1, yarn_level="true", spread=0.03, ineffective=1, warp_yarns=8):
    """A small cloth; ineffective_length 1 (any spring may break) unless a test is about that rule."""
    text = SCENE.format(seed=seed, yarn_level=yarn_level, spread=spread, ineffective=ineffective)
    text = text.replace("warp_yarns = 8", f"warp_yarns = {warp_yarns}")
    model = build_model(parse_scene(text, "cut.toml"))
    return model, model.state(), YarnTearing(model)


def test_cutting_a_yarn_cuts_its_bend_springs_and_the_shear_springs_of_both_cells():
    model, state, tear = make()
    W = model.warp_yarns
    s = int(model.weft_structural_spring[2, 3])  # joins (3,2)-(4,2); cells (3,1) below and (3,2) above
    tear.split(state, [2 * W + 3, 3 * W + 4])  # some shear twins are born
    alive_before = state.spring_alive.copy()
    cut = tear.cut(state, s)
    dead = ~state.spring_alive
    bends = np.nonzero(dead & (model.spring_kind == BEND_WEFT))[0]
    assert sorted((int(model.spring_crossing_a[b] % W), int(model.spring_crossing_a[b] // W)) for b in bends) == \
        [(2, 2), (3, 2)]  # (2,2)-(4,2) and (3,2)-(5,2) span the cut
    shear = np.nonzero(dead & (model.spring_kind == SHEAR))[0]
    cells = {(int(min(model.spring_crossing_a[k] % W, model.spring_crossing_b[k] % W)),
              int(min(model.spring_crossing_a[k] // W, model.spring_crossing_b[k] // W))) for k in shear}
    assert cells == {(3, 1), (3, 2)} and len(shear) == 4
    assert not state.spring_alive[model.spring_twin[shear]].any()
    twins_cut = int(((model.spring_kind == SHEAR_TWIN) & dead & alive_before).sum())
    # twins were born on the diagonals touching a split crossing: (3,2)-(4,3) and (4,1)-(3,2)
    assert twins_cut == 2
    assert cut == 1 + 2 + 4 + twins_cut
    assert (np.nonzero(state.spring_broken)[0] == [s]).all()  # only the yarn is "broken"
    assert not (dead & (model.spring_kind == BEND_WARP)).any()
    assert topology_problems(model, state) == []


def test_springs_over_their_own_break_strain_are_cut_and_only_those():
    # base-only, so that no split adds its crimp to the strain: the threshold is exact
    model, _, tear = make(yarn_level="false")
    W, n = model.warp_yarns, model.crossing_count
    s = int(model.warp_structural_spring[4, 2])  # joins (4,2)-(4,3)
    limit = model.spring_break_strain[s]
    top = np.arange(n) // W >= 3
    row = model.warp_structural_spring[:, 2]  # every warp spring between rows 2 and 3
    for factor, expect in ((0.999, False), (1.001, True)):
        state = model.state()
        x = state.particle_position_m
        strain = factor * (1 + limit) - 1
        x[:n][top, 1] += strain * model.spacing_m  # rows 3.. move up: row-2/3 warp springs stretch
        tear(state, x.copy(), 2e-4)
        assert bool(state.spring_broken[s]) == expect, factor
        assert (state.spring_broken[row] == (model.spring_break_strain[row] < strain)).all()
        assert state.spring_broken.sum() == state.spring_broken[row].sum()


def test_break_strains_are_drawn_once_from_the_seed():
    a, _, _ = make(seed=5)
    b, _, _ = make(seed=5)
    c, _, _ = make(seed=6)
    assert (a.spring_break_strain == b.spring_break_strain).all()
    assert (a.spring_break_strain != c.spring_break_strain).mean() > 0.99
    base_only, _, _ = make(seed=5, yarn_level="false")  # the comparison run tears the same cloth
    assert (base_only.spring_break_strain == a.spring_break_strain).all()
    zero, _, _ = make(spread=0.0)
    assert (zero.spring_break_strain == 0.2).all()
    wide, _, _ = make(spread=0.03)
    assert abs(wide.spring_break_strain.std() - 0.03) < 0.005  # the spread is the scene's
    assert wide.spring_break_strain.min() > 0.12  # floored above the transition strain


def test_base_only_tearing_has_no_couples_and_no_contact_pass():
    model, state, _ = make(yarn_level="false")
    solver = SolverExplicitPBD(model)
    assert solver.tearing is not None and "YarnContactStage" not in [type(s).__name__ for s in solver.stages]
    x = state.particle_position_m
    W = model.warp_yarns
    x[:model.crossing_count][np.arange(model.crossing_count) // W >= 3, 1] += 0.5 * model.spacing_m  # 50 % strain
    solver.tearing(state, x.copy(), 2e-4)
    assert state.spring_broken.sum() == W  # the whole row of warp springs between rows 2 and 3
    assert not state.crossing_yarn_level.any() and not state.particle_active[model.crossing_count:].any()
    lengths, _ = fray_lengths(model, solver.tearing.topology, state)
    assert len(lengths) == 2 * W and (lengths == 0).all()  # a clean edge
    assert topology_problems(model, state) == []


def test_fray_free_length_is_the_yarn_from_the_cut_to_the_first_woven_crossing():
    model, state, tear = make()
    W, L = model.warp_yarns, model.spacing_m
    row = [2 * W + i for i in range(8)]
    tear.split(state, row[2:7])                       # (2..6, 2) yarn level
    tear.cut(state, int(model.weft_structural_spring[2, 4]))  # weft 2 cut between i = 4 and 5
    tear.disconnect(state, row[4])
    tear.disconnect(state, row[3])                    # left end: 4, 3 parted; 2 still woven
    tear.disconnect(state, row[6])                    # right end: 5 woven -> 0
    lengths, crossings = fray_lengths(model, tear.topology, state)
    assert crossings.tolist() == [row[4], row[5]]
    x = state.particle_position_m
    expected = np.linalg.norm(x[row[4]] - x[row[3]]) + np.linalg.norm(x[row[3]] - x[row[2]])
    assert lengths[0] == pytest.approx(expected, rel=1e-12) and lengths[0] == pytest.approx(2 * L, rel=0.05)
    assert lengths[1] == 0.0
    summary = tear.summary(state)
    assert summary["fray_cut_ends"] == 2 and summary["fray_free_end_count"] == 1
    assert summary["fray_max_free_end_m"] == pytest.approx(expected)
    assert summary["broken_springs"] == 1 and summary["yarn_level_masses"] == 10
    assert summary["connected_couples"] == 2 and summary["disconnected_couples"] == 3


def test_fray_metric_matches_reference_on_random_tears():
    rng = np.random.default_rng(3)
    model, state, tear = make()
    structural = np.nonzero((model.spring_kind == STRUCT_WEFT) | (model.spring_kind == STRUCT_WARP))[0]
    tear.split(state, range(model.crossing_count))
    state.particle_position_m += rng.normal(0.0, 0.2 * model.spacing_m, state.particle_position_m.shape)
    for s in rng.choice(structural, 12, replace=False):
        tear.cut(state, int(s))
    for c in rng.choice(model.crossing_count, 25, replace=False):
        tear.disconnect(state, int(c))
    lengths, _ = fray_lengths(model, tear.topology, state)
    ref = free_end_lengths_reference(model, state_dict(state))
    np.testing.assert_allclose(lengths, ref, rtol=1e-12, atol=0)
    assert (lengths > 0).sum() >= 3


def test_springs_are_cut_one_by_one_per_yarn():
    """Two springs of one yarn over their limits in the same step: only the one furthest over
    breaks (the yarn snaps once and relaxes); a spring of another yarn breaks in the same step."""
    model, _, tear = make(yarn_level="false", spread=0.0)
    W, n = model.warp_yarns, model.crossing_count
    state = model.state()
    x = state.particle_position_m
    s1 = int(model.weft_structural_spring[2, 1])  # (1,2)-(2,2)
    s2 = int(model.weft_structural_spring[2, 5])  # (5,2)-(6,2), same weft yarn
    other = int(model.weft_structural_spring[4, 3])  # another weft yarn
    cols = np.arange(n) % W
    rows = np.arange(n) // W
    row2 = rows == 2
    x[:n][row2 & (cols >= 2), 0] += 0.30 * model.spacing_m  # s1 30 % over rest
    x[:n][row2 & (cols >= 6), 0] += 0.25 * model.spacing_m  # s2 25 %
    x[:n][(rows == 4) & (cols >= 4), 0] += 0.30 * model.spacing_m
    tear(state, x.copy(), 2e-4)
    assert state.spring_broken[s1] and not state.spring_broken[s2]
    assert state.spring_broken[other]
    assert state.spring_broken.sum() == 2


def _stretch_weft(model, x, row, col, strain):
    """Move the crossings of weft yarn `row` right of column `col` by `strain` x spacing along x: the
    spring (col-1, row)-(col, row) takes that strain, the others keep theirs."""
    n, W = model.crossing_count, model.warp_yarns
    sel = (np.arange(n) // W == row) & (np.arange(n) % W >= col)
    x[:n][sel, 0] += strain * model.spacing_m


def test_no_break_leaves_a_yarn_piece_shorter_than_the_ineffective_length():
    """12 crossings on a weft yarn, ineffective length 5: a spring breaks only with at least 5
    crossings of its yarn on each side up to the border or an earlier cut."""
    model, state, tear = make(yarn_level="false", spread=0.0, ineffective=5, warp_yarns=12)
    x = state.particle_position_m
    near_border = int(model.weft_structural_spring[2, 1])  # (1,2)-(2,2): 2 crossings to its left
    middle = int(model.weft_structural_spring[2, 5])  # (5,2)-(6,2): 6 and 6
    _stretch_weft(model, x, 2, 2, 0.5)
    tear(state, x.copy(), 2e-4)
    assert not state.spring_broken[near_border]  # 50 % over rest, but a 2-crossing piece would be left
    _stretch_weft(model, x, 2, 6, 0.5)
    tear(state, x.copy(), 2e-4)
    assert state.spring_broken[middle]
    assert state.spring_broken.sum() == 1
    # next to the cut: (7,2)-(8,2) would leave crossings 6..7 (2) on the cut's side
    beside_cut = int(model.weft_structural_spring[2, 7])
    _stretch_weft(model, x, 2, 8, 0.5)
    tear(state, x.copy(), 2e-4)
    assert not state.spring_broken[beside_cut] and state.spring_broken.sum() == 1
    # with the rule off (1), the same stretch breaks it
    model1, state1, tear1 = make(yarn_level="false", spread=0.0, ineffective=1, warp_yarns=12)
    _stretch_weft(model1, state1.particle_position_m, 2, 2, 0.5)
    tear1(state1, state1.particle_position_m.copy(), 2e-4)
    assert state1.spring_broken[near_border]


def test_a_yarn_sliding_free_towards_a_cut_does_not_break_but_an_anchored_one_does():
    """Yarn-level crossings (4,2)..(6,2) follow a cut at (3,2)-(4,2): that run reaches a loose end and
    slides, so its springs (and the one joining it to the weave at (7,2)) hold no tension; springs
    between base-level crossings beyond still break. (No transitions in this step: yarn_level off,
    the couples are split by hand.)"""
    model, state, tear = make(yarn_level="false", spread=0.0, ineffective=1, warp_yarns=12)
    W = model.warp_yarns
    tear.cut(state, int(model.weft_structural_spring[2, 3]))
    tear.split(state, [2 * W + 4, 2 * W + 5, 2 * W + 6])
    x = state.particle_position_m
    in_run = int(model.weft_structural_spring[2, 5])  # (5,2)-(6,2)
    to_anchor = int(model.weft_structural_spring[2, 6])  # (6,2)-(7,2)
    anchored = int(model.weft_structural_spring[2, 9])  # (9,2)-(10,2), base level
    n = model.crossing_count
    strains = np.zeros(W - 1)
    strains[[5, 6, 9]] = 0.5  # in_run, to_anchor, anchored: each 50 % over rest
    ends = np.concatenate([[0.0], np.cumsum(model.spacing_m * (1.0 + strains))])
    for i in range(W):
        c = 2 * W + i
        shift = x[c, 0] - x[2 * W, 0] - ends[i]
        x[c, 0] -= shift
        if state.crossing_yarn_level[c]:
            x[n + c, 0] -= shift  # the couple's warp mass moves with it
    tear(state, x.copy(), 2e-4)
    assert not state.spring_broken[in_run] and not state.spring_broken[to_anchor]
    assert state.spring_broken[anchored]


def test_a_piece_of_exactly_the_ineffective_length_may_be_left():
    """The boundary of the rule above: with ineffective length 5, the spring (4,2)-(5,2) leaves exactly 5
    crossings (0..4) on its left: it breaks; (3,2)-(4,2), leaving 4, does not. Catches the rule off by
    one (a piece of exactly the length refused, or one crossing short accepted)."""
    model, state, tear = make(yarn_level="false", spread=0.0, ineffective=5, warp_yarns=12)
    x = state.particle_position_m
    four_left = int(model.weft_structural_spring[2, 3])
    _stretch_weft(model, x, 2, 4, 0.5)
    tear(state, x.copy(), 2e-4)
    assert not state.spring_broken.any()
    model, state, tear = make(yarn_level="false", spread=0.0, ineffective=5, warp_yarns=12)
    x = state.particle_position_m
    five_left = int(model.weft_structural_spring[2, 4])
    _stretch_weft(model, x, 2, 5, 0.5)
    tear(state, x.copy(), 2e-4)
    assert state.spring_broken[five_left] and state.spring_broken.sum() == 1
    assert four_left != five_left


def test_first_over_length_finds_the_first_live_spring_past_its_limit():
    """The per-step pre-scan (fraytool.sim.tearing.cut.first_over_length) against a NumPy reference, on random
    strains with some springs dead: the first live spring, in list order, longer than (1 + limit) x its rest length."""
    from fraytool.sim.tearing.cut import first_over_length
    rng = np.random.default_rng(3)
    p, s = 40, 60
    x = rng.normal(size=(p, 3))
    a = rng.integers(0, p, s).astype(np.int32)
    b = rng.integers(0, p, s).astype(np.int32)
    length = np.linalg.norm(x[b] - x[a], axis=1)
    for trial in range(50):
        limit = rng.uniform(0.0, 0.3, s)
        rest = length / (1.0 + limit) * rng.uniform(0.97, 1.0, s)  # most within their limit, a few past it
        rest[rng.random(s) < 0.05] *= 0.5
        alive = rng.random(s) > 0.2
        listed = rng.permutation(s)[: s - 10].astype(np.int32)
        over = alive[listed] & (length[listed] > (1.0 + limit[listed]) * rest[listed] * (1 + 1e-12))
        within = alive[listed] & (length[listed] < (1.0 + limit[listed]) * rest[listed] * (1 - 1e-12))
        k = first_over_length(listed, limit, rest, a, b, alive, x)
        if k < 0:
            assert not over.any()
        else:
            assert alive[listed[k]] and not within[k], trial
            assert not over[:k].any(), trial


def test_a_cut_scan_started_at_the_first_spring_over_its_limit_cuts_what_a_whole_scan_does():
    """cut_overstrained started at first_over_length's index (as YarnTearing calls it) breaks the same springs as
    a scan of every spring, on a cloth stretched so that several yarns are over their limits."""
    from fraytool.sim.tearing.cut import cut_overstrained, first_over_length
    from fraytool.sim.tearing.groups import state_groups
    model, _, tear = make(yarn_level="false")
    W, n = model.warp_yarns, model.crossing_count
    top = np.arange(n) // W >= 3
    results = []
    for start in ("whole", "first"):
        state = model.state()
        x = state.particle_position_m
        x[:n][top, 1] += 0.215 * model.spacing_m  # around the break strains: some warp springs of row 2/3 over
        x[:n, 0] += 0.0005 * np.sin(np.arange(n))
        tear(state, x.copy(), 2e-4)  # sets up the free-run and fragment scans of this topology
        state = model.state()
        x = state.particle_position_m
        x[:n][top, 1] += 0.215 * model.spacing_m
        x[:n, 0] += 0.0005 * np.sin(np.arange(n))
        particles, _, springs = state_groups(state)
        m = tear.model_scan
        first = first_over_length(m.structural_springs, m.spring_break_strain, state.spring_rest_length_m,
                                  state.spring_particle_a, state.spring_particle_b, state.spring_alive, x)
        assert first > 0  # some springs before it are within their limits
        k = 0 if start == "whole" else first
        cut_overstrained(m, particles, springs, tear._weft_free, tear._warp_free, tear._fragment_left,
                         tear._fragment_right, k)
        results.append(state.spring_broken.copy())
    assert results[0].sum() >= 2
    assert (results[0] == results[1]).all()


def test_the_cut_rule_reads_scans_of_a_topology_changed_in_a_step_with_nothing_to_cut():
    """The free-run and fragment scans run only when the cut pass has a spring over its limit: after a cut made in
    a step with nothing else over its limit (whose tearing pass ran no scan), a later stretch beside that cut is
    judged on the scans of the cloth as it is now, so the ineffective-length rule holds the spring next to it."""
    model, state, tear = make(yarn_level="false", spread=0.0, ineffective=5, warp_yarns=12)
    x = state.particle_position_m
    tear(state, x.copy(), 2e-4)  # nothing over its limit
    tear.cut(state, int(model.weft_structural_spring[2, 3]))  # (3,2)-(4,2) cut: a new topology
    tear(state, x.copy(), 2e-4)  # nothing over its limit again: no scan needed in this step
    near_cut = int(model.weft_structural_spring[2, 5])  # (5,2)-(6,2): 2 crossings on the cut's side, 6 on the other
    _stretch_weft(model, x, 2, 6, 0.5)
    tear(state, x.copy(), 2e-4)
    assert not state.spring_broken[near_cut]
    # the same stretch without the cut breaks it: the rule, not the strain, held it
    _, fresh, fresh_tear = make(yarn_level="false", spread=0.0, ineffective=5, warp_yarns=12)
    _stretch_weft(model, fresh.particle_position_m, 2, 6, 0.5)
    fresh_tear(fresh, fresh.particle_position_m.copy(), 2e-4)
    assert fresh.spring_broken[near_cut]
