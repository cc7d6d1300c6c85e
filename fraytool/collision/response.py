"""Self-collision response between yarn segments (METHOD.md §4.2), plugged into the solver.

Runs after the rigid-body pass, on the live structural springs (yarn segments), each swept from its
start-of-step to its current end points. Three parts, as in Bridson, Fedkiw, Anderson 2002
("Robust treatment of collisions, contact and friction for cloth animation", §6-7):

1. proximity: pairs closer than the contact distance d_c at the end of the step (broad phase on the
   end positions) are pushed apart along their separation to exactly d_c;
2. collisions: the interval CCD at thickness 0 (fraytool.collision.ccd) on the candidate pairs of
   a swept-box spatial hash inflated by a slack of spacing/4, rebuilt only when a particle has
   moved further than the slack since the build or a split re-attached a spring, so the hash runs
   every few steps, not every step, finds pairs whose centre lines meet during the step, i.e. that pass
   through each other. For each, in a fixed order (deterministic): the normal n is the direction
   between the closest points a = (1-s) x1 + s x2 and b = (1-u) x3 + u x4 at the contact time t
   (the side each yarn came from; falling back to the start of the step, then to the cross product
   of the segments), and an inelastic position correction moves the end points along n by
       Δx1 = (1-s) w1 λ n,  Δx2 = s w2 λ n,  Δx3 = -(1-u) w3 λ n,  Δx4 = -u w4 λ n,
       λ = (d_c - (a - b)·n) / ((1-s)² w1 + s² w2 + (1-u)² w3 + u² w4)
   (w = inverse masses), which puts the closest points exactly d_c apart; friction reduces the
   tangential relative displacement over the step by μ x (normal correction), Coulomb-style.
   Detection runs again on the corrected positions, up to `iterations` passes;
3. failsafe: pairs still crossing after the last pass return to their start-of-step positions
   (which did not cross), round after round until none crosses; the step counts as a cap hit.
   Yarns therefore never pass through each other.

The contact distance is d_c = T/2: connected mass couples already keep their weft and warp T apart
(§3.3), so d_c < T leaves those resting contacts alone. Velocities follow from the corrected
positions in the solver's post-process (v = (x - x_prev)/dt), which makes the response inelastic.
"""
from __future__ import annotations

import math

import numba as nb
import numpy as np

from fraytool.segments import segment_closest_params

from fraytool.collision.broadphase import find_candidate_pairs_kernel
from fraytool.collision.ccd import edge_edge_ccd_kernel
from fraytool.sim.model import STRUCT_WARP, STRUCT_WEFT, Model

CONTACT_FRACTION = 0.5
"""d_c = CONTACT_FRACTION x thickness."""


@nb.njit(cache=True, fastmath=False, inline="always")
def _dot(u, v):
    """u . v of two 3-vectors (no BLAS: numba's `@` needs SciPy)."""
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


@nb.njit(cache=True, fastmath=False)
def closest_parameters(p1, p2, p3, p4):
    """Parameters (s, u) in [0, 1]^2 of the closest points of segments p1p2 and p3p4."""
    return segment_closest_params(p1[0], p1[1], p1[2], p2[0], p2[1], p2[2],
                                  p3[0], p3[1], p3[2], p4[0], p4[1], p4[2])


@nb.njit(cache=True, fastmath=False)
def _normal(xs, xe, i1, i2, i3, i4, t):
    """Unit separation normal of the pair at time t (see the module docstring, step 1)."""
    for k in range(2):
        tt = t if k == 0 else 0.0
        p1 = xs[i1] + tt * (xe[i1] - xs[i1])
        p2 = xs[i2] + tt * (xe[i2] - xs[i2])
        p3 = xs[i3] + tt * (xe[i3] - xs[i3])
        p4 = xs[i4] + tt * (xe[i4] - xs[i4])
        s, u = closest_parameters(p1, p2, p3, p4)
        d = (1.0 - s) * p1 + s * p2 - (1.0 - u) * p3 - u * p4
        length = math.sqrt(_dot(d, d))
        if length > 1e-12:
            return d / length
    n = np.cross(xs[i2] - xs[i1], xs[i4] - xs[i3])
    length = math.sqrt(_dot(n, n))
    if length > 1e-300:
        return n / length
    return np.array([0.0, 0.0, 1.0])


