"""Contact projection at connected mass couples (docs/method.md §3.3) and disconnection."""
from __future__ import annotations

import numpy as np
import pytest

from fraytool.grid import crossing_normals
from fraytool.scene import parse_scene
from fraytool.sim.builder import build_model
from fraytool.sim.tearing import YarnTearing, topology_problems
from fraytool.geometry.segments import segment_closest_params
from fraytool.sim.tearing.contact import crossing_pair_correction
from tearing_reference import (assert_named_close, closest_points_reference,
                                            project_couples_reference, state_dict)

EXACT_RTOL = 1e-12
REF_ATOL = 1e-14  # [m] kernel vs NumPy reference (different but equivalent arithmetic)

SCENE = """
[scene]
name = "contact"
[time]
step_s = 2e-4
steps_per_frame = 1
frames = 2
fps = 24
[cloth]
warp_yarns = 7
weft_yarns = 6
spacing_m = 0.004
thickness_m = 0.0006
mass_per_crossing_kg = 5e-6
origin_m = [0.0, 0.0, 0.0]
plane = "xz"
weave = "plain"
[cloth.springs]
structural_n_per_m = 40.0
bend_n_per_m = 1.0
shear_n_per_m = 5.0
damping = 0.0
[cloth.tearing]
enabled = true
disconnect_factor = 3.0
"""


@pytest.fixture
def cloth():
    model = build_model(parse_scene(SCENE, "contact.toml"))
    return model, model.state(), YarnTearing(model)


def pair_distance(x, pa, qa, pb, qb):
    return closest_points_reference(x[pa], x[qa], x[pb], x[qb])[2]


def couple_pairs(model, state, c):
    A, B = state.spring_particle_a, state.spring_particle_b
    weft = [s for s in model.crossing_weft_springs[c] if s >= 0 and state.spring_alive[s]]
    warp = [s for s in model.crossing_warp_springs[c] if s >= 0 and state.spring_alive[s]]
    return [(A[a], B[a], A[b], B[b]) for a in weft for b in warp]


@pytest.mark.parametrize("slide", [False, True])
def test_pair_closer_than_T_ends_exactly_T_apart(slide):
    T = 0.0006
    # weft spring along x above a warp spring along y, crossing at their middles, 0.3 T apart
    pa, qa = np.array([-0.002, 0.0, 0.0003]), np.array([0.002, 0.0, 0.0003])
    pb, qb = np.array([0.0, -0.002, 0.0003 - 0.3 * T]), np.array([0.0, 0.002, 0.0003 - 0.3 * T])
    d, ta, tb, kpa, kqa, kpb, kqb, nx, ny, nz = crossing_pair_correction((pa, qa, pb, qb), (pa, qa, pb, qb),
                                                                         (1.0, 1.0, 1.0, 1.0), 1.0, T, slide)
    assert np.isclose(d, 0.3 * T) and ta == tb == 0.5
    n = np.array([nx, ny, nz])
    new = [p + k * n for p, k in ((pa, kpa), (qa, kqa), (pb, kpb), (qb, kqb))]
    assert abs(closest_points_reference(*new)[2] - T) <= EXACT_RTOL * T
    assert new[0][2] > new[2][2]  # the weft stays on top


def test_pair_projection_is_exact_and_mass_weighted_at_any_parameters():
    rng = np.random.default_rng(2)
    T = 0.0006
    for _ in range(50):
        pa, qa = rng.normal(0, 0.002, 3) + [-0.002, 0, 0], rng.normal(0, 0.002, 3) + [0.002, 0, 0]
        pb, qb = rng.normal(0, 0.002, 3) + [0, -0.002, 0], rng.normal(0, 0.002, 3) + [0, 0.002, 0]
        w = rng.uniform(0.0, 2.0, 4)
        w[rng.integers(4)] = 0.0  # a held end never moves
        for slide in (False, True):
            d, ta, tb, *k, nx, ny, nz = crossing_pair_correction((pa, qa, pb, qb), (pa, qa, pb, qb), tuple(w), -1.0, T, slide)
            rta, rtb, rd = closest_points_reference(pa, qa, pb, qb)
            assert np.isclose(d, rd, rtol=1e-12) and np.allclose([ta, tb], [rta, rtb], atol=1e-9)
            n = np.array([nx, ny, nz])
            new = [p + kk * n for p, kk in zip((pa, qa, pb, qb), k)]
            assert all(kk == 0.0 for kk, wk in zip(k, w) if wk == 0.0)
            if not any(k):
                continue  # parallel at a free end: nothing to do
            r = (1 - ta) * new[0] + ta * new[1] - ((1 - tb) * new[2] + tb * new[3])
            # along the correction direction (warp to weft side) the closest points end T apart
            assert abs(r @ n - T) <= 1e-9 * T
            r0 = (1 - ta) * pa + ta * qa - ((1 - tb) * pb + tb * qb)
            if not slide and np.isclose(abs(r0 @ n), d, rtol=1e-9) and r0 @ n > 0:
                assert abs(np.linalg.norm(r) - T) <= 1e-9 * T  # the n_s form: |a - b| = T


