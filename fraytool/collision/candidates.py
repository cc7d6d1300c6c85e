"""Candidate pairs of swept yarn segments, kept valid across steps (pure geometry, numba kernels).

The self-collision stage (fraytool.sim.stages.self_collision) keeps the broad phase's candidate pairs
from one step to the next and repairs them here instead of rebuilding them every step.

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
the live segments ending at it; only the particles with one), and after corrections on the particles
they moved (the passes report it); whether the live segments still have their build's end particles,
only after a change of topology (the self-collision stage knows when). When it fails, the segments
are examined one by one. The few out of their slack (or alive now but dead at their build) are re-boxed alone, as a
build would (the boxes B_i may come from different steps: the argument is per segment): their pairs are dropped and
all their pairs with the other segments' B_j recomputed (brute force over the segments, then a merge), which
restores the invariant; more than REBOX_LIMIT of them at once start a full build. Look-ahead: a segment moving at
constant velocity stays valid for about LOOKAHEAD_STEPS steps more than with the slack alone, which matters for fast
torn yarn ends.

A split (tearing) re-attaches segments to the new mass of a couple: the weft and the warp segments
that met at a base crossing mass, skipped then as sharing an end particle, no longer share one.
The check sees the changed end particles and patches the candidates instead of rebuilding: every
pair of live segments that touched a re-attached segment's old end particles at the build, shares
no end particle now and whose boxes B + m overlap is merged in (sorted, without duplicates), which
restores the invariant; the recorded end particles are then updated (more than PATCH_LIMIT
segments around the re-attached ends start a full build instead).
"""
from __future__ import annotations

import math

import numba as nb
import numpy as np

from fraytool.collision.interval import round_down, round_up
from fraytool.collision.narrow import _share_end


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
def update_reach(reach_inout, touched, spring_particle_a, spring_particle_b, spring_alive, segments, box_lo, box_hi, slack):
    """``particle_reach`` again for the particles with ``touched[p]`` only (the others keep theirs)."""
    for p in range(reach_inout.shape[0]):
        if touched[p]:
            for d in range(3):
                reach_inout[p, d] = -math.inf
                reach_inout[p, 3 + d] = math.inf
    for k in range(segments.shape[0]):
        s = segments[k]
        if not spring_alive[s]:
            continue
        for p in (spring_particle_a[s], spring_particle_b[s]):
            if touched[p]:
                for d in range(3):
                    reach_inout[p, d] = max(reach_inout[p, d], box_lo[k, d] - slack)
                    reach_inout[p, 3 + d] = min(reach_inout[p, 3 + d], box_hi[k, d] + slack)


@nb.njit(cache=True, fastmath=False)
def check_candidates(x_start, x_end, spring_particle_a, spring_particle_b, spring_alive, segments, reach,
                     build_ends, build_alive, reached, check_segments):
    """Fast test of the candidates (module docstring, "Candidates"): True if every particle is within
    its ``reach`` at the start and the end of the step (NaN compares False: left to the solver's
    guard), every live listed segment was alive at its build and still has the end particles of
    ``build_ends`` (for which ``reach`` was computed); False: see ``escaped_segments``. ``reached``:
    the particles whose reach is bounded (the ends of live listed segments: every other particle is
    within its unbounded reach); ``check_segments`` False skips the segments' test, for a caller who
    knows they have not changed since they last passed it (no change of topology since)."""
    for k in range(reached.shape[0]):
        p = reached[k]
        for d in range(3):
            if (x_start[p, d] < reach[p, d] or x_end[p, d] < reach[p, d]
                    or x_start[p, d] > reach[p, 3 + d] or x_end[p, d] > reach[p, 3 + d]):
                return False
    if not check_segments:
        return True
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
def pair_segments(candidates, flag_inout):
    """The spring slots in ``candidates`` ((K, 2)), each once (in order of first appearance);
    ``flag`` ((S,) bools, all False) is scratch, all False again on return."""
    out = np.empty(2 * candidates.shape[0], np.int32)
    count = 0
    for k in range(candidates.shape[0]):
        for c in range(2):
            s = candidates[k, c]
            if not flag_inout[s]:
                flag_inout[s] = True
                out[count] = s
                count += 1
    for q in range(count):
        flag_inout[out[q]] = False
    return out[:count].copy()


@nb.njit(cache=True, fastmath=False)
def movable_pairs(candidates, spring_particle_a, spring_particle_b, particle_inv_mass):
    """The candidate pairs (in order) with an end particle of inverse mass > 0: a pair of two segments whose
    four ends are all held or slaved to coarse nodes cannot be moved by any pass (every correction is
    weighted by the inverse masses), so the passes need not look at it."""
    keep = np.empty(candidates.shape[0], np.bool_)
    count = 0
    for k in range(candidates.shape[0]):
        i = candidates[k, 0]
        j = candidates[k, 1]
        keep[k] = (particle_inv_mass[spring_particle_a[i]] > 0.0 or particle_inv_mass[spring_particle_b[i]] > 0.0
                   or particle_inv_mass[spring_particle_a[j]] > 0.0 or particle_inv_mass[spring_particle_b[j]] > 0.0)
        count += keep[k]
    out = np.empty((count, 2), candidates.dtype)
    n = 0
    for k in range(candidates.shape[0]):
        if keep[k]:
            out[n, 0] = candidates[k, 0]
            out[n, 1] = candidates[k, 1]
            n += 1
    return out


