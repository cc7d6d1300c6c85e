"""Self-collision response kernels for yarn segments (docs/method.md §4.2): proximity push, inelastic
correction with friction, failsafe freeze. The stage that runs them, with the candidates kept across
steps, is fraytool.sim.stages.self_collision.

Runs after the rigid-body pass, on the live structural springs (yarn segments), each swept from its
start-of-step to its current end points. Three parts, as in Bridson, Fedkiw, Anderson 2002
("Robust treatment of collisions, contact and friction for cloth animation", §6-7):

1. proximity: pairs closer than the contact distance d_c at the end of the step (among the
   candidates below) are pushed apart along their separation to exactly d_c;
2. collisions: the interval CCD at thickness 0 (fraytool.collision.ccd) finds the candidate pairs
   whose centre lines meet during the step, i.e. that pass through each other. The candidates
   come from the swept-box broad phase (fraytool.collision.broadphase), kept across steps: see
   "Candidates" below. For each, in a fixed order (deterministic): the normal n is the direction
   between the closest points a = (1-s) x1 + s x2 and b = (1-u) x3 + u x4 at the contact time t
   (the side each yarn came from; falling back to the start of the step, then to the cross product
   of the segments), and an inelastic position correction moves the end points along n by
       Δx1 = (1-s) w1 λ n,  Δx2 = s w2 λ n,  Δx3 = -(1-u) w3 λ n,  Δx4 = -u w4 λ n,
       λ = (d_c - (a - b)·n) / ((1-s)² w1 + s² w2 + (1-u)² w3 + u² w4)
   (w = inverse masses), which puts the closest points exactly d_c apart; friction reduces the
   tangential relative displacement over the step by μ x (normal correction), Coulomb-style.
   Detection runs again on the corrected positions, up to `iterations` passes;
3. failsafe: pairs still crossing after the last pass return to their start-of-step positions
   (which did not cross), round after round until none crosses, at most FAILSAFE_ROUNDS rounds;
   the step counts as a cap hit. Past the cap the stage gives up: every free particle returns to
   its start-of-step position (the stage module, "Failsafe"). Yarns therefore never pass through
   each other, unless ends held by bodies push them through (then the stage says so).

The contact distance is d_c = T/2: connected mass couples already keep their weft and warp T apart
(§3.3), so d_c < T leaves those resting contacts alone. Velocities follow from the corrected
positions in the solver's post-process (v = (x - x_prev)/dt), which makes the response inelastic.
"""
from __future__ import annotations

import math

import numba as nb
import numpy as np

from fraytool.collision.narrow import (_apart_at_end, _apart_boxes_end, _lines_apart, _outside_reach, _share_end,
                                       end_segment_boxes, segment_cross)
from fraytool.geometry.segments import segment_closest_params


LEVER_MAX = 1.0
"""In a coarse model, a correction moves no end particle farther along the normal than LEVER_MAX times the gap it
closes (``_correct_pair``; friction adds its tangential part, at most mu times that). A segment from a coarse
node to a slaved crossing, touched near the slaved end, would move the node by the gap over (1 - s): without
bound as s -> 1 (a coarse cloth folded flat onto itself blew up on its first step, before the Refinement stage
could refine the cells in contact). With equal masses and every end free an end moves at most 0.683 times the
gap (at s = 1 - sqrt(3)/2, u = 1/2), so the bound holds back pairs with an end that cannot move, and pairs of
unequal masses (a free crossing beside a node that carries its cell's mass): those are under-corrected, and the
next pass, the failsafe, or the refinement of their cells does the rest. The yarn-resolution model has no bound
(inf): a segment with an end held by a body keeps its full correction there, as it always had."""


@nb.njit(cache=True, fastmath=False)
def closest_parameters(p1, p2, p3, p4):
    """Parameters (s, u) in [0, 1]^2 of the closest points of segments p1p2 and p3p4."""
    return segment_closest_params(p1[0], p1[1], p1[2], p2[0], p2[1], p2[2],
                                  p3[0], p3[1], p3[2], p4[0], p4[1], p4[2])


