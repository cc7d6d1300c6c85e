"""Self-collision response between yarn segments (METHOD.md §4.2), plugged into the solver.

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
   (which did not cross), round after round until none crosses; the step counts as a cap hit.
   Yarns therefore never pass through each other.

The contact distance is d_c = T/2: connected mass couples already keep their weft and warp T apart
(§3.3), so d_c < T leaves those resting contacts alone. Velocities follow from the corrected
positions in the solver's post-process (v = (x - x_prev)/dt), which makes the response inelastic.

Candidates (kept across steps)
------------------------------
A build runs the broad phase on the live yarn segments, each swept from its start-of-step end
points to a look-ahead ``x + LOOKAHEAD_STEPS (x - x_prev)`` (the end points carried on at the
step's velocity; it contains x), its box B_i inflated by m = d_c/2 + slack, slack = SLACK_FRACTION
x spacing. Invariant: the candidates hold every pair of live segments that do not share an end
particle and whose boxes B_i + m and B_j + m overlap. They stay valid while every end point of
every live segment, at the start and at the end of the step (also after corrections), lies within
the slack of its B_i: the segment's box this step is then inside B_i + slack, so two segments
whose boxes this step, inflated by d_c/2, touch -- everything the proximity pass (closer than d_c
at the end) and the CCD (meeting during the step) can act on -- are candidates. The check runs at
the start of every step, on every particle against its reach (the intersection of B_i + slack over
the live segments ending at it), and after corrections on the particles they moved (the passes
report it); when it fails, the segments are examined one by one. The few out of their slack (or
alive now but dead at their build) are re-boxed alone, as a build would (the boxes B_i may come
from different steps: the argument is per segment): their pairs are dropped and all their pairs
with the other segments' B_j recomputed (brute force over the segments, then a merge), which
restores the invariant; more than REBOX_LIMIT of them at once start a full build. Look-ahead: a
segment moving at constant velocity stays valid for about LOOKAHEAD_STEPS steps more than with
the slack alone, which matters for fast torn yarn ends.

A split (tearing) re-attaches segments to the new mass of a couple: the weft and the warp segments
that met at a base crossing mass, skipped then as sharing an end particle, no longer share one.
The check sees the changed end particles and patches the candidates instead of rebuilding: every
pair of live segments that touched a re-attached segment's old end particles at the build, shares
no end particle now and whose boxes B + m overlap is merged in (sorted, without duplicates), which
restores the invariant; the recorded end particles are then updated (more than PATCH_LIMIT
segments around the re-attached ends start a full build instead).

Both per-step passes first skip, cheaply, the candidates that cannot act: end points separated
along an axis (proximity: by more than d_c at the end of the step; CCD: the two swept boxes, by
more than a relative 2^-40), then along n, the closest-point vector of the two segments (at the
end, resp. at the start of the step), by more than d_c (proximity) or 4 delta (CCD, delta its
tolerance) -- the end points move linearly, so a plane normal to n then separates the segments
during the whole step. The proximity pass would find them at d_c or more (up to a relative 2^-40
for rounding); the CCD could only report such a pair through its MAX_BOXES cap (a conservative
hit), as its hits are within sqrt(3) delta of touching.
"""
from __future__ import annotations

import math

import numba as nb
import numpy as np

from fraytool.segments import segment_closest_params

from fraytool.collision.broadphase import candidate_pairs_of_segments_kernel
from fraytool.collision.ccd import DELTA_REL, edge_edge_ccd_kernel
from fraytool.collision.interval import round_down, round_up
from fraytool.collision.segment import segment_closest_params as closest_params_of_rows
from fraytool.sim.model import STRUCT_WARP, STRUCT_WEFT, Model

CONTACT_FRACTION = 0.5
"""d_c = CONTACT_FRACTION x thickness."""
SLACK_FRACTION = 0.25
"""Broad-phase slack = SLACK_FRACTION x spacing (module docstring, "Candidates")."""
LOOKAHEAD_STEPS = 3.0
"""A build sweeps every segment on to x + LOOKAHEAD_STEPS (x - x_prev) (module docstring)."""
SEPARATION_REL = 2.0**-40
"""Relative separation above which the CCD pre-test skips a pair: far above the few ulps of the
CCD's own outward rounding, so its root box would be discarded too."""