@nb.njit(cache=True, fastmath=False)
def _correct_pair(contact_distance_m, friction, x_start, i1, i2, i3, i4, n, particle_inv_mass, x_end):
    """Move the four end points so the closest points are contact_distance_m apart along n, with
    friction on the tangential relative motion (module docstring, steps 2-3). Returns True if moved."""
    s, u = closest_parameters(x_end[i1], x_end[i2], x_end[i3], x_end[i4])
    w1, w2, w3, w4 = particle_inv_mass[i1], particle_inv_mass[i2], particle_inv_mass[i3], particle_inv_mass[i4]
    denom = (1.0 - s) ** 2 * w1 + s * s * w2 + (1.0 - u) ** 2 * w3 + u * u * w4
    if denom == 0.0:
        return False  # all four ends held by bodies: nothing can move
    a = (1.0 - s) * x_end[i1] + s * x_end[i2]
    b = (1.0 - u) * x_end[i3] + u * x_end[i4]
    gap = _dot(a - b, n)
    if gap >= contact_distance_m:
        return False
    lam = (contact_distance_m - gap) / denom
    a0 = (1.0 - s) * x_start[i1] + s * x_start[i2]
    b0 = (1.0 - u) * x_start[i3] + u * x_start[i4]
    rel = (a - a0) - (b - b0)
    tang = rel - _dot(rel, n) * n
    tl = math.sqrt(_dot(tang, tang))
    corr = lam * denom  # normal correction of the relative position
    scale = 0.0
    if tl > 0.0:
        scale = 1.0 if tl <= friction * corr else friction * corr / tl
    r = lam * n - (scale / denom) * tang  # relative correction, split barycentrically
    x_end[i1] += (1.0 - s) * w1 * r
    x_end[i2] += s * w2 * r
    x_end[i3] -= (1.0 - u) * w3 * r
    x_end[i4] -= u * w4 * r
    return True


@nb.njit(cache=True, fastmath=False)
def respond_pairs(
    # model
    contact_distance_m, friction,
    # state in
    x_start, pairs, t_hit, spring_particle_a, spring_particle_b, particle_inv_mass,
    # state in/out
    x_end,
):
    """Resolve colliding pairs (CCD hits at times t_hit): normal from the contact time, then the
    inelastic correction with friction. Returns the number of pairs moved."""
    moved = 0
    for k in range(pairs.shape[0]):
        i = pairs[k, 0]
        j = pairs[k, 1]
        i1, i2 = spring_particle_a[i], spring_particle_b[i]
        i3, i4 = spring_particle_a[j], spring_particle_b[j]
        n = _normal(x_start, x_end, i1, i2, i3, i4, t_hit[k])
        if _correct_pair(contact_distance_m, friction, x_start, i1, i2, i3, i4, n, particle_inv_mass, x_end):
            moved += 1
    return moved


@nb.njit(cache=True, fastmath=False)
def repel_close_pairs(
    # model
    contact_distance_m, friction,
    # state in
    x_start, candidates, spring_particle_a, spring_particle_b, spring_alive, particle_inv_mass,
    # state in/out
    x_end,
):
    """Proximity pass: candidate pairs whose segments end the step closer than the contact
    distance are pushed apart along their end-of-step separation. Returns the pairs moved."""
    moved = 0
    for k in range(candidates.shape[0]):
        i = candidates[k, 0]
        j = candidates[k, 1]
        if not (spring_alive[i] and spring_alive[j]):
            continue  # cut since the candidates were built
        i1, i2 = spring_particle_a[i], spring_particle_b[i]
        i3, i4 = spring_particle_a[j], spring_particle_b[j]
        s, u = closest_parameters(x_end[i1], x_end[i2], x_end[i3], x_end[i4])
        d = (1.0 - s) * x_end[i1] + s * x_end[i2] - (1.0 - u) * x_end[i3] - u * x_end[i4]
        dist = math.sqrt(_dot(d, d))
        if dist >= contact_distance_m:
            continue
        n = d / dist if dist > 1e-12 else _normal(x_start, x_end, i1, i2, i3, i4, 0.0)
        if _correct_pair(contact_distance_m, friction, x_start, i1, i2, i3, i4, n, particle_inv_mass, x_end):
            moved += 1
    return moved