@nb.njit(cache=True, fastmath=False)
def _normal(xs, xe, i1, i2, i3, i4, t):
    """Unit separation normal (n0, n1, n2) of the pair at time t (see the module docstring, step 1).
    Scalars throughout: no allocation per pair."""
    for k in range(2):
        tt = t if k == 0 else 0.0
        p10 = xs[i1, 0] + tt * (xe[i1, 0] - xs[i1, 0])
        p11 = xs[i1, 1] + tt * (xe[i1, 1] - xs[i1, 1])
        p12 = xs[i1, 2] + tt * (xe[i1, 2] - xs[i1, 2])
        p20 = xs[i2, 0] + tt * (xe[i2, 0] - xs[i2, 0])
        p21 = xs[i2, 1] + tt * (xe[i2, 1] - xs[i2, 1])
        p22 = xs[i2, 2] + tt * (xe[i2, 2] - xs[i2, 2])
        p30 = xs[i3, 0] + tt * (xe[i3, 0] - xs[i3, 0])
        p31 = xs[i3, 1] + tt * (xe[i3, 1] - xs[i3, 1])
        p32 = xs[i3, 2] + tt * (xe[i3, 2] - xs[i3, 2])
        p40 = xs[i4, 0] + tt * (xe[i4, 0] - xs[i4, 0])
        p41 = xs[i4, 1] + tt * (xe[i4, 1] - xs[i4, 1])
        p42 = xs[i4, 2] + tt * (xe[i4, 2] - xs[i4, 2])
        s, u = segment_closest_params(p10, p11, p12, p20, p21, p22, p30, p31, p32, p40, p41, p42)
        d0 = (1.0 - s) * p10 + s * p20 - (1.0 - u) * p30 - u * p40
        d1 = (1.0 - s) * p11 + s * p21 - (1.0 - u) * p31 - u * p41
        d2 = (1.0 - s) * p12 + s * p22 - (1.0 - u) * p32 - u * p42
        length = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        if length > 1e-12:
            return d0 / length, d1 / length, d2 / length
    c0, c1, c2 = segment_cross(xs, i1, i2, i3, i4)  # the cross product of the segments at the step start
    length = math.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
    if length > 1e-300:
        return c0 / length, c1 / length, c2 / length
    return 0.0, 0.0, 1.0