CCD_SKIP_DELTAS = 4.0
"""The CCD pre-test skips pairs a plane keeps this many times the CCD's tolerance delta apart (its
hits are within sqrt(3) delta of touching, short of its box cap); module docstring."""

REBOX_LIMIT = 64
"""More segments out of their slack at once than this start a full build instead of re-boxing them."""
PATCH_LIMIT = 512
"""More segments touching re-attached end particles at once than this start a full build instead."""


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


@nb.njit(cache=True, fastmath=False, inline="always")
def _share_end(i1, i2, i3, i4):
    return i1 == i3 or i1 == i4 or i2 == i3 or i2 == i4


@nb.njit(cache=True, fastmath=False)
def _apart_at_end(x, i1, i2, i3, i4, distance):
    """True if along some axis the end points of segment i1i2 are more than ``distance`` from those
    of i3i4: every point of one segment is then farther than that from the other (up to rounding
    of a few ulps, far below the 2^-40 relative tolerance added)."""
    for k in range(3):
        lo1 = min(x[i1, k], x[i2, k])
        hi1 = max(x[i1, k], x[i2, k])
        lo2 = min(x[i3, k], x[i4, k])
        hi2 = max(x[i3, k], x[i4, k])
        tol = distance + SEPARATION_REL * (abs(lo1) + abs(hi1) + abs(lo2) + abs(hi2))
        if lo2 - hi1 > tol or lo1 - hi2 > tol:
            return True
    return False


@nb.njit(cache=True, fastmath=False)
def _apart_swept(xs, xe, i1, i2, i3, i4):
    """True if along some axis the swept box of segment i1i2 (end points at step start and end) is
    separated from that of i3i4 by more than a relative SEPARATION_REL: the CCD at thickness 0 would
    discard the pair at its root box (all of F's outward-rounded corner values on one side of 0).
    False on NaN."""
    for k in range(3):
        lo1 = min(min(xs[i1, k], xs[i2, k]), min(xe[i1, k], xe[i2, k]))
        hi1 = max(max(xs[i1, k], xs[i2, k]), max(xe[i1, k], xe[i2, k]))
        lo2 = min(min(xs[i3, k], xs[i4, k]), min(xe[i3, k], xe[i4, k]))
        hi2 = max(max(xs[i3, k], xs[i4, k]), max(xe[i3, k], xe[i4, k]))
        tol = SEPARATION_REL * (abs(lo1) + abs(hi1) + abs(lo2) + abs(hi2)) + 1e-300
        if lo2 - hi1 > tol or lo1 - hi2 > tol:
            return True
    return False


@nb.njit(cache=True, fastmath=False)
def _plane_gap(xs, xe, i1, i2, i3, i4, seg):
    """Gap between the end points of segment i1i2 and those of i3i4, at the step start (xs) and end
    (xe), along n = the closest-point vector of the two segments at the start (plain floating point:
    it only chooses n, any n gives a lower bound): min over the first segment's four points of
    n.x / |n| minus max over the second's. When positive, a plane separates the two segments during
    the whole step (the points move linearly, their projections too), so they stay at least that
    far apart. Also returns the largest |coordinate| involved. Pass xs = xe for one instant.
    ``seg`` is (4, 3) scratch. NaN or touching: a gap of -inf."""
    scale = 0.0
    for k in range(3):
        seg[0, k] = xs[i1, k]
        seg[1, k] = xs[i2, k]
        seg[2, k] = xs[i3, k]
        seg[3, k] = xs[i4, k]
        scale = max(scale, abs(xs[i1, k]), abs(xs[i2, k]), abs(xs[i3, k]), abs(xs[i4, k]),
                    abs(xe[i1, k]), abs(xe[i2, k]), abs(xe[i3, k]), abs(xe[i4, k]))
    u, v = closest_params_of_rows(seg)
    n0 = seg[0, 0] + u * (seg[1, 0] - seg[0, 0]) - (seg[2, 0] + v * (seg[3, 0] - seg[2, 0]))
    n1 = seg[0, 1] + u * (seg[1, 1] - seg[0, 1]) - (seg[2, 1] + v * (seg[3, 1] - seg[2, 1]))
    n2 = seg[0, 2] + u * (seg[1, 2] - seg[0, 2]) - (seg[2, 2] + v * (seg[3, 2] - seg[2, 2]))
    length = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    if not length > 0.0:
        return -math.inf, scale
    lo_a = min(min(n0 * xs[i1, 0] + n1 * xs[i1, 1] + n2 * xs[i1, 2], n0 * xs[i2, 0] + n1 * xs[i2, 1] + n2 * xs[i2, 2]),
               min(n0 * xe[i1, 0] + n1 * xe[i1, 1] + n2 * xe[i1, 2], n0 * xe[i2, 0] + n1 * xe[i2, 1] + n2 * xe[i2, 2]))
    hi_b = max(max(n0 * xs[i3, 0] + n1 * xs[i3, 1] + n2 * xs[i3, 2], n0 * xs[i4, 0] + n1 * xs[i4, 1] + n2 * xs[i4, 2]),
               max(n0 * xe[i3, 0] + n1 * xe[i3, 1] + n2 * xe[i3, 2], n0 * xe[i4, 0] + n1 * xe[i4, 1] + n2 * xe[i4, 2]))
    gap = (lo_a - hi_b) / length
    return (gap if gap == gap else -math.inf), scale