@nb.njit(cache=True, fastmath=False)
def ccd_pairs(x_start, x_end, candidates, spring_particle_a, spring_particle_b, spring_alive):
    """Narrow phase at thickness 0 on candidate pairs: those whose centre lines meet during the
    step, (K, 2) int32, and their earliest contact times (K,)."""
    hit = np.zeros(candidates.shape[0], np.bool_)
    t_hit = np.ones(candidates.shape[0])
    for k in range(candidates.shape[0]):
        i = candidates[k, 0]
        j = candidates[k, 1]
        if not (spring_alive[i] and spring_alive[j]):
            continue  # cut since the candidates were built
        i1, i2 = spring_particle_a[i], spring_particle_b[i]
        i3, i4 = spring_particle_a[j], spring_particle_b[j]
        hit[k], t_hit[k] = edge_edge_ccd_kernel(x_start[i1], x_start[i2], x_start[i3], x_start[i4],
                                                x_end[i1], x_end[i2], x_end[i3], x_end[i4], 0.0)
    return candidates[hit].copy(), t_hit[hit].copy()


@nb.njit(cache=True, fastmath=False)
def segment_boxes(x_start, x_end, spring_particle_a, spring_particle_b, segments):
    """Axis-aligned boxes (lo, hi), shape (len(segments), 3) each, of the listed segments swept
    from x_start to x_end."""
    lo = np.empty((segments.shape[0], 3))
    hi = np.empty((segments.shape[0], 3))
    for k in range(segments.shape[0]):
        a = spring_particle_a[segments[k]]
        b = spring_particle_b[segments[k]]
        for d in range(3):
            lo[k, d] = min(min(x_start[a, d], x_start[b, d]), min(x_end[a, d], x_end[b, d]))
            hi[k, d] = max(max(x_start[a, d], x_start[b, d]), max(x_end[a, d], x_end[b, d]))
    return lo, hi


@nb.njit(cache=True, fastmath=False)
def segments_within(x_start, x_end, spring_particle_a, spring_particle_b, spring_alive, segments, box_lo, box_hi,
                    slack):
    """True if every live listed segment's end points, at the start and the end of the step, lie
    within `slack` of its build box."""
    for k in range(segments.shape[0]):
        s = segments[k]
        if not spring_alive[s]:
            continue  # a cut segment collides with nothing
        for p in (spring_particle_a[s], spring_particle_b[s]):
            for d in range(3):
                for x in (x_start[p, d], x_end[p, d]):
                    if x < box_lo[k, d] - slack or x > box_hi[k, d] + slack:
                        return False
    return True


@nb.njit(cache=True, fastmath=False)
def freeze_pairs(pairs, spring_particle_a, spring_particle_b, particle_inv_mass, x_start, x_end):
    """Failsafe: pairs still crossing after the last pass go back to their start-of-step positions
    (which did not cross), as in an inelastic impact zone that stops for this step."""
    for k in range(pairs.shape[0]):
        for s in (pairs[k, 0], pairs[k, 1]):
            for p in (spring_particle_a[s], spring_particle_b[s]):
                if particle_inv_mass[p] > 0.0:
                    x_end[p] = x_start[p]


def yarn_segment_ids(model: Model) -> np.ndarray:
    """Yarn id of every spring slot: weft yarn j -> j, warp yarn i -> weft_yarns + i, others -1."""
    yarn = np.full(model.spring_count, -1, np.int32)
    weft = model.weft_structural_spring
    warp = model.warp_structural_spring
    yarn[weft.ravel()] = np.repeat(np.arange(weft.shape[0], dtype=np.int32), weft.shape[1])
    yarn[warp.ravel()] = model.weft_yarns + np.repeat(np.arange(warp.shape[0], dtype=np.int32), warp.shape[1])
    assert ((model.spring_kind == STRUCT_WEFT) | (model.spring_kind == STRUCT_WARP)).sum() == (yarn >= 0).sum()
    return yarn


