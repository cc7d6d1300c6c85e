"""Narrow phase over candidate pairs of yarn segments: cheap separation pre-tests, then the interval
CCD (docs/method.md §4.2; docs/self-collision.md). Pure geometry, numba kernels.

Both per-step passes first skip, cheaply, the candidates that cannot act: end points separated
along an axis (proximity: by more than d_c at the end of the step; CCD: the two swept boxes, by
more than a relative 2^-40), then along n, the closest-point vector of the two segments (at the
end, resp. at the start of the step), by more than d_c (proximity) or 4 delta (CCD, delta its
tolerance) -- the end points move linearly, so a plane normal to n then separates the segments
during the whole step. The proximity pass would find them at d_c or more (up to a relative 2^-40
for rounding); the CCD could only report such a pair through its MAX_BOXES cap (a conservative
hit), as its hits are within sqrt(3) delta of touching.

Before that closest-point vector (a division or three), a cheaper plane: the one square to both
segments, n = d1 x d2 (at the end, resp. at the start of the step). Weft and warp crossing at a
mass couple (the yarn contact holds them a thickness apart, twice d_c) are about a fifth of the
candidates in a torn figure scene and overlap on every axis, so only a plane can tell them apart;
along d1 x d2 they are a thickness apart. Proximity (``_lines_apart``): the distance between the
two lines is a lower bound of the segments' distance, so lines more than d_c (1 + 1e-9) apart
leave the segments apart by more than the closest-point distance computed after it could round
to; the test answers only where its own rounding stays under half that margin (not for nearly
parallel segments, where the cross product loses digits). CCD (``_cross_plane_apart``): as for n above, any plane separating the swept end points
separates the segments during the step; the gap must exceed CCD_SKIP_DELTAS delta for the largest
|coordinate| of the pass (at least each pair's own). Both answer False for (nearly) parallel
segments and NaN, which the tests after them decide. They only skip pairs the tests after them
would skip (or find no hit for), so every pass acts on the same pairs as without them: fig7's
frames are identical (benchmarks/frames_identical.py), and the two passes cost 20 % (proximity)
and 30 % (CCD) less on it.
"""
from __future__ import annotations

import math

import numba as nb
import numpy as np

from fraytool.collision.ccd import DELTA_REL, edge_edge_ccd_kernel
from fraytool.geometry.segments import segment_closest_params_rows

SEPARATION_REL = 2.0**-40
"""Relative separation above which the CCD pre-test skips a pair: far above the few ulps of the
CCD's own outward rounding, so its root box would be discarded too."""

CCD_SKIP_DELTAS = 4.0
"""The CCD pre-test skips pairs a plane keeps this many times the CCD's tolerance delta apart (its
hits are within sqrt(3) delta of touching, short of its box cap); module docstring."""


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
def _plane_gap(xs, xe, i1, i2, i3, i4, seg_inout):
    """Gap between the end points of segment i1i2 and those of i3i4, at the step start (xs) and end
    (xe), along n = the closest-point vector of the two segments at the start (plain floating point:
    it only chooses n, any n gives a lower bound): min over the first segment's four points of
    n.x / |n| minus max over the second's. When positive, a plane separates the two segments during
    the whole step (the points move linearly, their projections too), so they stay at least that
    far apart. Also returns the largest |coordinate| involved. Pass xs = xe for one instant.
    ``seg`` is (4, 3) scratch. NaN or touching: a gap of -inf."""
    scale = 0.0
    for k in range(3):
        seg_inout[0, k] = xs[i1, k]
        seg_inout[1, k] = xs[i2, k]
        seg_inout[2, k] = xs[i3, k]
        seg_inout[3, k] = xs[i4, k]
        scale = max(scale, abs(xs[i1, k]), abs(xs[i2, k]), abs(xs[i3, k]), abs(xs[i4, k]),
                    abs(xe[i1, k]), abs(xe[i2, k]), abs(xe[i3, k]), abs(xe[i4, k]))
    u, v = segment_closest_params_rows(seg_inout)
    n0 = seg_inout[0, 0] + u * (seg_inout[1, 0] - seg_inout[0, 0]) - (seg_inout[2, 0] + v * (seg_inout[3, 0] - seg_inout[2, 0]))
    n1 = seg_inout[0, 1] + u * (seg_inout[1, 1] - seg_inout[0, 1]) - (seg_inout[2, 1] + v * (seg_inout[3, 1] - seg_inout[2, 1]))
    n2 = seg_inout[0, 2] + u * (seg_inout[1, 2] - seg_inout[0, 2]) - (seg_inout[2, 2] + v * (seg_inout[3, 2] - seg_inout[2, 2]))
    length = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    if not length > 0.0:
        return -math.inf, scale
    lo_a = min(min(n0 * xs[i1, 0] + n1 * xs[i1, 1] + n2 * xs[i1, 2], n0 * xs[i2, 0] + n1 * xs[i2, 1] + n2 * xs[i2, 2]),
               min(n0 * xe[i1, 0] + n1 * xe[i1, 1] + n2 * xe[i1, 2], n0 * xe[i2, 0] + n1 * xe[i2, 1] + n2 * xe[i2, 2]))
    hi_b = max(max(n0 * xs[i3, 0] + n1 * xs[i3, 1] + n2 * xs[i3, 2], n0 * xs[i4, 0] + n1 * xs[i4, 1] + n2 * xs[i4, 2]),
               max(n0 * xe[i3, 0] + n1 * xe[i3, 1] + n2 * xe[i3, 2], n0 * xe[i4, 0] + n1 * xe[i4, 1] + n2 * xe[i4, 2]))
    gap = (lo_a - hi_b) / length
    return (gap if gap == gap else -math.inf), scale


