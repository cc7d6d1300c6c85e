"""Transition to the yarn level (docs/method.md §3.4): split conservation, re-attachment, propagation."""
from __future__ import annotations

import numpy as np
import pytest

from fraytool.grid import base_yarn_points, crossing_normals
from fraytool.scene import parse_scene
from fraytool.sim.builder import build_model
from fraytool.sim.kernels.integrate import velocities_from_positions
from fraytool.kinds import BEND_WARP, BEND_WEFT, SHEAR, STRUCT_WARP, STRUCT_WEFT
from fraytool.sim.tearing import YarnTearing, topology_problems
from tearing_reference import assert_named_close, split_reference, state_dict

CONSERVE_RTOL = 1e-12
POSITION_ATOL = 1e-15  # [m]: the kernel's normal vs grid.crossing_normals, last-bit differences

SCENE = """
[scene]
name = "split"
seed = 3
[time]
step_s = 2e-4
steps_per_frame = 2
frames = 2
fps = 24
[cloth]
warp_yarns = {nx}
weft_yarns = {ny}
spacing_m = 0.004
thickness_m = 0.0006
mass_per_crossing_kg = 5e-6
origin_m = [0.0, 0.0, 0.0]
plane = "xz"
{weave}
[cloth.springs]
structural_n_per_m = 40.0
bend_n_per_m = 1.0
shear_n_per_m = 5.0
damping = 0.0
[cloth.tearing]
enabled = true
{extra}
"""


def make(nx=8, ny=6, weave='weave = "plain"', extra="", attach=""):
    spec = parse_scene(SCENE.format(nx=nx, ny=ny, weave=weave, extra=extra) + attach, "split.toml")
    model = build_model(spec)
    return model, model.state(), YarnTearing(model)


def crumple(model, state, seed=0, speed=0.6, dt=2e-4):
    """Non-flat positions and velocities of order `speed` [m/s]; returns prev positions."""
    rng = np.random.default_rng(seed)
    n = model.crossing_count
    state.particle_position_m[:n] += rng.normal(0.0, 0.3 * model.spacing_m, (n, 3))
    state.particle_position_m[n:] = state.particle_position_m[:n]
    state.particle_velocity_m_s[:n] = rng.uniform(0.5 * speed, speed, (n, 3)) * rng.choice([-1, 1], (n, 3))
    return state.particle_position_m - dt * state.particle_velocity_m_s


def cid(model, i, j):
    return j * model.warp_yarns + i


def test_split_conserves_mass_momentum_and_angular_momentum():
    model, state, tear = make()
    dt = 2e-4
    prev = crumple(model, state, dt=dt)
    c = cid(model, 3, 2)
    n = model.crossing_count
    x_old = state.particle_position_m[c].copy()
    m_old = state.particle_mass_kg[c]
    v_old = (state.particle_position_m[c] - prev[c]) / dt
    p_total = (state.particle_mass_kg[:, None] * state.particle_velocity_m_s).sum(axis=0)
    mass_total = state.particle_mass_kg.sum()

    assert tear.split(state, [c], prev) == 1
    pair = [c, n + c]
    m = state.particle_mass_kg
    assert m[c] == m[n + c] == 0.5 * m_old
    assert abs(m.sum() - mass_total) <= CONSERVE_RTOL * mass_total
    p_after = (m[:, None] * state.particle_velocity_m_s).sum(axis=0)
    assert np.abs(p_after - p_total).max() <= CONSERVE_RTOL * np.abs(p_total).max()
    # The velocity the step's post-process will compute, v = (x - x_prev) / dt, is the original one.
    v = np.zeros_like(state.particle_velocity_m_s)
    velocities_from_positions(state.particle_position_m, prev, state.particle_active, v, dt, 1e3)
    p_local = (m[pair, None] * v[pair]).sum(axis=0)
    assert np.abs(p_local - m_old * v_old).max() <= CONSERVE_RTOL * np.abs(m_old * v_old).max()
    # No angular momentum about the old position: R_warp = -R_weft, equal masses, equal velocities.
    L = sum(np.cross(state.particle_position_m[p] - x_old, m[p] * v[p]) for p in pair)
    scale = m_old * np.linalg.norm(v_old) * model.thickness_m
    assert np.abs(L).max() <= CONSERVE_RTOL * scale
    assert np.isclose(np.linalg.norm(state.particle_position_m[c] - state.particle_position_m[n + c]),
                      model.thickness_m, rtol=1e-12)
    assert topology_problems(model, state) == []