@nb.njit(cache=True, fastmath=False)
def _correct_pair(contact_distance_m, response_in, x_start, i1, i2, i3, i4, n0, n1, n2, particle_inv_mass, x_end_inout):
    """Move the four end points so the closest points are contact_distance_m apart along n, with
    friction on the tangential relative motion (module docstring, steps 2-3); `response_in`: (friction, the
    lever bound, LEVER_MAX in a coarse model and inf otherwise). Returns True if moved.
    Scalars throughout: no allocation per pair."""
    friction, lever_max = response_in
    s, u = closest_parameters(x_end_inout[i1], x_end_inout[i2], x_end_inout[i3], x_end_inout[i4])
    w1, w2, w3, w4 = particle_inv_mass[i1], particle_inv_mass[i2], particle_inv_mass[i3], particle_inv_mass[i4]
    denom = (1.0 - s) ** 2 * w1 + s * s * w2 + (1.0 - u) ** 2 * w3 + u * u * w4
    if denom == 0.0:
        return False  # all four ends held by bodies: nothing can move
    a0 = (1.0 - s) * x_end_inout[i1, 0] + s * x_end_inout[i2, 0]
    a1 = (1.0 - s) * x_end_inout[i1, 1] + s * x_end_inout[i2, 1]
    a2 = (1.0 - s) * x_end_inout[i1, 2] + s * x_end_inout[i2, 2]
    b0 = (1.0 - u) * x_end_inout[i3, 0] + u * x_end_inout[i4, 0]
    b1 = (1.0 - u) * x_end_inout[i3, 1] + u * x_end_inout[i4, 1]
    b2 = (1.0 - u) * x_end_inout[i3, 2] + u * x_end_inout[i4, 2]
    gap = (a0 - b0) * n0 + (a1 - b1) * n1 + (a2 - b2) * n2
    if gap >= contact_distance_m:
        return False
    lam = (contact_distance_m - gap) / denom
    # the lever: an end moves k lam along n (k below), up to (contact_distance_m - gap) / (1 - s) when the
    # segment's other end cannot move and the contact is near it; lever_max bounds it (LEVER_MAX)
    k_max = max(max((1.0 - s) * w1, s * w2), max((1.0 - u) * w3, u * w4))
    if k_max * lam > lever_max * (contact_distance_m - gap):
        lam = lever_max * (contact_distance_m - gap) / k_max
    # relative displacement of the closest points over the step
    r0 = (a0 - ((1.0 - s) * x_start[i1, 0] + s * x_start[i2, 0])) - (b0 - ((1.0 - u) * x_start[i3, 0] + u * x_start[i4, 0]))
    r1 = (a1 - ((1.0 - s) * x_start[i1, 1] + s * x_start[i2, 1])) - (b1 - ((1.0 - u) * x_start[i3, 1] + u * x_start[i4, 1]))
    r2 = (a2 - ((1.0 - s) * x_start[i1, 2] + s * x_start[i2, 2])) - (b2 - ((1.0 - u) * x_start[i3, 2] + u * x_start[i4, 2]))
    rn = r0 * n0 + r1 * n1 + r2 * n2
    t0 = r0 - rn * n0
    t1 = r1 - rn * n1
    t2 = r2 - rn * n2
    tl = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
    corr = lam * denom  # normal correction of the relative position
    scale = 0.0
    if tl > 0.0:
        scale = 1.0 if tl <= friction * corr else friction * corr / tl
    f = scale / denom
    c0 = lam * n0 - f * t0  # relative correction, split barycentrically
    c1 = lam * n1 - f * t1
    c2 = lam * n2 - f * t2
    k1 = (1.0 - s) * w1
    k2 = s * w2
    k3 = (1.0 - u) * w3
    k4 = u * w4
    x_end_inout[i1, 0] += k1 * c0
    x_end_inout[i1, 1] += k1 * c1
    x_end_inout[i1, 2] += k1 * c2
    x_end_inout[i2, 0] += k2 * c0
    x_end_inout[i2, 1] += k2 * c1
    x_end_inout[i2, 2] += k2 * c2
    x_end_inout[i3, 0] -= k3 * c0
    x_end_inout[i3, 1] -= k3 * c1
    x_end_inout[i3, 2] -= k3 * c2
    x_end_inout[i4, 0] -= k4 * c0
    x_end_inout[i4, 1] -= k4 * c1
    x_end_inout[i4, 2] -= k4 * c2
    return True


@nb.njit(cache=True, fastmath=False)
def respond_pairs(
    # model: the contact distance, (friction, lever bound) as _correct_pair
    contact_distance_m, response_in,
    # state in
    x_start, pairs, t_hit, spring_particle_a, spring_particle_b, particle_inv_mass, reach,
    # state in/out
    x_end_inout,
    # out: (P,) flags; scratch: (P, 3)
    changed_inout, before_inout,
):
    """Resolve colliding pairs (CCD hits at times t_hit): normal from the contact time, then the
    inelastic correction with friction. Returns the number of pairs moved and whether a moved
    particle left its ``reach`` (the candidates then need a check); ``changed[p]`` tells whether
    particle p ends the call at another position than it started it (as ``x != x_before``, without
    copying x)."""
    moved = 0
    left = False
    changed_inout[:] = False  # first used as "seen": its position before the call is in ``before``
    touched = np.empty(4 * pairs.shape[0], np.int64)
    n_touched = 0
    for k in range(pairs.shape[0]):
        i = pairs[k, 0]
        j = pairs[k, 1]
        i1, i2 = spring_particle_a[i], spring_particle_b[i]
        i3, i4 = spring_particle_a[j], spring_particle_b[j]
        for p in (i1, i2, i3, i4):
            if not changed_inout[p]:
                changed_inout[p] = True
                before_inout[p, 0] = x_end_inout[p, 0]
                before_inout[p, 1] = x_end_inout[p, 1]
                before_inout[p, 2] = x_end_inout[p, 2]
                touched[n_touched] = p
                n_touched += 1
        n0, n1, n2 = _normal(x_start, x_end_inout, i1, i2, i3, i4, t_hit[k])
        if _correct_pair(contact_distance_m, response_in, x_start, i1, i2, i3, i4, n0, n1, n2, particle_inv_mass,
                         x_end_inout):
            moved += 1
            left = left or _outside_reach(x_end_inout, reach, i1, i2, i3, i4)
    for q in range(n_touched):
        p = touched[q]
        changed_inout[p] = x_end_inout[p, 0] != before_inout[p, 0] or x_end_inout[p, 1] != before_inout[p, 1] or x_end_inout[p, 2] != before_inout[p, 2]
    return moved, left


