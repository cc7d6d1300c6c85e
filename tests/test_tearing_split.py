"""Transition to the yarn level (docs/method.md §3.4): split conservation, re-attachment, propagation."""
from __future__ import annotations

import numpy as np
from fraytool.sim.kernels.work_split import all_slots
import pytest

from fraytool.grid import base_yarn_points, crossing_normals
from fraytool.scene import parse_scene
from fraytool.sim.builder import build_model
from fraytool.sim.kernels.integrate import velocities_from_positions
from fraytool.kinds import BEND_WARP, BEND_WEFT, SHEAR, STRUCT_WARP, STRUCT_WEFT
from fraytool.sim.tearing import YarnTearing, topology_problems
from tearing_reference import assert_named_close, propagation_reference, split_reference, state_dict

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
    velocities_from_positions(*all_slots(len(v)), state.particle_position_m, prev, state.particle_active, v, dt, 1e3)
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


EXCLUSIVE = 'propagation = "exclusive"'
TWILL_2_2 = 'weave = "twill"\ntwill = "2/2"'
TABLE_3_1 = 'weave = "table"\ntable = [[1, 1, 1, 0], [0, 1, 1, 1], [1, 0, 1, 1], [1, 1, 0, 1]]'
PIN = """
[[bodies]]
name = "pin"
shape = "sphere"
radius_m = 0.001
position_m = [0.0, 0.0, 0.0]
collide = false
[[attachments]]
body = "pin"
warp_range = [{i}, {i}]
weft_range = [{j}, {j}]
"""


def _weft_row(model, j):
    return "".join("T" if model.crossing_weft_on_top[cid(model, i, j)] else "F" for i in range(model.warp_yarns))


def _warp_column(model, i):
    return "".join("T" if model.crossing_weft_on_top[cid(model, i, j)] else "F" for j in range(model.weft_yarns))


def test_propagation_reading_comes_from_the_scene_key():
    assert make()[0].propagation_inclusive  # the paper's reading is the default
    assert not make(extra=EXCLUSIVE)[0].propagation_inclusive
    assert make(extra='propagation = "inclusive"')[0].propagation_inclusive


def test_propagation_plain_weave_inclusive_splits_the_ends_and_the_next_crossing_beyond_each():
    model, _, _ = make(nx=8, ny=6)
    assert _weft_row(model, 2) == "TFTFTFTF"
    # weft spring (3,2)-(4,2): i = 2, 3, 4, 5
    assert _split_after_transition(model, model.weft_structural_spring[2, 3]) == [(2, 2), (3, 2), (4, 2), (5, 2)]
    # warp spring (5,1)-(5,2): j = 0, 1, 2, 3
    assert _split_after_transition(model, model.warp_structural_spring[5, 1]) == [(5, 0), (5, 1), (5, 2), (5, 3)]
    # at the border there is no crossing beyond the outer end: 3 crossings
    assert _split_after_transition(model, model.weft_structural_spring[2, 0]) == [(0, 2), (1, 2), (2, 2)]
    assert _split_after_transition(model, model.weft_structural_spring[2, 6]) == [(5, 2), (6, 2), (7, 2)]
    assert _split_after_transition(model, model.warp_structural_spring[5, 4]) == [(5, 3), (5, 4), (5, 5)]


def test_propagation_plain_weave_exclusive_splits_only_the_two_ends():
    model, _, _ = make(nx=8, ny=6, extra=EXCLUSIVE)
    assert _split_after_transition(model, model.weft_structural_spring[2, 3]) == [(3, 2), (4, 2)]
    assert _split_after_transition(model, model.warp_structural_spring[5, 1]) == [(5, 1), (5, 2)]
    assert _split_after_transition(model, model.weft_structural_spring[2, 0]) == [(0, 2), (1, 2)]


