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

from fraytool.collision.narrow import (SEPARATION_REL, _apart_at_end, _apart_boxes_end, _outside_reach, _plane_gap,
                                      _share_end, end_segment_boxes)
from fraytool.collision.segment import segment_closest_params


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
    x_start, pairs, t_hit, spring_particle_a, spring_particle_b, particle_inv_mass, reach,
    # state in/out
    x_end,
    # out: (P,) flags; scratch: (P, 3)
    changed, before,
):
    """Resolve colliding pairs (CCD hits at times t_hit): normal from the contact time, then the
    inelastic correction with friction. Returns the number of pairs moved and whether a moved
    particle left its ``reach`` (the candidates then need a check); ``changed[p]`` tells whether
    particle p ends the call at another position than it started it (as ``x != x_before``, without
    copying x)."""
    moved = 0
    left = False
    changed[:] = False  # first used as "seen": its position before the call is in ``before``
    touched = np.empty(4 * pairs.shape[0], np.int64)
    n_touched = 0
    for k in range(pairs.shape[0]):
        i = pairs[k, 0]
        j = pairs[k, 1]
        i1, i2 = spring_particle_a[i], spring_particle_b[i]
        i3, i4 = spring_particle_a[j], spring_particle_b[j]
        for p in (i1, i2, i3, i4):
            if not changed[p]:
                changed[p] = True
                before[p, 0] = x_end[p, 0]
                before[p, 1] = x_end[p, 1]
                before[p, 2] = x_end[p, 2]
                touched[n_touched] = p
                n_touched += 1
        n = _normal(x_start, x_end, i1, i2, i3, i4, t_hit[k])
        if _correct_pair(contact_distance_m, friction, x_start, i1, i2, i3, i4, n, particle_inv_mass, x_end):
            moved += 1
            left = left or _outside_reach(x_end, reach, i1, i2, i3, i4)
    for q in range(n_touched):
        p = touched[q]
        changed[p] = x_end[p, 0] != before[p, 0] or x_end[p, 1] != before[p, 1] or x_end[p, 2] != before[p, 2]
    return moved, left


@nb.njit(cache=True, fastmath=False)
def repel_close_pairs(
    # model
    contact_distance_m, friction,
    # state in
    x_start, candidates, first, spring_particle_a, spring_particle_b, spring_alive, particle_inv_mass, reach,
    # state in/out
    x_end,
    # scratch: the segments listed (every segment of the candidates), (S, >= 6) boxes, (P,) flags
    segments, box, dirty,
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
    particles (``dirty``): same answers, bit for bit, as computing them per pair."""
    moved = 0
    seg = np.empty((4, 3))
    end_segment_boxes(x_end, spring_particle_a, spring_particle_b, segments, box)
    dirty[:] = False
    for k in range(first, candidates.shape[0]):
        i = candidates[k, 0]
        j = candidates[k, 1]
        if not (spring_alive[i] and spring_alive[j]):
            continue  # cut since the candidates were built
        i1, i2 = spring_particle_a[i], spring_particle_b[i]
        i3, i4 = spring_particle_a[j], spring_particle_b[j]
        if not (dirty[i1] or dirty[i2] or dirty[i3] or dirty[i4]):
            if _apart_boxes_end(box, i, j, contact_distance_m):
                continue  # (the distance below would be >= d_c)
            if _share_end(i1, i2, i3, i4):
                continue
        elif _share_end(i1, i2, i3, i4) or _apart_at_end(x_end, i1, i2, i3, i4, contact_distance_m):
            continue  # (the distance below would be >= d_c)
        gap, scale = _plane_gap(x_end, x_end, i1, i2, i3, i4, seg)
        if gap > contact_distance_m + SEPARATION_REL * scale:
            continue  # likewise
        s, u = closest_parameters(x_end[i1], x_end[i2], x_end[i3], x_end[i4])
        d = (1.0 - s) * x_end[i1] + s * x_end[i2] - (1.0 - u) * x_end[i3] - u * x_end[i4]
        dist = math.sqrt(_dot(d, d))
        if dist >= contact_distance_m:
            continue
        n = d / dist if dist > 1e-12 else _normal(x_start, x_end, i1, i2, i3, i4, 0.0)
        if _correct_pair(contact_distance_m, friction, x_start, i1, i2, i3, i4, n, particle_inv_mass, x_end):
            moved += 1
            dirty[i1] = True
            dirty[i2] = True
            dirty[i3] = True
            dirty[i4] = True
            if _outside_reach(x_end, reach, i1, i2, i3, i4):
                return moved, k
    return moved, -1


@nb.njit(cache=True, fastmath=False)
def freeze_pairs(pairs, spring_particle_a, spring_particle_b, particle_inv_mass, x_start, x_end):
    """Failsafe: the free end particles of pairs still crossing after the last pass go back to their
    start-of-step positions (which did not cross), as in an inelastic impact zone that stops for
    this step. Returns how many particles moved (0: every free end was already back, so another
    round would change nothing)."""
    restored = 0
    for k in range(pairs.shape[0]):
        for s in (pairs[k, 0], pairs[k, 1]):
            for p in (spring_particle_a[s], spring_particle_b[s]):
                if particle_inv_mass[p] > 0.0:
                    if x_end[p, 0] != x_start[p, 0] or x_end[p, 1] != x_start[p, 1] or x_end[p, 2] != x_start[p, 2]:
                        restored += 1
                    x_end[p] = x_start[p]
    return restored