@nb.njit(cache=True, fastmath=False)
def _outside_reach(x, reach, i1, i2, i3, i4):
    """True if one of the four particles lies outside its ``reach`` (see ``particle_reach``)."""
    for p in (i1, i2, i3, i4):
        for d in range(3):
            if x[p, d] < reach[p, d] or x[p, d] > reach[p, 3 + d]:
                return True
    return False


@nb.njit(cache=True, fastmath=False)
def respond_pairs(
    # model
    contact_distance_m, friction,
    # state in
    x_start, pairs, t_hit, spring_particle_a, spring_particle_b, particle_inv_mass, reach,
    # state in/out
    x_end,
):
    """Resolve colliding pairs (CCD hits at times t_hit): normal from the contact time, then the
    inelastic correction with friction. Returns the number of pairs moved and whether a moved
    particle left its ``reach`` (the candidates then need a check)."""
    moved = 0
    left = False
    for k in range(pairs.shape[0]):
        i = pairs[k, 0]
        j = pairs[k, 1]
        i1, i2 = spring_particle_a[i], spring_particle_b[i]
        i3, i4 = spring_particle_a[j], spring_particle_b[j]
        n = _normal(x_start, x_end, i1, i2, i3, i4, t_hit[k])
        if _correct_pair(contact_distance_m, friction, x_start, i1, i2, i3, i4, n, particle_inv_mass, x_end):
            moved += 1
            left = left or _outside_reach(x_end, reach, i1, i2, i3, i4)
    return moved, left


@nb.njit(cache=True, fastmath=False)
def repel_close_pairs(
    # model
    contact_distance_m, friction,
    # state in
    x_start, candidates, spring_particle_a, spring_particle_b, spring_alive, particle_inv_mass, reach,
    # state in/out
    x_end,
):
    """Proximity pass: candidate pairs whose segments end the step closer than the contact
    distance are pushed apart along their end-of-step separation. Returns the pairs moved and
    whether a moved particle left its ``reach`` (the candidates then need a check)."""
    moved = 0
    left = False
    seg = np.empty((4, 3))
    for k in range(candidates.shape[0]):
        i = candidates[k, 0]
        j = candidates[k, 1]
        if not (spring_alive[i] and spring_alive[j]):
            continue  # cut since the candidates were built
        i1, i2 = spring_particle_a[i], spring_particle_b[i]
        i3, i4 = spring_particle_a[j], spring_particle_b[j]
        if _share_end(i1, i2, i3, i4) or _apart_at_end(x_end, i1, i2, i3, i4, contact_distance_m):
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
            left = left or _outside_reach(x_end, reach, i1, i2, i3, i4)
    return moved, left


