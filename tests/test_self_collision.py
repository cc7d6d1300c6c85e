"""Self-collision: a cloth folded onto itself with self-collision on; by brute force over every
step, no pair of yarn segments crosses another. The checker is independent of the solver's CCD:
all pairs, swept boxes in NumPy, then the coplanarity cubic solved with numpy.roots and the
segment distance at each real root in [0, 1]."""
from pathlib import Path

import numpy as np
import pytest

from helpers import pulled_strip_text

from fraytool.scene import parse_scene
from fraytool.sim import Simulation
from fraytool.kinds import STRUCT_WARP, STRUCT_WEFT

ROOT = Path(__file__).resolve().parent.parent


def _segment_distance(p1, p2, p3, p4):
    """Distance between segments p1p2 and p3p4 (dense sampling of one parameter + exact other)."""
    s = np.linspace(0.0, 1.0, 201)
    a = p1[None] + s[:, None] * (p2 - p1)[None]
    d = p4 - p3
    u = np.clip(((a - p3) @ d) / max(d @ d, 1e-300), 0.0, 1.0)
    b = p3 + u[:, None] * d
    return np.linalg.norm(a - b, axis=1).min()


def crossed_pairs(x0, x1, sa, sb, tol):
    """Pairs of segments (given by end indices) whose centre lines meet during linear motion."""
    lo = np.minimum(np.minimum(x0[sa], x0[sb]), np.minimum(x1[sa], x1[sb])) - tol
    hi = np.maximum(np.maximum(x0[sa], x0[sb]), np.maximum(x1[sa], x1[sb])) + tol
    overlap = np.all((lo[:, None] <= hi[None]) & (lo[None] <= hi[:, None]), axis=2)
    share = ((sa[:, None] == sa[None]) | (sa[:, None] == sb[None]) | (sb[:, None] == sa[None])
             | (sb[:, None] == sb[None]))
    i, j = np.nonzero(np.triu(overlap & ~share, 1))
    found = []
    for a, b in zip(i, j):
        p = [x0[sa[a]], x0[sb[a]], x0[sa[b]], x0[sb[b]]]
        q = [x1[sa[a]], x1[sb[a]], x1[sa[b]], x1[sb[b]]]
        v = [qq - pp for pp, qq in zip(p, q)]
        # f(t) = x31(t) . (x21(t) x x43(t)); expand as a cubic by sampling 4 points exactly
        ts = np.array([0.0, 1 / 3, 2 / 3, 1.0])
        vals = []
        for t in ts:
            x = [pp + t * vv for pp, vv in zip(p, v)]
            vals.append(np.dot(x[2] - x[0], np.cross(x[1] - x[0], x[3] - x[2])))
        coef = np.polyfit(ts, vals, 3)
        roots = np.roots(coef) if np.abs(coef).max() > 0 else np.array([0.0])
        candidates = [r.real for r in roots if abs(r.imag) < 1e-9 and -1e-9 <= r.real <= 1 + 1e-9]
        for t in candidates + [0.0, 1.0]:
            x = [pp + t * vv for pp, vv in zip(p, v)]
            if _segment_distance(*x) < tol:
                found.append((int(a), int(b), float(t)))
                break
    return found


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
        crossings += crossed_pairs(x0, x1, sa, sb, 1e-9)
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
    """The brute-force checker can fail: two segments moving through each other are caught, the
    same segments stopping short are not."""
    x0 = np.array([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.5], [0.0, 1.0, 0.5]])
    through = x0.copy()
    through[2:, 2] = -0.5
    short = x0.copy()
    short[2:, 2] = 0.1
    sa, sb = np.array([0, 2]), np.array([1, 3])
    assert crossed_pairs(x0, through, sa, sb, 1e-9) == [(0, 1, pytest.approx(0.5))]
    assert crossed_pairs(x0, short, sa, sb, 1e-9) == []




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
        need = _pairs_the_step_can_act_on(state, prev, sc.spring_yarn, sc.contact_distance_m)
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