def test_split_lands_on_the_renderers_base_yarn_points():
    model, state, tear = make()
    prev = crumple(model, state, seed=4)
    n = model.crossing_count
    first = [cid(model, 2, 2), cid(model, 3, 2)]
    tear.split(state, first, prev)  # neighbours of the next one are now yarn level (centre = midpoint)
    c = cid(model, 3, 3)
    x = state.particle_position_m
    centre = np.where(state.crossing_yarn_level[:, None], 0.5 * (x[:n] + x[n:]), x[:n])
    weft_pt, warp_pt = base_yarn_points(centre, crossing_normals(centre, model.warp_yarns, model.weft_yarns),
                                        model.crossing_weft_on_top, model.thickness_m)
    tear.split(state, [c], prev)
    np.testing.assert_allclose(x[c], weft_pt[c], rtol=0, atol=POSITION_ATOL)
    np.testing.assert_allclose(x[n + c], warp_pt[c], rtol=0, atol=POSITION_ATOL)


def test_split_reattaches_structural_and_bend_springs_to_their_yarn():
    model, state, tear = make()
    c = cid(model, 4, 3)
    n = model.crossing_count
    tear.split(state, [c])
    at = (model.spring_crossing_a == c) | (model.spring_crossing_b == c)
    for kind, slot in ((STRUCT_WEFT, c), (BEND_WEFT, c), (STRUCT_WARP, n + c), (BEND_WARP, n + c)):
        springs = np.nonzero(at & (model.spring_kind == kind))[0]
        assert len(springs) == 2
        ends = np.where(model.spring_crossing_a[springs] == c, state.spring_particle_a[springs],
                        state.spring_particle_b[springs])
        assert (ends == slot).all(), kind


def test_shear_springs_duplicate_at_half_stiffness_on_their_layer():
    model, state, tear = make()
    n = model.crossing_count
    c, o = cid(model, 3, 2), cid(model, 4, 3)  # diagonal neighbours
    s = int(np.nonzero((model.spring_kind == SHEAR) & (model.spring_crossing_a == c)
                       & (model.spring_crossing_b == o))[0][0])
    t = model.spring_twin[s]
    k0 = state.spring_stiffness_n_per_m[s]
    assert not state.spring_alive[t]

    def upper(k):
        return k if model.crossing_weft_on_top[k] else n + k

    def lower(k):
        return n + k if model.crossing_weft_on_top[k] else k

    tear.split(state, [c])
    assert state.spring_alive[s] and state.spring_alive[t]
    assert state.spring_stiffness_n_per_m[s] == state.spring_stiffness_n_per_m[t] == 0.5 * k0
    # other end still base: both copies to that same base mass
    assert (state.spring_particle_a[s], state.spring_particle_b[s]) == (upper(c), o)
    assert (state.spring_particle_a[t], state.spring_particle_b[t]) == (lower(c), o)
    tear.split(state, [o])
    assert (state.spring_particle_a[s], state.spring_particle_b[s]) == (upper(c), upper(o))
    assert (state.spring_particle_a[t], state.spring_particle_b[t]) == (lower(c), lower(o))
    assert state.spring_stiffness_n_per_m[s] == 0.5 * k0  # not halved twice
    assert topology_problems(model, state) == []


@pytest.mark.parametrize("weave", ['weave = "plain"', 'weave = "twill"\ntwill = "2/2"',
                                   'weave = "table"\ntable = [[1, 1, 1, 0], [0, 1, 1, 1], [1, 0, 1, 1], [1, 1, 0, 1]]'])
def test_split_matches_numpy_reference(weave):
    model, state, tear = make(weave=weave)
    prev = crumple(model, state, seed=7)
    rng = np.random.default_rng(11)
    order = rng.permutation(model.crossing_count)[:20]
    # cut a few shear springs first so that the "cut before any split" branch is exercised too
    tear.cut(state, int(model.weft_structural_spring[1, 1]))
    ref = state_dict(state, prev)
    for c in order:
        ref = split_reference(model, ref, int(c))
        tear.split(state, [int(c)], prev)
        got = state_dict(state, prev)
        assert_named_close(ref, got, [k for k in ref if k not in ("particle_position_m", "prev_position_m")])
        assert_named_close(ref, got, ["particle_position_m", "prev_position_m"], atol=POSITION_ATOL)
    assert topology_problems(model, state) == []