@pytest.mark.parametrize("inclusive", [True, False])
def test_propagation_twill_2_2(inclusive):
    # 2/2 twill: weft j is on top of warp i where (i - j) % 4 < 2.
    model, _, _ = make(nx=12, ny=12, weave=TWILL_2_2, extra="" if inclusive else EXCLUSIVE)
    assert _weft_row(model, 1) == "FTTFFTTFFTTF"
    assert _warp_column(model, 2) == "FTTFFTTFFTTF"
    weft = model.weft_structural_spring
    warp = model.warp_structural_spring
    if inclusive:
        # (6,1)-(7,1) joins the floats {5, 6} (T) and {7, 8} (F): both floats, plus the first
        # crossing of the next float on each side, 4 (F) and 9 (T)
        assert _split_after_transition(model, weft[1, 6]) == [(i, 1) for i in range(4, 10)]
        # (5,1)-(6,1) inside the float {5, 6}: the float, plus 4 and 7 where the weave flips
        assert _split_after_transition(model, weft[1, 5]) == [(i, 1) for i in range(4, 8)]
        # (0,1)-(1,1) at the border: 0 | 1, 2 (T) | 3 (F)
        assert _split_after_transition(model, weft[1, 0]) == [(0, 1), (1, 1), (2, 1), (3, 1)]
        # the same along warp 2: (2,6)-(2,7) between floats, (2,5)-(2,6) inside one
        assert _split_after_transition(model, warp[2, 6]) == [(2, j) for j in range(4, 10)]
        assert _split_after_transition(model, warp[2, 5]) == [(2, j) for j in range(4, 8)]
    else:
        # only whole floats: {5, 6} + {7, 8}; {5, 6}; {0} + {1, 2}
        assert _split_after_transition(model, weft[1, 6]) == [(i, 1) for i in range(5, 9)]
        assert _split_after_transition(model, weft[1, 5]) == [(5, 1), (6, 1)]
        assert _split_after_transition(model, weft[1, 0]) == [(0, 1), (1, 1), (2, 1)]
        assert _split_after_transition(model, warp[2, 6]) == [(2, j) for j in range(5, 9)]
        assert _split_after_transition(model, warp[2, 5]) == [(2, 5), (2, 6)]


@pytest.mark.parametrize("inclusive", [True, False])
def test_propagation_table_weave_follows_long_floats(inclusive):
    model, _, _ = make(nx=8, ny=4, weave=TABLE_3_1, extra="" if inclusive else EXCLUSIVE)
    assert _weft_row(model, 0) == "TTTFTTTF"  # each weft floats over 3 warps
    last = 4 if inclusive else 3
    # (2,0)-(3,0): the float {0, 1, 2} (border), {3}, and 4 where the weave flips back (inclusive)
    assert _split_after_transition(model, model.weft_structural_spring[0, 2]) == [(i, 0) for i in range(last + 1)]
    # (0,0)-(1,0) inside the float: the float, and 3 where the weave flips (inclusive)
    assert _split_after_transition(model, model.weft_structural_spring[0, 0]) == [(i, 0) for i in range(last)]


@pytest.mark.parametrize("inclusive", [True, False])
def test_propagation_stops_at_a_cut_yarn_and_at_held_crossings(inclusive):
    extra = "" if inclusive else EXCLUSIVE
    # row 1 reads F T T F F T T F; the spring (1,1)-(2,1) lies inside the float {1, 2}, and the
    # inclusive walk from (2,1) ends at (3,1), where the weave flips
    model, state, tear = make(nx=8, ny=6, weave=TWILL_2_2, extra=extra)
    assert _weft_row(model, 1) == "FTTFFTTF"
    flip = [cid(model, 3, 1)] if inclusive else []
    tear.cut(state, int(model.weft_structural_spring[1, 0]))  # cut between (0,1) and (1,1)
    tear.transition(state, int(model.weft_structural_spring[1, 1]))
    assert sorted(np.nonzero(state.crossing_yarn_level)[0].tolist()) == [cid(model, 1, 1), cid(model, 2, 1)] + flip
    # an end crossing held: it does not split and does not walk
    model, state, tear = make(nx=8, ny=6, weave=TWILL_2_2, extra=extra, attach=PIN.format(i=1, j=1))
    tear.transition(state, int(model.weft_structural_spring[1, 1]))
    assert sorted(np.nonzero(state.crossing_yarn_level)[0].tolist()) == [cid(model, 2, 1)] + flip
    assert topology_problems(model, state) == []
    # a held crossing where the weave flips (0,1): the walk stops before it, even inclusive
    model, state, tear = make(nx=8, ny=6, weave=TWILL_2_2, extra=extra, attach=PIN.format(i=0, j=1))
    tear.transition(state, int(model.weft_structural_spring[1, 1]))
    assert sorted(np.nonzero(state.crossing_yarn_level)[0].tolist()) == [cid(model, 1, 1), cid(model, 2, 1)] + flip
    assert topology_problems(model, state) == []