class SelfCollision:
    """The self-collision pass: detect (broad + interval CCD), respond, repeat up to a cap."""

    def __init__(self, model: Model):
        self.model = model
        self.spring_yarn = yarn_segment_ids(model)
        self.contact_distance_m = CONTACT_FRACTION * model.thickness_m
        self.iterations = model.self_collision_iterations
        self.slack_m = 0.25 * model.spacing_m
        self._cand = None
        self.yarn_segments = np.nonzero(self.spring_yarn >= 0)[0].astype(np.int32)
        self._box_lo = self._box_hi = None
        self.broad_phase_builds = 0
        """Extra broad-phase margin: candidates stay valid while corrections move no particle further."""
        self.friction = model.self_collision_friction
        self.pairs_last = 0
        """Crossing pairs found by the first CCD pass of the last step."""
        self.proximity_last = 0
        """Pairs pushed apart by the proximity pass of the last step."""
        self.proximity_total = 0
        self.pairs_total = 0
        self.cap_hits = 0
        """Steps that still had colliding pairs after the last pass."""

    def _build(self, state, prev_position_m) -> None:
        """Broad phase on the step's swept boxes inflated by d_c/2 + slack. The candidates stay
        valid for later steps and after corrections while every end point of every yarn segment
        stays within the slack of the box it had at the build (a split that re-attaches a segment
        to a couple mass T/2 away keeps it): every box of a later step, inflated by d_c/2, then
        lies inside its build box, so no pair outside the candidates can touch."""
        x = state.particle_position_m
        self._cand = find_candidate_pairs_kernel(prev_position_m, x, state.spring_particle_a,
                                                 state.spring_particle_b, state.spring_alive, self.spring_yarn,
                                                 0.5 * self.contact_distance_m + self.slack_m, 0.0)
        self._box_lo, self._box_hi = segment_boxes(prev_position_m, x, state.spring_particle_a,
                                                   state.spring_particle_b, self.yarn_segments)
        self.broad_phase_builds += 1

    def _valid(self, state, prev_position_m) -> bool:
        return self._cand is not None and segments_within(
            prev_position_m, state.particle_position_m, state.spring_particle_a, state.spring_particle_b,
            state.spring_alive, self.yarn_segments, self._box_lo, self._box_hi, self.slack_m)

    def __call__(self, state, prev_position_m: np.ndarray, dt_s: float) -> None:
        x = state.particle_position_m
        a, b, w, alive = state.spring_particle_a, state.spring_particle_b, state.particle_inv_mass, state.spring_alive
        if not self._valid(state, prev_position_m):
            self._build(state, prev_position_m)
        self.proximity_last = repel_close_pairs(self.contact_distance_m, self.friction, prev_position_m, self._cand,
                                                a, b, alive, w, x)
        self.proximity_total += self.proximity_last
        self.pairs_last = 0
        for it in range(self.iterations + 1):
            if (self.proximity_last or it) and not self._valid(state, prev_position_m):
                self._build(state, prev_position_m)
            pairs, t = ccd_pairs(prev_position_m, x, self._cand, a, b, alive)
            if it == 0:
                self.pairs_last = len(pairs)
                self.pairs_total += len(pairs)
            if len(pairs) == 0:
                return
            if it == self.iterations:
                break
            respond_pairs(self.contact_distance_m, self.friction, prev_position_m, pairs, t, a, b, w, x)
        self.cap_hits += 1
        while len(pairs):  # each round returns more particles to where they started: it ends
            freeze_pairs(pairs, a, b, w, prev_position_m, x)
            self._build(state, prev_position_m)
            pairs, _ = ccd_pairs(prev_position_m, x, self._cand, a, b, alive)

    def summary(self) -> dict:
        return {"self_collision_pairs": self.pairs_total, "self_collision_proximity_pushes": self.proximity_total,
                "self_collision_cap_hits": self.cap_hits}


def attach_self_collision(solver) -> None:
    """Plug the self-collision pass into a SolverExplicitPBD."""
    solver.self_collision = SelfCollision(solver.model)