@nb.njit(cache=True, fastmath=False)
def reattached_segments(spring_particle_a, spring_particle_b, spring_alive, segments, build_ends):
    """Indices into ``segments`` (increasing) of the live segments whose end particles are no longer
    those of ``build_ends``."""
    out = np.empty(segments.shape[0], np.int64)
    count = 0
    for k in range(segments.shape[0]):
        s = segments[k]
        if spring_alive[s] and (spring_particle_a[s] != build_ends[k, 0] or spring_particle_b[s] != build_ends[k, 1]):
            out[count] = k
            count += 1
    return out[:count].copy()


@nb.njit(cache=True, fastmath=False)
def _rebox_pairs(near, escaped, segments, flag, inflated, spring_particle_a, spring_particle_b, keys_inout):
    """Pairs of the escaped segments (``rebox_segments``) with the ``near`` ones, as keys
    i * S + j (i < j spring slots) stored in ``keys`` when it is long enough; returns how many."""
    spring_count = spring_particle_a.shape[0]
    store = keys_inout.shape[0] > 0
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
                keys_inout[count] = min(s, t) * spring_count + max(s, t)
            count += 1
    return count


@nb.njit(cache=True, fastmath=False)
def rebox_segments(x_start, x_end, springs_in, segments, escaped, lookahead, margin, boxes_inout, candidates):
    """Re-box the ``escaped`` segments (indices into ``segments``) as a build would (swept from
    x_start to x_end + lookahead (x_end - x_start)), writing their rows of the ``boxes_inout`` group
    (``box_lo``, ``box_hi``, ``inflated`` (boxes + margin), ``build_alive``), and return the candidates
    without their pairs, plus every pair of an escaped segment with a live listed segment sharing no
    end particle whose inflated boxes overlap: (K, 2) int32, sorted (module docstring, "Candidates").
    ``springs_in``: the springs' (ends a, ends b, alive flags)."""
    spring_particle_a, spring_particle_b, spring_alive = springs_in
    box_lo_inout, box_hi_inout, inflated_inout, build_alive_out = boxes_inout
    spring_count = spring_particle_a.shape[0]
    flag = np.zeros(spring_count, np.bool_)
    union = np.empty(6)
    union[:3] = math.inf
    union[3:] = -math.inf
    for r in range(escaped.shape[0]):
        k = escaped[r]
        s = segments[k]
        flag[s] = True
        build_alive_out[k] = True
        pa = spring_particle_a[s]
        pb = spring_particle_b[s]
        for d in range(3):
            ahead_a = x_end[pa, d] + lookahead * (x_end[pa, d] - x_start[pa, d])
            ahead_b = x_end[pb, d] + lookahead * (x_end[pb, d] - x_start[pb, d])
            box_lo_inout[k, d] = min(min(x_start[pa, d], x_start[pb, d]), min(ahead_a, ahead_b))
            box_hi_inout[k, d] = max(max(x_start[pa, d], x_start[pb, d]), max(ahead_a, ahead_b))
            inflated_inout[k, d] = round_down(box_lo_inout[k, d] - margin)
            inflated_inout[k, 3 + d] = round_up(box_hi_inout[k, d] + margin)
            union[d] = min(union[d], inflated_inout[k, d])
            union[3 + d] = max(union[3 + d], inflated_inout[k, 3 + d])
    # segments near any escaped one (inside the union of their boxes), then the pairs, counted and
    # then stored as keys i * S + j (no array reassigned in a loop: see fraytool.collision.broadphase)
    near = np.empty(segments.shape[0], np.int32)
    n_near = 0
    for k in range(segments.shape[0]):
        if (spring_alive[segments[k]] and inflated_inout[k, 0] <= union[3] and union[0] <= inflated_inout[k, 3]
                and inflated_inout[k, 1] <= union[4] and union[1] <= inflated_inout[k, 4]
                and inflated_inout[k, 2] <= union[5] and union[2] <= inflated_inout[k, 5]):
            near[n_near] = k
            n_near += 1
    count = _rebox_pairs(near[:n_near], escaped, segments, flag, inflated_inout, spring_particle_a, spring_particle_b,
                         np.empty(0, np.int64))
    keys = np.empty(count, np.int64)
    _rebox_pairs(near[:n_near], escaped, segments, flag, inflated_inout, spring_particle_a, spring_particle_b, keys)
    keys = np.sort(keys)
    added = np.empty((keys.shape[0], 2), np.int32)
    for q in range(keys.shape[0]):
        added[q, 0] = keys[q] // spring_count
        added[q, 1] = keys[q] % spring_count
    # merge the kept candidates (no escaped segment) with the added pairs (each with one): disjoint
    # sorted lists, so the merge of merge_pairs without its duplicate case, in one pass
    out = np.empty((candidates.shape[0] + added.shape[0], 2), np.int32)
    n = 0
    j = 0
    for q in range(candidates.shape[0]):
        c0 = candidates[q, 0]
        c1 = candidates[q, 1]
        if flag[c0] or flag[c1]:
            continue
        while j < added.shape[0] and (added[j, 0] < c0 or (added[j, 0] == c0 and added[j, 1] < c1)):
            out[n, 0] = added[j, 0]
            out[n, 1] = added[j, 1]
            n += 1
            j += 1
        out[n, 0] = c0
        out[n, 1] = c1
        n += 1
    while j < added.shape[0]:
        out[n, 0] = added[j, 0]
        out[n, 1] = added[j, 1]
        n += 1
        j += 1
    return out[:n]


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