@nb.njit(cache=True, fastmath=False)
def ccd_pairs(x_start, x_end, candidates, spring_particle_a, spring_particle_b, spring_alive, moved=None):
    """Narrow phase at thickness 0 on candidate pairs: those whose centre lines meet during the
    step, (K, 2) int32, and their earliest contact times (K,). With `moved` (a flag per particle),
    only pairs with a flagged end point are tested: the others were tested already with the same
    positions and did not hit."""
    hit = np.zeros(candidates.shape[0], np.bool_)
    t_hit = np.ones(candidates.shape[0])
    seg = np.empty((4, 3))
    for k in range(candidates.shape[0]):
        i = candidates[k, 0]
        j = candidates[k, 1]
        if not (spring_alive[i] and spring_alive[j]):
            continue  # cut since the candidates were built
        i1, i2 = spring_particle_a[i], spring_particle_b[i]
        i3, i4 = spring_particle_a[j], spring_particle_b[j]
        if moved is not None and not (moved[i1] or moved[i2] or moved[i3] or moved[i4]):
            continue  # unchanged since the last pass, which found no hit here
        if _share_end(i1, i2, i3, i4) or _apart_swept(x_start, x_end, i1, i2, i3, i4):
            continue  # (the CCD would report no hit)
        gap, scale = _plane_gap(x_start, x_end, i1, i2, i3, i4, seg)
        if gap > CCD_SKIP_DELTAS * DELTA_REL * scale:
            continue  # never within CCD_SKIP_DELTAS x the CCD's tolerance delta of each other
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
def inflate_boxes(box_lo, box_hi, margin):
    """Boxes inflated by ``margin``, outward rounded as in the broad phase: (M, 6) rows lo, hi."""
    out = np.empty((box_lo.shape[0], 6))
    for k in range(box_lo.shape[0]):
        for d in range(3):
            out[k, d] = round_down(box_lo[k, d] - margin)
            out[k, 3 + d] = round_up(box_hi[k, d] + margin)
    return out


@nb.njit(cache=True, fastmath=False)
def particle_reach(spring_particle_a, spring_particle_b, spring_alive, segments, box_lo, box_hi, slack, particle_count):
    """Where every particle may go while the candidates stay valid: the intersection, over the live
    listed segments ending at it, of their build boxes grown by ``slack`` ((P, 6) rows lo, hi;
    unbounded for the other particles), computed like the per-segment test of ``escaped_segments``."""
    reach = np.empty((particle_count, 6))
    reach[:, :3] = -math.inf
    reach[:, 3:] = math.inf
    for k in range(segments.shape[0]):
        s = segments[k]
        if not spring_alive[s]:
            continue
        for p in (spring_particle_a[s], spring_particle_b[s]):
            for d in range(3):
                reach[p, d] = max(reach[p, d], box_lo[k, d] - slack)
                reach[p, 3 + d] = min(reach[p, 3 + d], box_hi[k, d] + slack)
    return reach


@nb.njit(cache=True, fastmath=False)
def update_reach(reach, touched, spring_particle_a, spring_particle_b, spring_alive, segments, box_lo, box_hi, slack):
    """``particle_reach`` again for the particles with ``touched[p]`` only (the others keep theirs)."""
    for p in range(reach.shape[0]):
        if touched[p]:
            for d in range(3):
                reach[p, d] = -math.inf
                reach[p, 3 + d] = math.inf
    for k in range(segments.shape[0]):
        s = segments[k]
        if not spring_alive[s]:
            continue
        for p in (spring_particle_a[s], spring_particle_b[s]):
            if touched[p]:
                for d in range(3):
                    reach[p, d] = max(reach[p, d], box_lo[k, d] - slack)
                    reach[p, 3 + d] = min(reach[p, 3 + d], box_hi[k, d] + slack)


@nb.njit(cache=True, fastmath=False)
def check_candidates(x_start, x_end, spring_particle_a, spring_particle_b, spring_alive, segments, reach,
                     build_ends, build_alive):
    """Fast test of the candidates (module docstring, "Candidates"): True if every particle is within
    its ``reach`` at the start and the end of the step (NaN compares False: left to the solver's
    guard), every live listed segment was alive at its build and still has the end particles of
    ``build_ends`` (for which ``reach`` was computed); False: see ``escaped_segments``."""
    for p in range(reach.shape[0]):
        for d in range(3):
            if (x_start[p, d] < reach[p, d] or x_end[p, d] < reach[p, d]
                    or x_start[p, d] > reach[p, 3 + d] or x_end[p, d] > reach[p, 3 + d]):
                return False
    for k in range(segments.shape[0]):
        s = segments[k]
        if spring_alive[s] and (not build_alive[k] or spring_particle_a[s] != build_ends[k, 0]
                                or spring_particle_b[s] != build_ends[k, 1]):
            return False
    return True