@nb.njit(cache=True, fastmath=False, inline="always")
def segment_cross(x, i1, i2, i3, i4):
    """(x_i2 - x_i1) x (x_i4 - x_i3): square to both segments (not normalised), as scalars."""
    a0 = x[i2, 0] - x[i1, 0]
    a1 = x[i2, 1] - x[i1, 1]
    a2 = x[i2, 2] - x[i1, 2]
    b0 = x[i4, 0] - x[i3, 0]
    b1 = x[i4, 1] - x[i3, 1]
    b2 = x[i4, 2] - x[i3, 2]
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


_LINES_GUARD = (0.5e-9 / (64.0 * 2.220446049250313e-16)) ** 2
"""Largest G^2 for which `_lines_apart` answers (its docstring): its rounding then stays under 0.5e-9
relative, half its margin. Crossing yarns a thickness apart have G of about 10."""


@nb.njit(cache=True, fastmath=False, inline="always")
def _lines_apart(x, i1, i2, i3, i4, distance):
    """True if the lines through segments i1i2 and i3i4 (positions x) are more than distance (1 +
    1e-9) apart: the segments are then farther apart than that (module docstring). The test is
    p^2 > (distance (1 + 1e-9))^2 |c|^2 with c = d1 x d2 and p = (x3 - x1) . c; in floating point p and
    |c|^2 are off by at most about 64 eps G relative, G = |x3 - x1| |d1| |d2| / (distance |c|) (the
    cross product loses digits as the segments turn parallel), so it answers only where G <=
    _LINES_GUARD^(1/2), which keeps that error under 0.5e-9, inside the margin; elsewhere (nearly
    parallel segments, NaN) it answers False and the closest-point test decides."""
    cx, cy, cz = segment_cross(x, i1, i2, i3, i4)
    cc = cx * cx + cy * cy + cz * cz
    l1 = (x[i2, 0] - x[i1, 0]) ** 2 + (x[i2, 1] - x[i1, 1]) ** 2 + (x[i2, 2] - x[i1, 2]) ** 2
    l2 = (x[i4, 0] - x[i3, 0]) ** 2 + (x[i4, 1] - x[i3, 1]) ** 2 + (x[i4, 2] - x[i3, 2]) ** 2
    rx = x[i3, 0] - x[i1, 0]
    ry = x[i3, 1] - x[i1, 1]
    rz = x[i3, 2] - x[i1, 2]
    if not (rx * rx + ry * ry + rz * rz) * l1 * l2 <= _LINES_GUARD * distance * distance * cc:
        return False  # too near parallel (or too far) for the margin below to cover the rounding; NaN too
    p = rx * cx + ry * cy + rz * cz
    limit = distance * (1.0 + 1e-9)
    return p * p > limit * limit * cc


