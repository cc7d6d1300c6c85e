"""Self-collision: by brute force over every step, no yarn segment passes through another -- a cloth
folded onto itself, the first frames of the Fig. 6 and Fig. 7 shots (tearing) -- and the stage's
failsafe is bounded and reports giving up; its results do not depend on the candidates it kept.

The checker is independent of the solver's broad phase and CCD: all pairs of segments whose boxes
swept over the step overlap (a plain sort and sweep), then the coplanarity cubic
x31(t) . (x21(t) x x43(t)) split at its critical points into monotone pieces, every sign change
bisected, and the exact segment distance at those roots, at the critical points and at t = 0, 1
(plus a grid of times where the motion is coplanar and the cubic vanishes)."""
from dataclasses import replace
from pathlib import Path

import numba
import numpy as np
import pytest

from helpers import pulled_strip_text, small_scene

from fraytool.collision import edge_edge_ccd
from fraytool.scene import load_scene, parse_scene
from fraytool.sim import Simulation
from fraytool.kinds import STRUCT_WARP, STRUCT_WEFT
from fraytool.sim.stages import self_collision as stage_module
from fraytool.sim.stages.base import HookStage

ROOT = Path(__file__).resolve().parent.parent
TOL = 1e-9
"""The checker's contact distance [m]: far below the CCD's tolerance (1e-6 x the coordinates)."""