def test_segment_closest_params_match_the_reference():
    rng = np.random.default_rng(5)
    for _ in range(200):
        p = rng.normal(size=(4, 3))
        ta, tb = segment_closest_params(*p.ravel())
        rta, rtb, rd = closest_points_reference(*p)
        a = p[0] + ta * (p[1] - p[0])
        b = p[2] + tb * (p[3] - p[2])
        assert np.isclose(np.linalg.norm(a - b), rd, rtol=1e-12, atol=1e-15)


def weft_side(model, c):
    """Unit vector from the warp to the weft side at crossing c: s n_c (n_c = -y for an xz cloth)."""
    n_c = crossing_normals(model.crossing_rest_position_m, model.warp_yarns, model.weft_yarns)[c]
    return n_c if model.crossing_weft_on_top[c] else -n_c


def _squeeze(model, state, c, fraction):
    n = model.crossing_count
    state.particle_position_m[n + c] = state.particle_position_m[c] - fraction * model.thickness_m * weft_side(model, c)


def test_couple_with_one_pair_closer_than_T_ends_exactly_T_apart(cloth):
    # Through the kernel: one weft and one warp spring left at the couple, crossing at their middles
    # 0.25 T apart (equal masses), end exactly T apart at their closest points.
    model, state, tear = cloth
    W, n, T, L = model.warp_yarns, model.crossing_count, model.thickness_m, model.spacing_m
    c = 3 * W + 3
    tear.split(state, [c, c + 1, c + W])
    tear.disconnect(state, c + 1)
    tear.disconnect(state, c + W)  # only c's couple is projected
    tear.cut(state, int(model.weft_structural_spring[3, 2]))  # keep weft spring c -> c+1 ...
    tear.cut(state, int(model.warp_structural_spring[3, 2]))  # ... and warp spring c -> c+W
    up = weft_side(model, c)
    x = state.particle_position_m
    centre = x[c].copy()
    x[c] = centre + [-L / 2, 0.0, 0.0] + 0.125 * T * up
    x[c + 1] = centre + [L / 2, 0.0, 0.0] + 0.125 * T * up
    x[n + c] = centre + [0.0, 0.0, -L / 2] - 0.125 * T * up
    x[n + c + W] = centre + [0.0, 0.0, L / 2] - 0.125 * T * up
    (pair,) = couple_pairs(model, state, c)
    assert np.isclose(pair_distance(x, *pair), 0.25 * T)
    tear.contact(state, x.copy(), 2e-4)
    assert abs(pair_distance(x, *pair) - T) <= EXACT_RTOL * T
    assert (x[c] + x[c + 1] - x[n + c] - x[n + c + W]) @ up > 0  # weft still on its side
    assert state.couple_connected[c]


def test_couple_with_four_pairs_converges_to_T(cloth):
    # Crimped yarns: the 4 pairs' closest points are near, not at, the couple's masses and the pairs
    # pull slightly against each other, so one Gauss-Seidel pass (one per step) leaves a residual of
    # a few per cent of T that further passes shrink.
    model, state, tear = cloth
    c = 3 * model.warp_yarns + 3
    tear.split(state, [c])
    _squeeze(model, state, c, 0.25)
    T = model.thickness_m
    pairs = couple_pairs(model, state, c)
    assert len(pairs) == 4
    residual = []
    for _ in range(30):
        tear.contact(state, state.particle_position_m.copy(), 2e-4)
        residual.append(max(abs(pair_distance(state.particle_position_m, *p) - T) for p in pairs))
    assert residual[0] < 0.05 * T
    assert residual[-1] < 0.01 * T and all(b <= a for a, b in zip(residual, residual[1:]))