@pytest.mark.parametrize("inclusive", [True, False])
@pytest.mark.parametrize("weave", ['weave = "plain"', TWILL_2_2, 'weave = "twill"\ntwill = "2/1"',
                                   'weave = "satin"', TABLE_3_1])
def test_propagation_matches_numpy_reference_for_every_spring(weave, inclusive):
    """Every live structural spring of a cloth with a cut weft, a cut warp and a held crossing."""
    model, _, tear = make(nx=9, ny=7, weave=weave, extra="" if inclusive else EXCLUSIVE,
                          attach=PIN.format(i=6, j=4))
    held = model.attachment_particle.tolist()
    cuts = [int(model.weft_structural_spring[2, 4]), int(model.warp_structural_spring[3, 2])]
    for s in np.nonzero((model.spring_kind == STRUCT_WEFT) | (model.spring_kind == STRUCT_WARP))[0]:
        state = model.state()
        for cut in cuts:
            tear.cut(state, cut)
        if not state.spring_alive[s]:
            continue
        expected = propagation_reference(model, int(s), state.spring_alive, held, inclusive)
        count = tear.transition(state, int(s))
        got = set(np.nonzero(state.crossing_yarn_level)[0].tolist())
        assert got == expected, (int(s), sorted(expected), sorted(got))
        assert count == len(expected)


@pytest.mark.parametrize("inclusive", [True, False])
def test_transition_with_propagation_conserves_mass_and_momentum(inclusive):
    model, state, tear = make(nx=12, ny=8, weave=TWILL_2_2, extra="" if inclusive else EXCLUSIVE)
    dt = 2e-4
    prev = crumple(model, state, seed=5, dt=dt)
    m0 = state.particle_mass_kg.copy()
    v0 = (state.particle_position_m - prev) / dt
    mass_total = m0.sum()
    p_total = (m0[:, None] * v0).sum(axis=0)
    count = tear.transition(state, int(model.weft_structural_spring[1, 6]), prev)
    assert count == (6 if inclusive else 4)
    m = state.particle_mass_kg
    assert abs(m.sum() - mass_total) <= CONSERVE_RTOL * mass_total
    v = np.zeros_like(state.particle_velocity_m_s)
    velocities_from_positions(*all_slots(len(v)), state.particle_position_m, prev, state.particle_active, v, dt, 1e3)
    p_after = (m[:, None] * v).sum(axis=0)
    assert np.abs(p_after - p_total).max() <= CONSERVE_RTOL * np.abs(m0[:, None] * v0).sum()
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


@pytest.mark.parametrize("weave", ['weave = "plain"', 'weave = "twill"'])
def test_a_split_leaves_every_springs_strain_as_it_was(weave):
    """The couple's masses move ±T/2 along the normal; the split rescales the rest lengths of the
    springs at the crossing so that no spring's strain changes (to 1e-12), whatever the order of the
    splits (shear twins born at the first split of either end, moved at the second)."""
    model, state, tear = make(nx=9, ny=7, weave=weave)
    rng = np.random.default_rng(4)
    x = state.particle_position_m
    x[:model.crossing_count] += rng.normal(scale=0.15 * model.spacing_m, size=(model.crossing_count, 3))
    x[model.crossing_count:] = x[:model.crossing_count]

    def strains():
        d = x[state.spring_particle_b] - x[state.spring_particle_a]
        return np.linalg.norm(d, axis=1) / state.spring_rest_length_m - 1.0

    order = rng.permutation(model.crossing_count)[:40]
    moved = 0.0
    for c in order:
        before, alive = strains(), state.spring_alive.copy()
        length_before = np.linalg.norm(x[state.spring_particle_b] - x[state.spring_particle_a], axis=1)
        tear.split(state, [int(c)])
        after = strains()
        kept = alive & state.spring_alive  # springs alive before and after (a twin born now is new)
        assert np.abs(after[kept] - before[kept]).max() <= 1e-12
        born = state.spring_alive & ~alive
        twins_of = {int(model.spring_twin[t]): int(t) for t in np.flatnonzero(born)}
        for s, t in twins_of.items():  # a twin starts with its original's strain
            assert abs(after[t] - before[s]) <= 1e-12
        moved = max(moved, np.abs(np.linalg.norm(x[state.spring_particle_b] - x[state.spring_particle_a], axis=1)
                                  - length_before)[kept].max())
    assert moved > 0.1 * model.thickness_m  # the masses did move: the lengths changed, the strains did not