def segment_distance(p1, q1, p2, q2):
    """Exact distance between segments p1q1 and p2q2, row by row ((K, 3) arrays; Ericson,
    Real-Time Collision Detection §5.1.9, with the clamps of both parameters)."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a = np.maximum(np.einsum("ij,ij->i", d1, d1), 1e-300)
    e = np.maximum(np.einsum("ij,ij->i", d2, d2), 1e-300)
    b = np.einsum("ij,ij->i", d1, d2)
    c = np.einsum("ij,ij->i", d1, r)
    f = np.einsum("ij,ij->i", d2, r)
    denom = a * e - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(denom > 1e-14 * a * e, np.clip((b * f - c * e) / denom, 0.0, 1.0), 0.0)
    t = (b * s + f) / e
    s = np.where(t < 0.0, np.clip(-c / a, 0.0, 1.0), np.where(t > 1.0, np.clip((b - c) / a, 0.0, 1.0), s))
    t = np.clip(t, 0.0, 1.0)
    return np.linalg.norm(p1 + s[:, None] * d1 - p2 - t[:, None] * d2, axis=1)


@numba.njit(cache=True)
def _sweep(lo, hi, order, axis, out):
    """Sort-and-sweep along ``axis`` (boxes in ``order`` of increasing lo): writes the overlapping
    pairs into ``out`` while they fit; returns how many there are."""
    n = 0
    for a in range(order.shape[0]):
        i = order[a]
        for b in range(a + 1, order.shape[0]):
            j = order[b]
            if lo[j, axis] > hi[i, axis]:
                break
            if (lo[i, 0] <= hi[j, 0] and lo[j, 0] <= hi[i, 0] and lo[i, 1] <= hi[j, 1] and lo[j, 1] <= hi[i, 1]
                    and lo[i, 2] <= hi[j, 2] and lo[j, 2] <= hi[i, 2]):
                if n < out.shape[0]:
                    out[n, 0] = i
                    out[n, 1] = j
                n += 1
    return n


def overlapping_boxes(lo, hi):
    """Pairs (i, j) of overlapping boxes, each once: sort and sweep along the widest axis."""
    if not len(lo):
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    axis = int(np.argmax(hi.max(axis=0) - lo.min(axis=0)))
    order = np.argsort(lo[:, axis], kind="stable")
    out = np.empty((4 * len(lo), 2), np.int64)
    n = _sweep(lo, hi, order, axis, out)
    if n > len(out):
        out = np.empty((n, 2), np.int64)
        _sweep(lo, hi, order, axis, out)
    return out[:n, 0], out[:n, 1]


def _cubic(ends0, ends1, t):
    """x31 . (x21 x x43) at times t (K,) of pairs moving linearly: ends0, ends1 (4, K, 3)."""
    x = ends0 + t[None, :, None] * (ends1 - ends0)
    u, v, w = x[1] - x[0], x[3] - x[2], x[2] - x[0]
    return (w[:, 0] * (u[:, 1] * v[:, 2] - u[:, 2] * v[:, 1]) + w[:, 1] * (u[:, 2] * v[:, 0] - u[:, 0] * v[:, 2])
            + w[:, 2] * (u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]))


def crossed_pairs(x0, x1, sa, sb, tol, sa1=None, sb1=None):
    """Pairs of segments whose centre lines meet during linear motion: segment k goes from
    x0[sa[k]] x0[sb[k]] to x1[sa1[k]] x1[sb1[k]] (sa1, sb1 default sa, sb); pairs sharing an end
    particle at the start or at the end are skipped. [(k, l, t)], k < l, t the time found."""
    sa1 = sa if sa1 is None else sa1
    sb1 = sb if sb1 is None else sb1
    p0, q0, p1, q1 = x0[sa], x0[sb], x1[sa1], x1[sb1]
    lo = np.minimum(np.minimum(p0, q0), np.minimum(p1, q1)) - tol
    hi = np.maximum(np.maximum(p0, q0), np.maximum(p1, q1)) + tol
    i, j = overlapping_boxes(lo, hi)
    share = ((sa[i] == sa[j]) | (sa[i] == sb[j]) | (sb[i] == sa[j]) | (sb[i] == sb[j])
             | (sa1[i] == sa1[j]) | (sa1[i] == sb1[j]) | (sb1[i] == sa1[j]) | (sb1[i] == sb1[j]))
    i, j = np.minimum(i[~share], j[~share]), np.maximum(i[~share], j[~share])
    if not len(i):
        return []
    e0 = np.stack([p0[i], q0[i], p0[j], q0[j]])
    e1 = np.stack([p1[i], q1[i], p1[j], q1[j]])
    # the coplanarity cubic f(t): coefficients from 4 exact samples (Lagrange), critical points from f'
    ts = np.array([0.0, 1 / 3, 2 / 3, 1.0])
    vals = np.stack([_cubic(e0, e1, np.full(len(i), t)) for t in ts], axis=1)
    coef = np.linalg.solve(np.vander(ts, 4), vals.T).T  # c3, c2, c1, c0
    c3, c2, c1 = coef[:, 0], coef[:, 1], coef[:, 2]
    qa, qb, qc = 3 * c3, 2 * c2, c1
    disc = qb * qb - 4 * qa * qc
    sq = np.sqrt(np.maximum(disc, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        quad = np.abs(qa) > 1e-12 * (np.abs(qb) + np.abs(qc))
        r1 = np.where(quad, (-qb - sq) / (2 * qa), -qc / qb)
        r2 = np.where(quad, (-qb + sq) / (2 * qa), np.nan)
    r1 = np.where((disc >= 0) | ~quad, r1, np.nan)
    r2 = np.where(disc >= 0, r2, np.nan)
    crit = np.stack([r1, r2], axis=1)
    crit = np.sort(np.where((crit > 0.0) & (crit < 1.0), crit, np.nan), axis=1)  # inside (0, 1), NaN last
    # monotone pieces [0, c_1], [c_1, c_2], [c_2, 1] (NaN bounds: piece skipped / merged)
    times = [np.zeros(len(i)), np.ones(len(i)), crit[:, 0], crit[:, 1]]
    bounds = np.stack([np.zeros(len(i)), np.nan_to_num(crit[:, 0], nan=1.0),
                       np.nan_to_num(crit[:, 1], nan=1.0), np.ones(len(i))], axis=1)
    bounds[:, 1:] = np.maximum.accumulate(bounds[:, 1:], axis=1)
    for k in range(3):  # bisection on the pieces where f changes sign
        lo_t, hi_t = bounds[:, k], bounds[:, k + 1]
        flo, fhi = _cubic(e0, e1, lo_t), _cubic(e0, e1, hi_t)
        has = np.nonzero((hi_t > lo_t) & (np.sign(flo) * np.sign(fhi) <= 0))[0]
        lo_t, hi_t, flo, s0, s1 = lo_t[has], hi_t[has], flo[has], e0[:, has], e1[:, has]
        for _ in range(64):
            mid = 0.5 * (lo_t + hi_t)
            fm = _cubic(s0, s1, mid)
            left = np.sign(fm) * np.sign(flo) <= 0
            hi_t, lo_t = np.where(left, mid, hi_t), np.where(left, lo_t, mid)
            flo = np.where(left, flo, fm)
        root = np.full(len(i), np.nan)
        root[has] = 0.5 * (lo_t + hi_t)
        times.append(root)
    # f identically ~0 (coplanar motion): a coarse grid of times as well
    scale = np.abs(vals).max(axis=1)
    size = np.max(np.abs(e1 - e0).max(axis=2) + np.abs(e0 - e0[0][None]).max(axis=2), axis=0)
    flat = scale <= 1e-12 * np.maximum(size, 1e-300) ** 3
    for t in np.linspace(0.0, 1.0, 33)[1:-1]:
        times.append(np.where(flat, t, np.nan))
    found = {}
    for t in times:
        ok = ~np.isnan(t)
        if not ok.any():
            continue
        tt = t[ok]
        x = e0[:, ok] + tt[None, :, None] * (e1[:, ok] - e0[:, ok])
        hit = segment_distance(x[0], x[1], x[2], x[3]) < tol
        for k, tk in zip(np.nonzero(ok)[0][hit], tt[hit]):
            found.setdefault(int(k), float(tk))
    return sorted((int(i[k]), int(j[k]), t) for k, t in found.items())


def _fold_scene(self_collision: bool):
    """fold_pile at 14 x 14: the same bars, closing in on a smaller cloth."""
    text = (ROOT / "scenes" / "fold_pile.toml").read_text()
    text = text.replace("warp_yarns = 24", "warp_yarns = 14").replace("weft_yarns = 24", "weft_yarns = 14")
    text = text.replace("origin_m = [-0.046, 0.1, -0.046]", "origin_m = [-0.026, 0.1, -0.026]")
    text = text.replace("-0.046, 0.1, 0.0]", "-0.026, 0.1, 0.0]").replace("0.046, 0.1, 0.0]", "0.026, 0.1, 0.0]")
    text = text.replace("0.03, 0.1, 0.0]", "0.018, 0.1, 0.0]").replace("-0.03, 0.09, 0.0]", "-0.018, 0.092, 0.0]")
    if not self_collision:
        text = text.replace("enabled = true", "enabled = false")
    return parse_scene(text, "fold_small.toml")


def _run_and_check(spec, frames):
    sim = Simulation(spec)
    kinds = sim.model.spring_kind
    structural = np.nonzero((kinds == STRUCT_WEFT) | (kinds == STRUCT_WARP))[0]
    sa = sim.state.spring_particle_a[structural]
    sb = sim.state.spring_particle_b[structural]
    crossings = []
    folded = 0.0
    for _ in range(frames * spec.time.steps_per_frame):
        x0 = sim.state.particle_position_m.copy()
        sim.step()
        x1 = sim.state.particle_position_m
        crossings += crossed_pairs(x0, x1, sa, sb, TOL)
    n = sim.model.crossing_count
    # the cloth really folded onto itself: masses far apart along the cloth lie close in space
    y = sim.state.particle_position_m[:n, 1]
    folded = y.max() - y.min()
    return crossings, folded, sim


@pytest.mark.parametrize("frames", [36])
def test_folding_cloth_never_crosses_itself(frames):
    crossings, folded, sim = _run_and_check(_fold_scene(True), frames)
    summary = sim.summary()
    assert summary["self_collision_pairs"] + summary["self_collision_proximity_pushes"] > 0, \
        "the scene never brought yarns into contact"
    assert crossings == [], f"yarn segments crossed: {crossings[:5]}"


def test_checker_detects_a_crossing():
    """The brute-force checker can fail: two segments moving through each other are caught (also off
    the sample points of a parameter grid, and within their plane), the same segments stopping short
    are not."""
    x0 = np.array([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.5], [0.0, 1.0, 0.5]])
    through = x0.copy()
    through[2:, 2] = -0.5
    short = x0.copy()
    short[2:, 2] = 0.1
    sa, sb = np.array([0, 2]), np.array([1, 3])
    assert crossed_pairs(x0, through, sa, sb, TOL) == [(0, 1, pytest.approx(0.5))]
    assert crossed_pairs(x0, short, sa, sb, TOL) == []
    off = np.array([[-1.0, 0.0, 0.0], [1.3, 0.0, 0.0], [0.123, -1.0, 0.5], [0.123, 1.7, 0.5]])
    off_through = off.copy()
    off_through[2:, 2] = -0.37
    assert crossed_pairs(off, off_through, sa, sb, TOL) == [(0, 1, pytest.approx(0.5 / 0.87))]
    flat = np.array([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.3, 0.5, 0.0], [0.3, 1.5, 0.0]])
    flat_through = flat.copy()
    flat_through[2:, 1] -= 2.0
    assert crossed_pairs(flat, flat_through, sa, sb, TOL) != []
    flat_short = flat.copy()
    flat_short[2:, 1] -= 0.4
    assert crossed_pairs(flat, flat_short, sa, sb, TOL) == []


def test_checker_agrees_with_the_ccd_on_random_motions():
    """On random segment pairs moving linearly, the checker and the solver's interval CCD
    (fraytool.collision.edge_edge_ccd, thickness 0) find the same pairs crossing."""
    rng = np.random.default_rng(5)
    sa, sb = np.array([0, 2]), np.array([1, 3])
    hits = 0
    for k in range(600):
        xs = rng.normal(size=(4, 3))
        xe = xs + (0.1 if k % 2 else 1.0) * rng.normal(size=(4, 3))
        hit, _ = edge_edge_ccd(xs, xe)
        assert bool(crossed_pairs(xs, xe, sa, sb, TOL)) == bool(hit), (xs, xe)
        hits += bool(hit)
    assert 30 < hits < 570


def _pairs_the_step_can_act_on(state, prev, yarn, contact_distance):
    """Brute force: live yarn-segment pairs sharing no end particle whose boxes swept from prev to
    the current positions, inflated by d_c / 2, overlap (proximity and CCD act on nothing else)."""
    seg = np.nonzero((yarn >= 0) & state.spring_alive)[0]
    sa, sb = state.spring_particle_a[seg], state.spring_particle_b[seg]
    x0, x1 = prev, state.particle_position_m
    lo = np.minimum(np.minimum(x0[sa], x0[sb]), np.minimum(x1[sa], x1[sb])) - 0.5 * contact_distance
    hi = np.maximum(np.maximum(x0[sa], x0[sb]), np.maximum(x1[sa], x1[sb])) + 0.5 * contact_distance
    overlap = np.all((lo[:, None] <= hi[None]) & (lo[None] <= hi[:, None]), axis=2)
    share = ((sa[:, None] == sa[None]) | (sa[:, None] == sb[None]) | (sb[:, None] == sa[None])
             | (sb[:, None] == sb[None]))
    i, j = np.nonzero(np.triu(overlap & ~share, 1))
    return set(zip(seg[i].tolist(), seg[j].tolist()))


def test_kept_candidates_cover_every_pair_while_tearing():
    """The broad phase's candidates are kept across steps, re-boxed where segments leave their slack
    and patched where splits re-attach segments (module docstring of fraytool.collision.candidates):
    after every validation, in a strip torn at yarn level, they hold every pair the step can act on."""
    sim = Simulation(parse_scene(pulled_strip_text("torn_strip", yarn_level=True,
                                                    extra="[self_collision]\nenabled = true\n"),
                                  "torn_strip.toml"))
    sc = sim.solver.self_collision
    checked = []
    ensure = sc._ensure_valid

    def ensure_and_check(state, prev):
        ensure(state, prev)
        need = _pairs_the_step_can_act_on(state, prev, sim.model.spring_yarn(), sc.contact_distance_m)
        have = set(map(tuple, sc._cand.tolist()))
        assert need <= have, f"step {state.step_index}: missing {sorted(need - have)[:5]}"
        assert np.all(sc._cand[:, 0] < sc._cand[:, 1])
        keys = sc._cand[:, 0].astype(np.int64) * sc.model.spring_count + sc._cand[:, 1]
        assert np.all(np.diff(keys) > 0)  # sorted, no duplicates
        checked.append(len(need))

    sc._ensure_valid = ensure_and_check
    for _ in range(20):
        sim.advance_frame()
    assert sc.broad_phase_patches > 0 and sc.broad_phase_reboxes > 0  # both paths were taken
    assert sim.summary()["yarn_level_masses"] > 0 and max(checked) > 0


def _run_checking_every_step(sim, frames):
    """Advance ``frames`` frames and check every step by brute force, the yarn segments alive in it:
    (1) their motion from the start of the step to the end of the self-collision stage, with the
    end particles the stage saw (what the stage answers for); (2) then to the end of the step, in
    which tearing splits base masses into couples, moving them T/2 along the cloth normal and
    re-attaching segments to the new masses: each end goes from its particle before to its particle
    after (pairs that share an end particle before or after are skipped: they meet at that mass).
    Returns the crossings as (motion, step, spring, spring, t)."""
    segments = sim.solver.self_collision.yarn_segments
    found, mid = [], {}

    def after_self_collision(state, prev, dt_s):
        live = segments[state.spring_alive[segments]]
        sa, sb = state.spring_particle_a[live], state.spring_particle_b[live]
        for k, l, t in crossed_pairs(prev, state.particle_position_m, sa, sb, TOL):
            found.append(("self_collision", state.step_index, int(live[k]), int(live[l]), t))
        mid.update(x=state.particle_position_m.copy(), a=state.spring_particle_a.copy(),
                   b=state.spring_particle_b.copy())

    sim.solver.insert_stage(HookStage("self_collision", after_self_collision))
    for _ in range(frames * sim.steps_per_frame):
        sim.step()
        state = sim.state
        live = segments[state.spring_alive[segments]]
        a0, b0, a1, b1 = mid["a"][live], mid["b"][live], state.spring_particle_a[live], state.spring_particle_b[live]
        if np.array_equal(a0, a1) and np.array_equal(b0, b1) and np.array_equal(mid["x"], state.particle_position_m):
            continue  # nothing moved after the self-collision stage
        for k, l, t in crossed_pairs(mid["x"], state.particle_position_m, a0, b0, TOL, a1, b1):
            found.append(("tearing", state.step_index - 1, int(live[k]), int(live[l]), t))
    return found


@pytest.mark.parametrize("scene, frames", [("fig6_thrown_ball_plain", 16), ("fig7_square_grab", 24)])
def test_figure_shots_never_cross_themselves(scene, frames):
    """The first frames of the Fig. 6 and Fig. 7 shots with self-collision on (forced here, whatever
    the scene file says), every step checked (``_run_checking_every_step``). Fig. 6 tears from about
    frame 3 and its yarns run into each other from frame 5; Fig. 7 tears from about frame 9 and its
    yarns run into each other from about frame 15 (the frames move with the model: the test asserts
    that the cloth tore and that the CCD caught crossing pairs). About 6 s (Fig. 6) and 10 s
    (Fig. 7) on one core, half of it the checker."""
    spec = load_scene(str(ROOT / "scenes" / f"{scene}.toml"))
    spec = replace(spec, self_collision=replace(spec.self_collision, enabled=True))
    sim = Simulation(spec)
    crossings = _run_checking_every_step(sim, frames)
    summary = sim.summary()
    assert summary["yarn_level_masses"] > 0 and summary["broken_springs"] > 0, "the cloth did not tear"
    assert summary["self_collision_pairs"] > 0, "no yarns passed through each other before the response"
    assert crossings == [], f"yarn segments crossed: {crossings[:5]}"


def _crossing_step():
    """A 12 x 12 cloth at rest with self-collision on (no response pass: iterations = 0), and a step
    in which a corner weft segment is carried from 2 mm above a middle weft segment, crosswise, to
    2 mm below it; the segments joined to its ends follow, so several pairs cross. Returns the
    simulation, the start-of-step positions and the two carried particles."""
    sim = Simulation(small_scene("[self_collision]\nenabled = true\n", gravity="[0.0, 0.0, 0.0]"))
    sim.solver.self_collision.iterations = 0
    state, model = sim.state, sim.model
    x = state.particle_position_m
    weft = np.nonzero(model.spring_kind == STRUCT_WEFT)[0]
    ends = np.stack([state.spring_particle_a[weft], state.spring_particle_b[weft]], axis=1)
    middle = 0.5 * (x[ends[:, 0]] + x[ends[:, 1]])
    centre = x[: model.crossing_count].mean(axis=0)
    dist = np.linalg.norm(middle - centre, axis=1)
    target, carried = ends[np.argmin(dist)], ends[np.argmax(dist)]
    along = x[target[1]] - x[target[0]]
    normal = np.array([0.0, 1.0, 0.0])
    across = np.cross(normal, along)
    centre = 0.5 * (x[target[0]] + x[target[1]])
    prev = x.copy()
    prev[carried[0]] = centre + 0.002 * normal - 0.5 * across
    prev[carried[1]] = centre + 0.002 * normal + 0.5 * across
    x[carried] = prev[carried] - 0.004 * normal
    return sim, prev, carried


def _yarn_crossings(sim, prev):
    state = sim.state
    live = np.nonzero((sim.model.spring_yarn() >= 0) & state.spring_alive)[0]
    return crossed_pairs(prev, state.particle_position_m, state.spring_particle_a[live],
                         state.spring_particle_b[live], TOL)


def test_failsafe_returns_crossing_pairs_to_their_start(capsys):
    """Without any response pass, the failsafe alone undoes the crossing step, in one round."""
    sim, prev, carried = _crossing_step()
    assert len(_yarn_crossings(sim, prev)) > 1
    sc = sim.solver.self_collision
    sc(sim.state, prev, sim.dt_s)
    assert sc.cap_hits == 1 and sc.failsafe_rounds_max == 1 and sc.failsafe_give_ups == 0
    assert np.array_equal(sim.state.particle_position_m[carried], prev[carried])
    assert _yarn_crossings(sim, prev) == []
    assert capsys.readouterr().err == ""


def test_failsafe_is_bounded_and_says_once_that_it_gave_up(monkeypatch, capsys):
    """A failsafe that never gets anywhere (here ``freeze_pairs`` claims to move particles back and
    moves none) stops after FAILSAFE_ROUNDS rounds and gives up: every free particle back at its
    start, so nothing crosses; the give-up is counted every time and printed the first time only."""
    rounds = []

    def stuck_freeze(pairs, *args):
        rounds.append(len(pairs))
        return 1

    monkeypatch.setattr(stage_module, "freeze_pairs", stuck_freeze)
    sim, prev, carried = _crossing_step()
    sc, state = sim.solver.self_collision, sim.state
    crossing_x = state.particle_position_m.copy()
    sc(state, prev, sim.dt_s)
    assert len(rounds) == stage_module.FAILSAFE_ROUNDS and rounds[0] > 1
    summary = sim.summary()
    assert summary["self_collision_failsafe_give_ups"] == 1 and summary["self_collision_failsafe_crossings_left"] == 0
    free = state.particle_inv_mass > 0.0
    assert np.array_equal(state.particle_position_m[free], prev[free])
    assert _yarn_crossings(sim, prev) == []
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("fraytool: warning: self-collision failsafe gave up at step 1 "
                                                     "(t = 0.0004 s) with ")
    assert f"after {stage_module.FAILSAFE_ROUNDS} rounds" in err and "(0 pairs still cross" in err

    state.particle_position_m[:] = crossing_x  # the same step again: counted, not printed again
    sc(state, prev, sim.dt_s)
    assert len(rounds) == 2 * stage_module.FAILSAFE_ROUNDS and sc.failsafe_give_ups == 2
    assert capsys.readouterr().err == ""


def test_failsafe_gives_up_on_crossings_that_held_ends_force(capsys):
    """Ends held by bodies (inverse mass 0) that carry a segment through the cloth: no reset of free
    particles can stop it. The failsafe returns the free ends it can (those the proximity pass
    moved), sees that a round changes nothing more, gives up, leaves the held segments where the
    bodies put them, and says so, once."""
    sim, prev, carried = _crossing_step()
    sc, state = sim.solver.self_collision, sim.state
    state.particle_inv_mass[carried] = 0.0
    carried_x = state.particle_position_m[carried].copy()
    sc(state, prev, sim.dt_s)
    assert sc.failsafe_give_ups == 1 and sc.failsafe_rounds_max < stage_module.FAILSAFE_ROUNDS
    assert np.array_equal(state.particle_position_m[carried], carried_x)
    assert _yarn_crossings(sim, prev) != [] and sim.summary()["self_collision_failsafe_crossings_left"] > 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "gave up at step 1" in err and "ends held by bodies" in err
    sc(state, prev, sim.dt_s)
    assert sc.failsafe_give_ups == 2 and capsys.readouterr().err == ""


def test_results_do_not_depend_on_the_kept_candidates(monkeypatch):
    """The torn strip twice: once keeping its candidates across steps with no slack (re-validated
    all the time, also in the middle of the proximity pass), once building candidates with a slack
    of 2 cm afresh at every step (far more, and different, extra pairs). Same positions, bit for
    bit, after every step (fraytool.sim.stages.self_collision, "Results independent of the kept
    candidates"): what makes a resumed run equal an unbroken one."""
    stops = []
    repel = stage_module.repel_close_pairs

    def counting_repel(*args):
        moved, stop = repel(*args)
        stops.append(stop)
        return moved, stop

    monkeypatch.setattr(stage_module, "repel_close_pairs", counting_repel)
    spec = parse_scene(pulled_strip_text("torn_strip", yarn_level=True, extra="[self_collision]\nenabled = true\n"),
                       "torn_strip.toml")
    tight, loose = Simulation(spec), Simulation(spec)
    for sim, slack in ((tight, 0.0), (loose, 0.02)):
        sc = sim.solver.self_collision
        sc.slack_m, sc.margin_m = slack, 0.5 * sc.contact_distance_m + slack
    fresh = loose.solver.self_collision
    for _ in range(24 * spec.time.steps_per_frame):
        tight.step()
        fresh._cand = None
        loose.step()
        assert tight.state.particle_position_m.tobytes() == loose.state.particle_position_m.tobytes(), \
            f"step {tight.state.step_index}"
    assert tight.summary()["self_collision_pairs"] > 0 and tight.summary()["yarn_level_masses"] > 0
    assert max(stops) >= 0  # the proximity pass did stop for a check and go on
    assert len(fresh._cand) > 10 * len(tight.solver.self_collision._cand)


def test_movable_pairs_keeps_exactly_the_pairs_with_an_end_that_can_move():
    """fraytool.collision.candidates.movable_pairs against a plain filter: a pair stays (in order) when any of
    its four end particles has inverse mass > 0."""
    from fraytool.collision.candidates import movable_pairs

    rng = np.random.default_rng(5)
    a, b = rng.integers(0, 40, 300).astype(np.int32), rng.integers(0, 40, 300).astype(np.int32)
    w = np.where(rng.random(40) < 0.6, 0.0, 1.0)
    pairs = np.sort(rng.integers(0, 300, (500, 2)), axis=1).astype(np.int32)
    kept = movable_pairs(pairs, a, b, w)
    expected = pairs[(w[a[pairs[:, 0]]] > 0) | (w[b[pairs[:, 0]]] > 0) | (w[a[pairs[:, 1]]] > 0)
                     | (w[b[pairs[:, 1]]] > 0)]
    assert 0 < len(expected) < len(pairs)
    assert np.array_equal(kept, expected)


def _folded_coarse_cloth(thickness_m, lift_m):
    """A 17 x 17 coarse cloth (factor 4, self-collision on) folded along its coarse line j = 8: row j > 8 lies
    over row 16 - j, `lift_m` above it. Returns (model, state, the fold's normal)."""
    from fraytool.sim import multires
    from fraytool.sim.builder import ModelBuilder

    b = ModelBuilder(seed=3)
    b.add_cloth(warp_yarns=17, weft_yarns=17, spacing_m=0.004, thickness_m=thickness_m, mass_per_crossing_kg=1e-5,
                structural_n_per_m=20.0, bend_n_per_m=0.5, shear_n_per_m=2.0)
    b.set_multires(factor=4, band_cells=1)
    b.set_self_collision()
    model = b.finalize()
    state = model.state()
    x = state.particle_position_m
    grid = model.crossing_grid()  # (j, i) -> crossing
    rest = model.crossing_rest_position_m
    normal = np.cross(rest[grid[0, 1]] - rest[grid[0, 0]], rest[grid[1, 0]] - rest[grid[0, 0]])
    normal /= np.linalg.norm(normal)
    for jj in range(9, 17):
        x[grid[jj]] = rest[grid[16 - jj]] + lift_m * normal
    layout = multires.coarse_layout(model)
    multires.interpolate_slaved(layout, multires.free_crossings(layout, state.coarse_cell_refined), x)
    return model, state, normal


def test_a_coarse_model_leaves_out_pairs_nothing_can_move_and_moves_the_same():
    """A coarse cloth folded onto itself, its layers 0.2 mm apart (within the contact distance of 0.3 mm): most
    of the candidates join two segments whose ends are all slaved. The passes leave those out
    (SelfCollision._worked: exactly the pairs with an end of inverse mass > 0), and the positions are those of
    passes over every candidate, bit for bit, while the passes push the pairs they can move."""
    from fraytool.sim.solver import SolverExplicitPBD

    runs = []
    for skip in (True, False):
        model, state, _ = _folded_coarse_cloth(0.0006, 0.0002)
        solver = SolverExplicitPBD(model)
        stage = solver.self_collision
        stage._skip_fixed = skip
        left_out = [0]
        mark = stage._mark_self_contact

        def after_the_passes(state_, coarse, mark=mark, stage=stage, left_out=left_out, skip=skip):
            """Before the Refinement stage frees the slaved crossings in contact."""
            if skip:
                cand, w = stage._cand, state_.particle_inv_mass
                sa, sb = state_.spring_particle_a, state_.spring_particle_b
                movable = (w[sa[cand[:, 0]]] > 0) | (w[sb[cand[:, 0]]] > 0) | (w[sa[cand[:, 1]]] > 0) | (
                    w[sb[cand[:, 1]]] > 0)
                assert np.array_equal(stage._worked(state_), cand[movable])
                left_out[0] = max(left_out[0], len(cand) - len(stage._worked(state_)))
            mark(state_, coarse)

        stage._mark_self_contact = after_the_passes
        for _ in range(5):
            solver.step(state, 1e-4)
        assert stage.proximity_total > 0  # the passes moved pairs
        runs.append((state.particle_position_m.copy(), left_out[0]))
    assert runs[0][1] > 100  # pairs of two slaved segments were left out
    assert np.array_equal(runs[0][0], runs[1][0])


def test_a_coarse_cloth_folded_onto_itself_refines_where_it_touches_and_stays_apart():
    """The coarse layers 0.2 mm apart, within the contact distance (0.3 mm): their slaved crossings cannot be
    pushed, so the cells holding them refine on the first step (docs/multires.md, "When a cell refines"), and
    the layers are then kept apart at yarn resolution. Before, a segment from a node to a slaved crossing touched near
    its slaved end moved the node by the gap over (1 - s): the cloth blew up on its first step."""
    from fraytool.sim.solver import SolverExplicitPBD

    model, state, normal = _folded_coarse_cloth(0.0006, 0.0002)
    assert not state.coarse_cell_refined.any()
    solver = SolverExplicitPBD(model)
    solver.step(state, 1e-4)
    assert state.coarse_cell_refined.all()  # every cell of both layers touches the other layer
    for _ in range(39):
        solver.step(state, 1e-4)
    speed = np.linalg.norm(state.particle_velocity_m_s[:model.crossing_count], axis=1)
    assert np.isfinite(speed).all() and speed.max() < 2.0  # (the fold's own bend alone: 0.6 m/s)
    grid, x = model.crossing_grid(), state.particle_position_m
    height = np.array([(x[grid[jj]] - x[grid[16 - jj]]) @ normal for jj in range(9, 17)])
    assert height.min() > 0.0  # the upper layer is still over the lower one


def test_fold_pile_at_factor_4_stays_coarse_until_its_layers_touch():
    """fold_pile (two bars fold a cloth over itself) as a coarse model: nothing strains it past the refine
    strain, so it stays coarse until the fold brings one layer onto the other; then the cells in contact refine
    (docs/multires.md, "When a cell refines"), and the shot ends calm, every position finite."""
    from fraytool.scene import load_scene
    from fraytool.sim.simulation import Simulation

    sim = Simulation(load_scene(ROOT / "scenes" / "fold_pile.toml", [("cloth.multires.factor", 4)]))
    refined = []
    for _ in range(sim.spec.time.frames):
        sim.advance_frame()
        refined.append(int(sim.state.coarse_cell_refined.sum()))
    cells = sim.state.coarse_cell_refined.size
    assert refined[29] == 0 and refined[-1] == cells  # coarse through the first half, refined where it folded
    speed = np.linalg.norm(sim.state.particle_velocity_m_s, axis=1)
    assert np.isfinite(sim.state.particle_position_m).all() and speed.max() < 1.0