@nb.njit(cache=True, fastmath=False, inline="always")
def _cross_plane_apart(xs, xe, i1, i2, i3, i4, gap_m):
    """True if the plane square to both segments at the step start (n = d1 x d2) keeps the swept
    end points of segment i1i2 (xs, xe) and those of i3i4 more than gap_m apart: the segments are
    then that far apart during the whole step (module docstring). False for parallel segments and
    NaN."""
    n0, n1, n2 = segment_cross(xs, i1, i2, i3, i4)
    nn = n0 * n0 + n1 * n1 + n2 * n2
    if not nn > 0.0:
        return False
    pa1 = n0 * xs[i1, 0] + n1 * xs[i1, 1] + n2 * xs[i1, 2]
    pa2 = n0 * xs[i2, 0] + n1 * xs[i2, 1] + n2 * xs[i2, 2]
    pa3 = n0 * xe[i1, 0] + n1 * xe[i1, 1] + n2 * xe[i1, 2]
    pa4 = n0 * xe[i2, 0] + n1 * xe[i2, 1] + n2 * xe[i2, 2]
    pb1 = n0 * xs[i3, 0] + n1 * xs[i3, 1] + n2 * xs[i3, 2]
    pb2 = n0 * xs[i4, 0] + n1 * xs[i4, 1] + n2 * xs[i4, 2]
    pb3 = n0 * xe[i3, 0] + n1 * xe[i3, 1] + n2 * xe[i3, 2]
    pb4 = n0 * xe[i4, 0] + n1 * xe[i4, 1] + n2 * xe[i4, 2]
    if not (pa1 + pa2 + pa3 + pa4 + pb1 + pb2 + pb3 + pb4) == (pa1 + pa2 + pa3 + pa4 + pb1 + pb2 + pb3 + pb4):
        return False  # a NaN (min and max below could drop it)
    gap = max(min(min(pa1, pa2), min(pa3, pa4)) - max(max(pb1, pb2), max(pb3, pb4)),
              min(min(pb1, pb2), min(pb3, pb4)) - max(max(pa1, pa2), max(pa3, pa4)))
    return gap > 0.0 and gap * gap > gap_m * gap_m * nn


@nb.njit(cache=True, fastmath=False)
def _coordinate_reach(x_start, x_end, candidates, spring_particle_a, spring_particle_b):
    """Largest |coordinate| of the candidates' end particles at the step start and end: the values
    ``swept_segment_boxes`` spans for the same segments."""
    reach = 0.0
    for k in range(candidates.shape[0]):
        for c in range(2):
            s = candidates[k, c]
            for p in (spring_particle_a[s], spring_particle_b[s]):
                for d in range(3):
                    reach = max(reach, abs(x_start[p, d]), abs(x_end[p, d]))
    return reach


@nb.njit(cache=True, fastmath=False)
def _outside_reach(x, reach, i1, i2, i3, i4):
    """True if one of the four particles lies outside its ``reach`` (see ``particle_reach``)."""
    for p in (i1, i2, i3, i4):
        for d in range(3):
            if x[p, d] < reach[p, d] or x[p, d] > reach[p, 3 + d]:
                return True
    return False


@nb.njit(cache=True, fastmath=False)
def swept_segment_boxes(x_start, x_end, spring_particle_a, spring_particle_b, segments, box_row, box_out):
    """Rows ``box[box_row[s]] = (lo, hi)`` of the listed segments' swept boxes, the very values
    ``_apart_swept`` computes (so the pre-test on them gives the same answers, bit for bit).
    ``box_row`` maps a spring slot to its row of ``box`` (one row per yarn segment, not per slot:
    the boxes were the self-collision stage's largest array, 381 B a crossing when per slot)."""
    for k in range(segments.shape[0]):
        s = segments[k]
        i1 = spring_particle_a[s]
        i2 = spring_particle_b[s]
        r = box_row[s]
        for d in range(3):
            box_out[r, d] = min(min(x_start[i1, d], x_start[i2, d]), min(x_end[i1, d], x_end[i2, d]))
            box_out[r, 3 + d] = max(max(x_start[i1, d], x_start[i2, d]), max(x_end[i1, d], x_end[i2, d]))


@nb.njit(cache=True, fastmath=False)
def end_segment_boxes(x, spring_particle_a, spring_particle_b, segments, box_row, box_out):
    """Rows ``box[box_row[s]] = (lo, hi)`` of the listed segments' boxes at one instant, the very
    values ``_apart_at_end`` computes."""
    for k in range(segments.shape[0]):
        s = segments[k]
        i1 = spring_particle_a[s]
        i2 = spring_particle_b[s]
        r = box_row[s]
        for d in range(3):
            box_out[r, d] = min(x[i1, d], x[i2, d])
            box_out[r, 3 + d] = max(x[i1, d], x[i2, d])


@nb.njit(cache=True, fastmath=False, inline="always")
def _apart_boxes_end(box, i, j, distance):
    """``_apart_at_end`` on the boxes in rows i and j stored by ``end_segment_boxes``: the same
    values, the same expression, the same answer."""
    for k in range(3):
        lo1 = box[i, k]
        hi1 = box[i, 3 + k]
        lo2 = box[j, k]
        hi2 = box[j, 3 + k]
        tol = distance + SEPARATION_REL * (abs(lo1) + abs(hi1) + abs(lo2) + abs(hi2))
        if lo2 - hi1 > tol or lo1 - hi2 > tol:
            return True
    return False