def test_settle_places_new_couples_outside_bodies_and_keeps_every_velocity():
    # A ball touching the cloth from below at crossing (3, 2): the split puts the lower mass T/2
    # below the cloth, inside the ball. settle() moves it out and brings the couple's pairs to about
    # T apart, and moves the previous positions with the masses, so no velocity changes (pushed out
    # by the next collision pass instead, the offset would become a velocity offset / dt).
    # The ball wins over the contact where they disagree: the couple ends slightly open.
    R, T = 0.01, 0.0006
    c_pos = np.array([3 * 0.004, 0.0, 2 * 0.004])
    ball = (f'\n[[bodies]]\nname = "ball"\nshape = "sphere"\nradius_m = {R}\n'
            f'position_m = [{c_pos[0]}, {-R - 0.1 * T}, {c_pos[2]}]\n')
    model, state, tear = make(attach=ball)
    dt = 2e-4
    crumple(model, state, seed=1, speed=0.3, dt=dt)  # velocities of order 0.3 m/s everywhere
    c = cid(model, 3, 2)
    state.particle_position_m[[c, model.crossing_count + c]] = c_pos  # flat at the crossing
    prev = state.particle_position_m - dt * state.particle_velocity_m_s
    tear.split(state, [c], prev)
    n = model.crossing_count
    x = state.particle_position_m
    centre = np.array([c_pos[0], -R - 0.1 * T, c_pos[2]])
    inside = [p for p in (c, n + c) if np.linalg.norm(x[p] - centre) < R + 0.5 * T]
    assert inside  # the split put a mass inside the ball (margin T/2 included)
    velocity = (x - prev) / dt
    pairs = _pairs_of(model, state, c)
    tear.settle(state, np.array([c]), prev)
    for p in (c, n + c):
        assert np.linalg.norm(x[p] - centre) >= R + 0.5 * T - 1e-12
    np.testing.assert_allclose((x - prev) / dt, velocity, rtol=0, atol=1e-12)
    off = max(abs(np.linalg.norm(np.subtract(*_closest(x, *pair))) - T) for pair in pairs)
    assert off < 0.2 * T  # still woven: neither through each other nor apart


def test_settle_brings_a_crumpled_couple_to_its_thickness_without_changing_velocities():
    model, state, tear = make()
    dt, T = 2e-4, model.thickness_m
    prev = crumple(model, state, seed=2, speed=0.5, dt=dt)
    c = cid(model, 3, 2)
    tear.split(state, [c], prev)
    x = state.particle_position_m
    velocity = (x - prev) / dt
    pairs = _pairs_of(model, state, c)
    off_before = max(abs(np.linalg.norm(np.subtract(*_closest(x, *pair))) - T) for pair in pairs)
    tear.settle(state, np.array([c]), prev)
    off_after = max(abs(np.linalg.norm(np.subtract(*_closest(x, *pair))) - T) for pair in pairs)
    assert off_before > 0.05 * T and off_after < 0.5 * off_before
    np.testing.assert_allclose((x - prev) / dt, velocity, rtol=0, atol=1e-12)


def _pairs_of(model, state, c):
    A, B = state.spring_particle_a, state.spring_particle_b
    weft = [s for s in model.crossing_weft_springs[c] if s >= 0 and state.spring_alive[s]]
    warp = [s for s in model.crossing_warp_springs[c] if s >= 0 and state.spring_alive[s]]
    return [(A[s], B[s], A[u], B[u]) for s in weft for u in warp]


def _closest(x, a, b, p, q):
    from tearing_reference import closest_points_reference
    ta, tb, _ = closest_points_reference(x[a], x[b], x[p], x[q])
    return x[a] + ta * (x[b] - x[a]), x[p] + tb * (x[q] - x[p])