@nb.njit(cache=True, fastmath=False)
def repel_close_pairs(
    # model: the contact distance, (friction, lever bound) as _correct_pair
    contact_distance_m, response_in,
    # state in: start-of-step positions, the candidate pairs and where to start in them, the springs'
    # (ends a, ends b, alive flags), inverse masses, each particle's reach
    x_start, candidates, first, springs_in, particle_inv_mass, reach,
    # state in/out
    x_end_inout,
    # the segments listed (every segment of the candidates) and their rows in the boxes (box_row[slot],
    # narrow.swept_segment_boxes); scratch: (the boxes (>= 6 columns), (P,) flags)
    listed_in, scratch_inout,
):
    """Proximity pass over ``candidates[first:]``, in their (sorted) order: pairs whose segments end
    the step closer than the contact distance are pushed apart along their end-of-step separation.
    Returns the pairs moved and ``stop``: -1 when the pass got to the end, else the index of the
    pair whose correction moved a particle out of its ``reach``; the pass stops right after it, as
    the candidates after it may then miss a pair that the correction brought close (the stage checks
    the candidates and goes on after that pair: its results do not depend on which candidates it
    kept from earlier steps).

    The end boxes of the listed ``segments`` are computed once (``end_segment_boxes``) and the axis
    pre-test reads them, as long as no correction of this call moved one of the pair's end
    particles (``dirty``): same answers, bit for bit, as computing them per pair. Then the distance
    between the two lines (``_lines_apart``, a lower bound of the segments' distance: it skips only
    pairs the distance test skips, without its divisions), then the closest distance itself
    decides. No allocation per pair."""
    spring_particle_a, spring_particle_b, spring_alive = springs_in
    segments, box_row = listed_in
    box_inout, dirty_inout = scratch_inout
    moved = 0
    end_segment_boxes(x_end_inout, spring_particle_a, spring_particle_b, segments, box_row, box_inout)
    dirty_inout[:] = False
    for k in range(first, candidates.shape[0]):
        i = candidates[k, 0]
        j = candidates[k, 1]
        if not (spring_alive[i] and spring_alive[j]):
            continue  # cut since the candidates were built
        i1, i2 = spring_particle_a[i], spring_particle_b[i]
        i3, i4 = spring_particle_a[j], spring_particle_b[j]
        if not (dirty_inout[i1] or dirty_inout[i2] or dirty_inout[i3] or dirty_inout[i4]):
            if _apart_boxes_end(box_inout, box_row[i], box_row[j], contact_distance_m):
                continue  # (the distance below would be >= d_c)
            if _share_end(i1, i2, i3, i4):
                continue
        elif _share_end(i1, i2, i3, i4) or _apart_at_end(x_end_inout, i1, i2, i3, i4, contact_distance_m):
            continue  # (the distance below would be >= d_c)
        if _lines_apart(x_end_inout, i1, i2, i3, i4, contact_distance_m):
            continue  # (likewise: fraytool.collision.narrow)
        s, u = closest_parameters(x_end_inout[i1], x_end_inout[i2], x_end_inout[i3], x_end_inout[i4])
        d0 = (1.0 - s) * x_end_inout[i1, 0] + s * x_end_inout[i2, 0] - (1.0 - u) * x_end_inout[i3, 0] - u * x_end_inout[i4, 0]
        d1 = (1.0 - s) * x_end_inout[i1, 1] + s * x_end_inout[i2, 1] - (1.0 - u) * x_end_inout[i3, 1] - u * x_end_inout[i4, 1]
        d2 = (1.0 - s) * x_end_inout[i1, 2] + s * x_end_inout[i2, 2] - (1.0 - u) * x_end_inout[i3, 2] - u * x_end_inout[i4, 2]
        dist = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        if dist >= contact_distance_m:
            continue
        if dist > 1e-12:
            n0, n1, n2 = d0 / dist, d1 / dist, d2 / dist
        else:
            n0, n1, n2 = _normal(x_start, x_end_inout, i1, i2, i3, i4, 0.0)
        if _correct_pair(contact_distance_m, response_in, x_start, i1, i2, i3, i4, n0, n1, n2, particle_inv_mass,
                         x_end_inout):
            moved += 1
            dirty_inout[i1] = True
            dirty_inout[i2] = True
            dirty_inout[i3] = True
            dirty_inout[i4] = True
            if _outside_reach(x_end_inout, reach, i1, i2, i3, i4):
                return moved, k
    return moved, -1