@nb.njit(cache=True, fastmath=False)
def escaped_segments(x_start, x_end, spring_particle_a, spring_particle_b, spring_alive, segments, box_lo, box_hi,
                     slack, build_alive):
    """Indices into ``segments`` (increasing) of the live segments with an end point (current end
    particles), at the start or the end of the step, farther than ``slack`` outside their build
    box, or dead at their build."""
    out = np.empty(segments.shape[0], np.int64)
    count = 0
    for k in range(segments.shape[0]):
        s = segments[k]
        if not spring_alive[s]:
            continue  # a cut segment collides with nothing
        pa = spring_particle_a[s]
        pb = spring_particle_b[s]
        out_k = not build_alive[k]
        for d in range(3):
            lo = min(min(x_start[pa, d], x_end[pa, d]), min(x_start[pb, d], x_end[pb, d]))
            hi = max(max(x_start[pa, d], x_end[pa, d]), max(x_start[pb, d], x_end[pb, d]))
            if lo < box_lo[k, d] - slack or hi > box_hi[k, d] + slack:
                out_k = True
        if out_k:
            out[count] = k
            count += 1
    return out[:count].copy()


@nb.njit(cache=True, fastmath=False)
def _rebox_pairs(near, escaped, segments, flag, inflated, spring_particle_a, spring_particle_b, keys):
    """Pairs of the escaped segments (``rebox_segments``) with the ``near`` ones, as keys
    i * S + j (i < j spring slots) stored in ``keys`` when it is long enough; returns how many."""
    spring_count = spring_particle_a.shape[0]
    store = keys.shape[0] > 0
    count = 0
    for q in range(near.shape[0]):
        k = near[q]
        s = segments[k]
        for r in range(escaped.shape[0]):
            e = escaped[r]
            if flag[s] and k <= e:
                continue  # a pair of two escaped segments: once, from the later one
            if (inflated[e, 0] > inflated[k, 3] or inflated[k, 0] > inflated[e, 3]
                    or inflated[e, 1] > inflated[k, 4] or inflated[k, 1] > inflated[e, 4]
                    or inflated[e, 2] > inflated[k, 5] or inflated[k, 2] > inflated[e, 5]):
                continue
            t = segments[e]
            if _share_end(spring_particle_a[s], spring_particle_b[s], spring_particle_a[t], spring_particle_b[t]):
                continue
            if store:
                keys[count] = min(s, t) * spring_count + max(s, t)
            count += 1
    return count