def test_beyond_the_disconnect_distance_nothing_is_corrected(cloth):
    model, state, tear = cloth
    n = model.crossing_count
    c = 3 * model.warp_yarns + 3
    tear.split(state, [c])
    D = model.disconnect_distance_m
    assert np.isclose(D, 3.0 * model.thickness_m)
    state.particle_position_m[n + c] -= 1.05 * D * weft_side(model, c)
    before = state.particle_position_m.copy()
    tear.contact(state, before.copy(), 2e-4)
    assert (state.particle_position_m == before).all()
    assert not state.couple_connected[c] and c not in tear.connected_couples
    # disconnected for good: brought back within T it is still left alone
    state.particle_position_m[n + c] = state.particle_position_m[c]
    before = state.particle_position_m.copy()
    tear.contact(state, before.copy(), 2e-4)
    assert (state.particle_position_m == before).all()
    assert topology_problems(model, state) == []


def test_a_pair_that_passed_through_is_pushed_back_to_its_side(cloth):
    model, state, tear = cloth
    n = model.crossing_count
    c = 2 * model.warp_yarns + 2
    tear.split(state, [c])
    prev = state.particle_position_m.copy()  # on its side at the start of the step
    _squeeze(model, state, c, -0.5)  # ... and now the warp mass half a thickness on the weft's side
    x = state.particle_position_m
    assert (x[c] - x[n + c]) @ weft_side(model, c) < 0
    tear.contact(state, prev, 2e-4)
    assert (x[c] - x[n + c]) @ weft_side(model, c) > 0.9 * model.thickness_m


def test_a_pair_already_on_the_wrong_side_is_not_thrown_through(cloth):
    # Through the kernel: on the wrong side at the start of the step as well (a frame that turned,
    # or an old pass-through): pushed apart to T where it is, never thrown through by T + |h|.
    model, state, tear = cloth
    n, T = model.crossing_count, model.thickness_m
    c = 2 * model.warp_yarns + 2
    tear.split(state, [c])
    _squeeze(model, state, c, -0.5)
    x = state.particle_position_m
    before = x.copy()
    tear.contact(state, x.copy(), 2e-4)
    assert (x[c] - x[n + c]) @ weft_side(model, c) < 0
    assert np.abs(x - before).max() < 0.5 * T


@pytest.mark.parametrize("slide", [False, True])
def test_a_pair_on_the_wrong_side_but_apart_is_not_thrown_through(slide):
    # Further apart than T on the wrong side: not a pass-through within the step (a yarn moves far
    # less than T per step) but a turned frame. The old push of T + |h| along the crossing normal
    # was a jump of 3 T here, i.e. a speed of 3 T / dt. Inside the weave the pair is pulled to T
    # apart where it is (the paper's n_s); at a free end it is left alone.
    T = 0.0006
    pa, qa = np.array([-0.002, 0.0, 0.0]), np.array([0.002, 0.0, 0.0])  # weft, meant to be on top
    pb, qb = np.array([0.0, -0.002, 2 * T]), np.array([0.0, 0.002, 2 * T])  # warp 2 T above it
    d, ta, tb, kpa, kqa, kpb, kqb, nx, ny, nz = crossing_pair_correction((pa, qa, pb, qb), (pa, qa, pb, qb),
                                                                         (1.0, 1.0, 1.0, 1.0), 1.0, T, slide)
    assert np.isclose(d, 2 * T)
    n = np.array([nx, ny, nz])
    new = [p + k * n for p, k in ((pa, kpa), (qa, kqa), (pb, kpb), (qb, kqb))]
    if slide:
        assert kpa == kqa == kpb == kqb == 0.0
        return
    ta2, tb2, d2 = closest_points_reference(*new)
    assert abs(d2 - T) <= EXACT_RTOL * T
    a = new[0] + ta2 * (new[1] - new[0])
    b = new[2] + tb2 * (new[3] - new[2])
    assert (a - b)[2] < 0  # still on the side it was: pulled together, not thrown through
    assert max(abs(k) for k in (kpa, kqa, kpb, kqb)) <= 0.51 * T  # the old push moved each end 1.5 T