def _split_after_transition(model, spring):
    """(i, j) of the crossings that split when `spring` is over-strained on an untorn cloth."""
    state = model.state()
    tear = YarnTearing(model)
    tear.transition(state, spring)
    W = model.warp_yarns
    return sorted((int(c % W), int(c // W)) for c in np.nonzero(state.crossing_yarn_level)[0])


def test_propagation_plain_weave_splits_only_the_two_ends():
    model, _, _ = make(nx=8, ny=6)
    assert _split_after_transition(model, model.weft_structural_spring[2, 3]) == [(3, 2), (4, 2)]
    assert _split_after_transition(model, model.warp_structural_spring[5, 1]) == [(5, 1), (5, 2)]


def test_propagation_twill_2_2_splits_the_float_partners():
    # 2/2 twill: weft j is on top of warp i where (i - j) % 4 < 2.
    # Row j = 1 reads F T T F F T T F: the spring (2,1)-(3,1) joins floats {1, 2} and {3, 4}.
    model, _, _ = make(nx=8, ny=6, weave='weave = "twill"\ntwill = "2/2"')
    assert [bool(model.crossing_weft_on_top[cid(model, i, 1)]) for i in range(8)] == \
        [False, True, True, False, False, True, True, False]
    assert _split_after_transition(model, model.weft_structural_spring[1, 2]) == [(1, 1), (2, 1), (3, 1), (4, 1)]
    # inside one float (1,1)-(2,1): just that float
    assert _split_after_transition(model, model.weft_structural_spring[1, 1]) == [(1, 1), (2, 1)]
    # at the border the walk stops at the cloth edge: (0,1) is F and (1,1) is T
    assert _split_after_transition(model, model.weft_structural_spring[1, 0]) == [(0, 1), (1, 1), (2, 1)]
    # warp 2 reads down j: F T T F F T; spring (2,2)-(2,3)
    assert _split_after_transition(model, model.warp_structural_spring[2, 2]) == [(2, 1), (2, 2), (2, 3), (2, 4)]


def test_propagation_table_weave_follows_long_floats():
    # 3/1 table: each weft floats over 3 warps; row 0 reads T T T F T T T F
    table = 'weave = "table"\ntable = [[1, 1, 1, 0], [0, 1, 1, 1], [1, 0, 1, 1], [1, 1, 0, 1]]'
    model, _, _ = make(nx=8, ny=4, weave=table)
    assert _split_after_transition(model, model.weft_structural_spring[0, 2]) == [(0, 0), (1, 0), (2, 0), (3, 0)]
    assert _split_after_transition(model, model.weft_structural_spring[0, 0]) == [(0, 0), (1, 0), (2, 0)]


def test_propagation_stops_at_a_cut_yarn_and_at_held_crossings():
    model, state, tear = make(nx=8, ny=6, weave='weave = "twill"\ntwill = "2/2"')
    tear.cut(state, int(model.weft_structural_spring[1, 0]))  # cut between (0,1) and (1,1)
    tear.transition(state, int(model.weft_structural_spring[1, 1]))
    assert sorted(np.nonzero(state.crossing_yarn_level)[0].tolist()) == [cid(model, 1, 1), cid(model, 2, 1)]
    held = """
[[bodies]]
name = "pin"
shape = "sphere"
radius_m = 0.001
position_m = [0.0, 0.0, 0.0]
collide = false
[[attachments]]
body = "pin"
warp_range = [1, 1]
weft_range = [1, 1]
"""
    model, state, tear = make(nx=8, ny=6, weave='weave = "twill"\ntwill = "2/2"', attach=held)
    tear.transition(state, int(model.weft_structural_spring[1, 1]))  # (1,1) is held
    assert sorted(np.nonzero(state.crossing_yarn_level)[0].tolist()) == [cid(model, 2, 1)]
    assert topology_problems(model, state) == []


def test_held_crossings_never_split():
    model, state, tear = make(attach="""
[[bodies]]
name = "pin"
shape = "sphere"
radius_m = 0.001
position_m = [0.0, 0.0, 0.0]
collide = false
[[attachments]]
body = "pin"
corner = "bottom_left"
corner_size = 2
""")
    held = model.attachment_particle
    assert tear.split(state, held) == 0
    assert not state.crossing_yarn_level[held].any()