@nb.njit(cache=True, fastmath=False)
def rebox_segments(x_start, x_end, spring_particle_a, spring_particle_b, spring_alive, segments, escaped, lookahead,
                   margin, box_lo, box_hi, inflated, build_alive, candidates):
    """Re-box the ``escaped`` segments (indices into ``segments``) as a build would (swept from
    x_start to x_end + lookahead (x_end - x_start)), writing their rows of ``box_lo``, ``box_hi``,
    ``inflated`` (boxes + margin) and ``build_alive``, and return the candidates without their
    pairs, plus every pair of an escaped segment with a live listed segment sharing no end
    particle whose inflated boxes overlap: (K, 2) int32, sorted (module docstring, "Candidates")."""
    spring_count = spring_particle_a.shape[0]
    flag = np.zeros(spring_count, np.bool_)
    union = np.empty(6)
    union[:3] = math.inf
    union[3:] = -math.inf
    for r in range(escaped.shape[0]):
        k = escaped[r]
        s = segments[k]
        flag[s] = True
        build_alive[k] = True
        pa = spring_particle_a[s]
        pb = spring_particle_b[s]
        for d in range(3):
            ahead_a = x_end[pa, d] + lookahead * (x_end[pa, d] - x_start[pa, d])
            ahead_b = x_end[pb, d] + lookahead * (x_end[pb, d] - x_start[pb, d])
            box_lo[k, d] = min(min(x_start[pa, d], x_start[pb, d]), min(ahead_a, ahead_b))
            box_hi[k, d] = max(max(x_start[pa, d], x_start[pb, d]), max(ahead_a, ahead_b))
            inflated[k, d] = round_down(box_lo[k, d] - margin)
            inflated[k, 3 + d] = round_up(box_hi[k, d] + margin)
            union[d] = min(union[d], inflated[k, d])
            union[3 + d] = max(union[3 + d], inflated[k, 3 + d])
    # segments near any escaped one (inside the union of their boxes), then the pairs, counted and
    # then stored as keys i * S + j (no array reassigned in a loop: see fraytool.collision.broadphase)
    near = np.empty(segments.shape[0], np.int64)
    n_near = 0
    for k in range(segments.shape[0]):
        if (spring_alive[segments[k]] and inflated[k, 0] <= union[3] and union[0] <= inflated[k, 3]
                and inflated[k, 1] <= union[4] and union[1] <= inflated[k, 4]
                and inflated[k, 2] <= union[5] and union[2] <= inflated[k, 5]):
            near[n_near] = k
            n_near += 1
    count = _rebox_pairs(near[:n_near], escaped, segments, flag, inflated, spring_particle_a, spring_particle_b,
                         np.empty(0, np.int64))
    keys = np.empty(count, np.int64)
    _rebox_pairs(near[:n_near], escaped, segments, flag, inflated, spring_particle_a, spring_particle_b, keys)
    keys = np.sort(keys)
    added = np.empty((keys.shape[0], 2), np.int32)
    for q in range(keys.shape[0]):
        added[q, 0] = keys[q] // spring_count
        added[q, 1] = keys[q] % spring_count
    kept = np.empty((candidates.shape[0], 2), np.int32)
    n = 0
    for q in range(candidates.shape[0]):
        if not (flag[candidates[q, 0]] or flag[candidates[q, 1]]):
            kept[n, 0] = candidates[q, 0]
            kept[n, 1] = candidates[q, 1]
            n += 1
    return merge_pairs(kept[:n], added)