@nb.njit(cache=True, fastmath=False, inline="always")
def _apart_boxes_swept(box, i, j):
    """``_apart_swept`` on the boxes in rows i and j stored by ``swept_segment_boxes``: the same
    values, the same expression, the same answer."""
    for k in range(3):
        lo1 = box[i, k]
        hi1 = box[i, 3 + k]
        lo2 = box[j, k]
        hi2 = box[j, 3 + k]
        tol = SEPARATION_REL * (abs(lo1) + abs(hi1) + abs(lo2) + abs(hi2)) + 1e-300
        if lo2 - hi1 > tol or lo1 - hi2 > tol:
            return True
    return False


@nb.njit(cache=True, fastmath=False)
def ccd_pairs_all(x_start, x_end, candidates, spring_particle_a, spring_particle_b, spring_alive, segments, box_row,
                  box_inout):
    """``ccd_pairs`` on every candidate (no ``moved``), faster: the swept boxes of the listed
    ``segments`` (every segment of the candidates) are computed once into ``box`` (scratch, a row
    per segment at ``box_row[slot]``, >= 6 columns) instead of once per pair; same answers, bit for bit."""
    swept_segment_boxes(x_start, x_end, spring_particle_a, spring_particle_b, segments, box_row, box_inout)
    reach = 0.0  # the largest |coordinate| of the pass, as _coordinate_reach (every box value is one)
    for k in range(segments.shape[0]):
        s = segments[k]
        for d in range(6):
            reach = max(reach, abs(box_inout[box_row[s], d]))
    skip_m = CCD_SKIP_DELTAS * DELTA_REL * reach
    hit = np.zeros(candidates.shape[0], np.bool_)
    t_hit = np.ones(candidates.shape[0])
    count = 0
    seg = np.empty((4, 3))
    for k in range(candidates.shape[0]):
        i = candidates[k, 0]
        j = candidates[k, 1]
        if not (spring_alive[i] and spring_alive[j]):
            continue  # cut since the candidates were built
        if _apart_boxes_swept(box_inout, box_row[i], box_row[j]):
            continue  # (the CCD would report no hit)
        i1, i2 = spring_particle_a[i], spring_particle_b[i]
        i3, i4 = spring_particle_a[j], spring_particle_b[j]
        if _share_end(i1, i2, i3, i4) or _cross_plane_apart(x_start, x_end, i1, i2, i3, i4, skip_m):
            continue
        gap, scale = _plane_gap(x_start, x_end, i1, i2, i3, i4, seg)
        if gap > CCD_SKIP_DELTAS * DELTA_REL * scale:
            continue  # never within CCD_SKIP_DELTAS x the CCD's tolerance delta of each other
        hit[k], t_hit[k] = edge_edge_ccd_kernel(x_start[i1], x_start[i2], x_start[i3], x_start[i4],
                                                x_end[i1], x_end[i2], x_end[i3], x_end[i4], 0.0)
        if hit[k]:
            count += 1
    pairs = np.empty((count, 2), candidates.dtype)
    times = np.empty(count)
    n = 0
    for k in range(candidates.shape[0]):
        if hit[k]:
            pairs[n, 0] = candidates[k, 0]
            pairs[n, 1] = candidates[k, 1]
            times[n] = t_hit[k]
            n += 1
    return pairs, times


@nb.njit(cache=True, fastmath=False)
def ccd_pairs(x_start, x_end, candidates, spring_particle_a, spring_particle_b, spring_alive, moved=None):
    """Narrow phase at thickness 0 on candidate pairs: those whose centre lines meet during the
    step, (K, 2) int32, and their earliest contact times (K,). With `moved` (a flag per particle),
    only pairs with a flagged end point are tested: the others were tested already with the same
    positions and did not hit."""
    hit = np.zeros(candidates.shape[0], np.bool_)
    t_hit = np.ones(candidates.shape[0])
    seg = np.empty((4, 3))
    skip_m = CCD_SKIP_DELTAS * DELTA_REL * _coordinate_reach(x_start, x_end, candidates, spring_particle_a,
                                                             spring_particle_b)
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
        if _cross_plane_apart(x_start, x_end, i1, i2, i3, i4, skip_m):
            continue
        gap, scale = _plane_gap(x_start, x_end, i1, i2, i3, i4, seg)
        if gap > CCD_SKIP_DELTAS * DELTA_REL * scale:
            continue  # never within CCD_SKIP_DELTAS x the CCD's tolerance delta of each other
        hit[k], t_hit[k] = edge_edge_ccd_kernel(x_start[i1], x_start[i2], x_start[i3], x_start[i4],
                                                x_end[i1], x_end[i2], x_end[i3], x_end[i4], 0.0)
    return candidates[hit].copy(), t_hit[hit].copy()