def test_a_free_end_apart_from_the_other_yarn_is_left_alone(cloth):
    # At a free yarn end the contact only pushes apart: a weft end lifted 2 T off its warp (within
    # the disconnect distance) is not pulled back down; pressed to 0.5 T it is pushed back to T.
    model, state, tear = cloth
    n, T, W = model.crossing_count, model.thickness_m, model.warp_yarns
    end = 2 * W + 4
    tear.split(state, [end])
    tear.cut(state, int(model.weft_structural_spring[2, 4]))  # weft 2 cut right of crossing (4, 2)
    pairs = couple_pairs(model, state, end)
    _squeeze(model, state, end, 2.0)
    before = state.particle_position_m.copy()
    tear.contact(state, before.copy(), 2e-4)
    assert state.couple_connected[end]
    x = state.particle_position_m
    moved = np.abs(x[[end, n + end]] - before[[end, n + end]]).max()
    assert moved == 0.0
    _squeeze(model, state, end, 0.5)
    assert min(pair_distance(x, *p) for p in pairs) < 0.6 * T
    tear.contact(state, x.copy(), 2e-4)
    assert min(pair_distance(x, *p) for p in pairs) > 0.95 * T


def test_free_end_slides_in_plane_but_woven_crossing_holds(cloth):
    model, state, tear = cloth
    n = model.crossing_count
    W = model.warp_yarns
    inner, end = 2 * W + 2, 2 * W + 4
    tear.split(state, [inner, end])
    tear.cut(state, int(model.weft_structural_spring[2, 4]))  # weft 2 cut right of crossing (4, 2)
    dx = 0.4 * model.spacing_m  # slide both weft masses along the weft, inwards
    for c in (inner, end):
        state.particle_position_m[c, 0] -= dx
    before = state.particle_position_m.copy()
    tear.contact(state, before.copy(), 2e-4)
    x = state.particle_position_m
    # free end: corrected across the cloth (y) only, up to the tilt of the crimped yarns
    assert np.abs(x[end, [0, 2]] - before[end, [0, 2]]).max() < 0.01 * dx
    assert np.abs(x[n + end, [0, 2]] - before[n + end, [0, 2]]).max() < 0.01 * dx
    # woven crossing: the slid weft is pulled back towards its warp (the paper's n_s)
    assert abs(x[inner, 0] - x[n + inner, 0]) < 0.9 * dx


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_projection_matches_numpy_reference(cloth, seed):
    model, state, tear = cloth
    rng = np.random.default_rng(seed)
    n = model.crossing_count
    tear.split(state, range(n))
    tear.cut(state, int(model.weft_structural_spring[3, 2]))
    tear.cut(state, int(model.warp_structural_spring[4, 1]))
    state.particle_position_m[:] += rng.normal(0.0, 0.8 * model.thickness_m, state.particle_position_m.shape)
    for c in rng.choice(n, 4, replace=False):  # some couples pulled apart, beyond the threshold
        state.particle_position_m[n + c] += 2.0 * model.spacing_m * rng.normal(size=3)
    tear._rebuild(state)
    couples = tear.connected_couples
    prev = state.particle_position_m + rng.normal(0.0, 0.3 * model.thickness_m, state.particle_position_m.shape)
    ref = project_couples_reference(model, state_dict(state, prev), couples)
    tear.contact(state, prev, 2e-4)
    got = state_dict(state)
    assert_named_close(ref, got, ["couple_connected", "spring_alive"])
    assert_named_close(ref, got, ["particle_position_m"], atol=REF_ATOL)
    assert 0 < state.couple_connected.sum() < n  # both branches were exercised
    assert topology_problems(model, state) == []


def test_settle_guard_finds_a_segment_carried_through_another():
    from fraytool.sim.tearing.contact import settle_crosses_yarns

    # segment 0: particles 0-1 along x at z = 0; segment 1: particles 2-3 along y, 0.2 mm above
    x0 = np.array([[-0.002, 0.0, 0.0], [0.002, 0.0, 0.0], [0.0, -0.002, 0.0002], [0.0, 0.002, 0.0002]])
    a, b = np.array([0, 2]), np.array([1, 3])
    segments = np.array([0, 1])
    through = x0.copy()
    through[2:, 2] -= 0.0004  # carried 0.2 mm below: through segment 0
    beside = x0.copy()
    beside[2:, 2] += 0.0004  # lifted: never meets it
    assert settle_crosses_yarns(x0, through, a, b, segments)
    assert not settle_crosses_yarns(x0, beside, a, b, segments)
    assert not settle_crosses_yarns(x0, x0.copy(), a, b, segments)