@nb.njit(cache=True, fastmath=False)
def reattached_pairs(spring_particle_a, spring_particle_b, spring_alive, segments, build_ends, inflated,
                     particle_count, max_touching):
    """Pairs to add after re-attachments (module docstring, "Candidates"): (K, 2) int32 spring slots,
    i < j, sorted, without duplicates, of live listed segments that touched an old end particle
    (``build_ends``) of a re-attached segment, share no end particle now, and whose ``inflated``
    build boxes (+ margin) overlap. Returns (pairs, True), or (empty, False) when more than
    ``max_touching`` segments touch those particles (the caller rebuilds instead)."""
    n = segments.shape[0]
    mark = np.zeros(particle_count, np.bool_)
    for k in range(n):
        s = segments[k]
        if spring_alive[s] and (spring_particle_a[s] != build_ends[k, 0] or spring_particle_b[s] != build_ends[k, 1]):
            mark[build_ends[k, 0]] = True
            mark[build_ends[k, 1]] = True
    touching = np.empty(max_touching, np.int64)
    m = 0
    for k in range(n):
        if spring_alive[segments[k]] and (mark[build_ends[k, 0]] or mark[build_ends[k, 1]]):
            if m == max_touching:
                return np.empty((0, 2), np.int32), False
            touching[m] = k  # increasing k: increasing spring slots
            m += 1
    out = np.empty((m * (m - 1) // 2, 2), np.int32)
    count = 0
    for x in range(m):
        k = touching[x]
        s = segments[k]
        for y in range(x + 1, m):
            l = touching[y]
            t = segments[l]
            if _share_end(spring_particle_a[s], spring_particle_b[s], spring_particle_a[t], spring_particle_b[t]):
                continue
            overlap = True
            for d in range(3):
                if inflated[k, d] > inflated[l, 3 + d] or inflated[l, d] > inflated[k, 3 + d]:
                    overlap = False
            if overlap:
                out[count, 0] = s
                out[count, 1] = t
                count += 1
    return out[:count].copy(), True


@nb.njit(cache=True, fastmath=False)
def merge_pairs(first, second):
    """Union of two lexicographically sorted, duplicate-free (K, 2) pair lists, sorted."""
    out = np.empty((first.shape[0] + second.shape[0], 2), np.int32)
    i = 0
    j = 0
    n = 0
    while i < first.shape[0] or j < second.shape[0]:
        if j == second.shape[0]:
            take = -1
        elif i == first.shape[0]:
            take = 1
        elif first[i, 0] != second[j, 0]:
            take = -1 if first[i, 0] < second[j, 0] else 1
        elif first[i, 1] != second[j, 1]:
            take = -1 if first[i, 1] < second[j, 1] else 1
        else:
            take = 0
        if take <= 0:
            out[n, 0] = first[i, 0]
            out[n, 1] = first[i, 1]
            i += 1
            if take == 0:
                j += 1
        else:
            out[n, 0] = second[j, 0]
            out[n, 1] = second[j, 1]
            j += 1
        n += 1
    return out[:n].copy()


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
    yarn = model.spring_yarn()
    assert ((model.spring_kind == STRUCT_WEFT) | (model.spring_kind == STRUCT_WARP)).sum() == (yarn >= 0).sum()
    return yarn


class SelfCollision:
    """The self-collision pass: detect (broad + interval CCD), respond, repeat up to a cap."""

    def __init__(self, model: Model):
        self.model = model
        self.spring_yarn = yarn_segment_ids(model)
        self.contact_distance_m = CONTACT_FRACTION * model.thickness_m
        self.iterations = model.self_collision_iterations
        self.slack_m = SLACK_FRACTION * model.spacing_m
        """Extra broad-phase margin: candidates stay valid while no end point leaves its box by more."""
        self.margin_m = 0.5 * self.contact_distance_m + self.slack_m
        self.friction = model.self_collision_friction
        self.yarn_segments = np.nonzero(self.spring_yarn >= 0)[0].astype(np.int32)
        self._cand = None
        self._box_lo = self._box_hi = None
        self._inflated = None
        """Build boxes inflated by the margin, (M, 6)."""
        self._reach = None
        """Per particle, the box it may stay in (``particle_reach``), (P, 6)."""
        self._ends = None
        """End particles of every yarn segment at the build or the last patch, (M, 2) int32."""
        self._alive = None
        """Yarn segments alive at the build."""
        self.broad_phase_builds = 0
        self.broad_phase_patches = 0
        """Candidate patches after re-attachments (module docstring, "Candidates")."""
        self.broad_phase_reboxes = 0
        """Partial updates for segments that left their slack (module docstring, "Candidates")."""
        self.pairs_last = 0
        """Crossing pairs found by the first CCD pass of the last step."""
        self.proximity_last = 0
        """Pairs pushed apart by the proximity pass of the last step."""
        self.proximity_total = 0
        self.pairs_total = 0
        self.cap_hits = 0
        """Steps that still had colliding pairs after the last pass."""

    def _build(self, state, prev_position_m) -> None:
        """Broad phase on the segments swept from x_prev to the look-ahead x + LOOKAHEAD_STEPS (x - x_prev),
        boxes inflated by d_c/2 + slack (module docstring, "Candidates")."""
        x = state.particle_position_m
        a, b = state.spring_particle_a, state.spring_particle_b
        ahead = x + LOOKAHEAD_STEPS * (x - prev_position_m)
        self._cand = candidate_pairs_of_segments_kernel(prev_position_m, ahead, a, b, state.spring_alive,
                                                        self.yarn_segments, self.margin_m, 0.0)
        self._box_lo, self._box_hi = segment_boxes(prev_position_m, ahead, a, b, self.yarn_segments)
        self._inflated = inflate_boxes(self._box_lo, self._box_hi, self.margin_m)
        self._ends = np.stack([a[self.yarn_segments], b[self.yarn_segments]], axis=1)
        self._alive = state.spring_alive[self.yarn_segments]
        self.broad_phase_builds += 1

    def _ensure_valid(self, state, prev_position_m) -> None:
        """Keep, re-box, patch or build the candidates (module docstring, "Candidates")."""
        x = state.particle_position_m
        a, b, alive = state.spring_particle_a, state.spring_particle_b, state.spring_alive
        if self._cand is not None and check_candidates(prev_position_m, x, a, b, alive, self.yarn_segments,
                                                       self._reach, self._ends, self._alive):
            return
        if self._cand is None:
            self._build(state, prev_position_m)
        else:
            escaped = escaped_segments(prev_position_m, x, a, b, alive, self.yarn_segments, self._box_lo,
                                       self._box_hi, self.slack_m, self._alive)
            touched = np.zeros(x.shape[0], np.bool_)
            if len(escaped) > REBOX_LIMIT:
                self._build(state, prev_position_m)
                touched = None
            elif len(escaped):
                self._cand = rebox_segments(prev_position_m, x, a, b, alive, self.yarn_segments, escaped,
                                            LOOKAHEAD_STEPS, self.margin_m, self._box_lo, self._box_hi,
                                            self._inflated, self._alive, self._cand)
                touched[a[self.yarn_segments[escaped]]] = True
                touched[b[self.yarn_segments[escaped]]] = True
                self.broad_phase_reboxes += 1
            ends = np.stack([a[self.yarn_segments], b[self.yarn_segments]], axis=1)
            changed = np.nonzero(np.any(ends != self._ends, axis=1) & alive[self.yarn_segments])[0]
            if touched is not None and len(changed):
                extra, ok = reattached_pairs(a, b, alive, self.yarn_segments, self._ends, self._inflated,
                                             x.shape[0], PATCH_LIMIT)
                if ok:
                    self._cand = merge_pairs(self._cand, extra)
                    touched[self._ends[changed].ravel()] = True
                    touched[ends[changed].ravel()] = True
                    self._ends = ends
                    self.broad_phase_patches += 1
                else:
                    self._build(state, prev_position_m)
                    touched = None
            if touched is not None and not len(escaped) and not len(changed):
                touched = None  # the check failed for another reason (a segment cut since): start afresh
            if touched is not None:
                update_reach(self._reach, touched, a, b, alive, self.yarn_segments, self._box_lo, self._box_hi,
                             self.slack_m)
                return
        self._reach = particle_reach(a, b, alive, self.yarn_segments, self._box_lo, self._box_hi, self.slack_m,
                                     x.shape[0])

    def __call__(self, state, prev_position_m: np.ndarray, dt_s: float) -> None:
        x = state.particle_position_m
        a, b, w, alive = state.spring_particle_a, state.spring_particle_b, state.particle_inv_mass, state.spring_alive
        self._ensure_valid(state, prev_position_m)
        self.proximity_last, left = repel_close_pairs(self.contact_distance_m, self.friction, prev_position_m,
                                                      self._cand, a, b, alive, w, self._reach, x)
        self.proximity_total += self.proximity_last
        self.pairs_last = 0
        moved = None  # first pass: every candidate
        for it in range(self.iterations + 1):
            if left:  # a correction moved an end point out of its reach: candidates may change
                self._ensure_valid(state, prev_position_m)
                moved = None
            pairs, t = ccd_pairs(prev_position_m, x, self._cand, a, b, alive, moved)
            if it == 0:
                self.pairs_last = len(pairs)
                self.pairs_total += len(pairs)
            if len(pairs) == 0:
                return
            if it == self.iterations:
                break
            before = x.copy()
            _, left = respond_pairs(self.contact_distance_m, self.friction, prev_position_m, pairs, t, a, b, w,
                                    self._reach, x)
            moved = np.any(x != before, axis=1)  # later passes test only pairs these particles touch
        self.cap_hits += 1
        while len(pairs):  # each round returns more particles to where they started: it ends
            freeze_pairs(pairs, a, b, w, prev_position_m, x)
            self._ensure_valid(state, prev_position_m)
            pairs, _ = ccd_pairs(prev_position_m, x, self._cand, a, b, alive)

    def summary(self) -> dict:
        return {"self_collision_pairs": self.pairs_total, "self_collision_proximity_pushes": self.proximity_total,
                "self_collision_cap_hits": self.cap_hits}


def attach_self_collision(solver) -> None:
    """Plug the self-collision pass into a SolverExplicitPBD."""
    solver.self_collision = SelfCollision(solver.model)