@nb.njit(cache=True, fastmath=False)
def freeze_pairs(pairs, spring_particle_a, spring_particle_b, particle_inv_mass, x_start, x_end_inout):
    """Failsafe: the free end particles of pairs still crossing after the last pass go back to their
    start-of-step positions (which did not cross), as in an inelastic impact zone that stops for
    this step. Returns how many particles moved (0: every free end was already back, so another
    round would change nothing)."""
    restored = 0
    for k in range(pairs.shape[0]):
        for s in (pairs[k, 0], pairs[k, 1]):
            for p in (spring_particle_a[s], spring_particle_b[s]):
                if particle_inv_mass[p] > 0.0:
                    if x_end_inout[p, 0] != x_start[p, 0] or x_end_inout[p, 1] != x_start[p, 1] or x_end_inout[p, 2] != x_start[p, 2]:
                        restored += 1
                    x_end_inout[p] = x_start[p]
    return restored


@nb.njit(cache=True, fastmath=False)
def mark_close_pairs(candidates, springs_in, particle_inv_mass, particle_position_m, distance_m, fixed_only,
                     touching_out):
    """touching_out[p] = True for the ends of every candidate pair of live segments (``springs_in``: the springs'
    ends a, ends b, alive flags) that share no end and lie closer than `distance_m` (closest points of the two
    segments, positions as they are); touching_out is not cleared. All four ends, or with `fixed_only` only those
    of inverse mass 0 (held, or slaved to coarse nodes), and only pairs with such an end.
    - All four: where the cloth touches itself, for the woven-strain figure away from contact
      (fraytool.sim.pieces.woven_strain_away, at twice the contact distance).
    - Fixed only: where a coarse cloth touches itself or another yarn, the passes cannot move its slaved
      crossings, so the Refinement stage refines their cells (fraytool.sim.stages.multires). Pairs within the
      contact distance are in the candidates whenever these were built (fraytool.collision.candidates), so the
      marks do not depend on when that was.
    The two pre-tests skip only pairs the distance test skips (fraytool.collision.narrow)."""
    spring_particle_a, spring_particle_b, spring_alive = springs_in
    x = particle_position_m
    w = particle_inv_mass
    for k in range(candidates.shape[0]):
        i = candidates[k, 0]
        j = candidates[k, 1]
        if not (spring_alive[i] and spring_alive[j]):
            continue
        i1, i2 = spring_particle_a[i], spring_particle_b[i]
        i3, i4 = spring_particle_a[j], spring_particle_b[j]
        if fixed_only and w[i1] > 0.0 and w[i2] > 0.0 and w[i3] > 0.0 and w[i4] > 0.0:
            continue  # the passes move every end of this pair
        if _share_end(i1, i2, i3, i4) or _apart_at_end(x, i1, i2, i3, i4, distance_m):
            continue
        if _lines_apart(x, i1, i2, i3, i4, distance_m):
            continue
        s, t = segment_closest_params(x[i1, 0], x[i1, 1], x[i1, 2], x[i2, 0], x[i2, 1], x[i2, 2],
                                      x[i3, 0], x[i3, 1], x[i3, 2], x[i4, 0], x[i4, 1], x[i4, 2])
        d2 = 0.0
        for d in range(3):
            v = (x[i1, d] + s * (x[i2, d] - x[i1, d])) - (x[i3, d] + t * (x[i4, d] - x[i3, d]))
            d2 += v * v
        if d2 < distance_m * distance_m:
            for p in (i1, i2, i3, i4):
                if not fixed_only or w[p] == 0.0:
                    touching_out[p] = True
