"""Edge-edge continuous collision detection (narrow phase) for yarn segments (docs/method.md §4.2).

Two segments ``a = a0 a1`` and ``b = b0 b1`` whose end points move linearly over a step,
``p(t) = p_s + t (p_e - p_s)`` for ``t`` in [0, 1]. They are in contact at time ``t`` when the
distance between the two segments is at most the thickness ``h`` (0: actual intersection), i.e.
when for some ``u, v`` in [0, 1]

    F(t, u, v) = [a0(t) + u (a1(t) - a0(t))] - [b0(t) + v (b1(t) - b0(t))],   |F(t, u, v)| <= h.

With ``h = 0`` this is the edge-edge case of Bridson, Fedkiw & Anderson 2002 ("Robust treatment of
collisions, contact and friction for cloth animation", SIGGRAPH 2002): the four points must be
coplanar, i.e. ``t`` must be a root of the cubic

    f(t) = x31(t) . (x21(t) x x43(t)),   xij(t) = xi(t) - xj(t),   (x1, x2, x3, x4) = (a0, a1, b0, b1),

and at that root the segments must actually touch (coplanarity alone is not contact).

Method chosen: **conservative interval exclusion over (t, u, v) boxes, earliest time first** --
the inclusion-based approach of Wang, Ferguson, Schneider, Jiang, Attene & Panozzo 2021 ("A Large
Scale Benchmark and an Inclusion-Based Algorithm for Continuous Collision Detection", ACM TOG
40(5)), with the coplanarity cubic as an interval root filter and a separating-direction bound
that also advances the time conservatively. A box ``T x U x V`` (starting at [0, 1]^3) loses a
part only when one of these outward-rounded tests (:mod:`fraytool.collision.interval`) proves
that no point of that part is in contact:

1. cubic filter (T only): the Bernstein coefficients of ``f`` are computed as intervals
   (:mod:`fraytool.collision.cubic`) and its range over T bounded by de Casteljau subdivision.
   ``|f| = dist(lines) * |x21 x x43| <= dist(segments) * |x21 x x43|``, so contact needs
   ``|f(t)| <= h N`` with ``N >= |x21 x x43|``; T is discarded when the range of ``f`` misses
   ``[-h N, h N]`` (for ``h = 0``: when it does not contain 0). This is the interval root
   isolation of the cubic; for parallel edges or coplanar motion ``f`` vanishes and the proximity
   tests below decide.
2. hull test: F is multilinear in (t, u, v), so its range over the box is spanned by its values at
   the 8 corners; the box is discarded when the hull of the outward-rounded corner values misses
   the ball ``|x| <= h``.
3. separating direction: for any ``n``, ``|F| >= n.F / |n|``. We take ``n`` = the closest-point
   vector of the box's sub-segments at ``T.lo`` (plain floating point: it only chooses the
   direction; by the KKT conditions the bound is then exact at ``T.lo``). For fixed (u, v),
   ``n.F`` is linear in t, and for fixed t bilinear in (u, v), so a lower bound of ``n.F`` over
   the box at any t is the minimum over the 4 (u, v) corners of the linear interpolation of its
   rounded-down corner values at ``T.lo`` and ``T.hi``. The first t where that bound can reach
   ``h |n|`` is a proven-free time ``t_free`` (conservative advancement, as in Mirtich 1996 or
   Tang, Kim & Manocha 2009 "C2A"); the box is discarded when ``t_free >= T.hi``. This is what
   makes first contacts with ``h > 0`` (tangential, flat in u and v) cheap: the hull alone
   would need of the order of 1/delta boxes there.

Boxes come out of a priority queue by smallest ``T.lo`` (:mod:`fraytool.collision.boxqueue`).
When the box popped has ``T.lo = t0``, every point with ``t < t0`` lies in a discarded part, so
there is no contact before ``t0``. The search **accepts** the box, returning ``(True, t0)``, when
it survives the tests and either its sub-segments are within ``h + delta`` at ``t0`` (plain
floating-point distance) or the hull of F is narrower than ``delta``. Otherwise, if
``[t0, t_free)`` is at least ``ADVANCE_FRACTION`` of T, the box is put back as
``[t_free, T.hi] x U x V``; else it is halved: in t while ``width(T) * L_t > delta`` (time
resolution is what the answer needs), else along the larger of ``width * L`` for u and v
(``L_*``: Lipschitz bounds of F). ``delta = DELTA_REL * max(max |coordinate|, h)``.

Why this method: every discard is an inclusion proof, so a box holding a contact is never lost:
no false negatives whatever the degeneracy (parallel edges, a cubic identically zero, coplanar
motion, touching at t = 0 or t = 1, zero-length edges), with no special cases. The reported time
is conservative (never after the first contact) and the segments are within ``h + delta`` of
each other at it. The price is a false positive when the segments come within ``delta`` of
touching without touching. If the search visits ``MAX_BOXES`` boxes it stops and reports a hit
at the smallest ``T.lo`` still open (conservative).

No hit is reported as ``(False, 1.0)``: t = 1.0 means "the whole step is free", which lets a
caller take ``min(t)`` over pairs without special cases. Non-finite input gives ``(True, 0.0)``.
Segments already within the thickness at the start report ``(True, 0.0)``.
"""
from __future__ import annotations

import math

import numba
import numpy as np

from fraytool.collision.boxqueue import ROW, queue_pop, queue_push
from fraytool.collision.cubic import coplanarity_bernstein, cubic_range
from fraytool.collision.interval import (
    iv_add,
    iv_gap_to_zero,
    iv_scale_nonneg,
    iv_sub,
    round_down,
    round_up,
)
from fraytool.geometry.segments import segment_closest_params_rows

DELTA_REL = 1e-6
"""Spatial tolerance of a hit relative to the largest |coordinate|: a hit means the segments come
within thickness + delta. On the sample queries 1e-6, 1e-9 and 1e-12 give the same 90 false
positives (all within 1.3e-12 of touching); 1e-6 keeps near-miss searches short in yarn grids."""
MAX_BOXES = 10_000
"""Cap on boxes visited per query (a few ms); reaching it reports a conservative hit. The sample
queries and the random tests need a few tens at most."""
MAX_QUEUE = 1 << 16
"""Cap on boxes waiting in the search queue; reaching it reports a conservative hit."""
ADVANCE_FRACTION = 0.25
"""A box whose proven-free start [t0, t_free) is at least this fraction of T is shrunk and put
back; otherwise it is split (conservative advancement alone can creep for rotating edges)."""
NO_HIT_TIME = 1.0
"""Time returned with hit == False."""


@numba.njit(cache=True, fastmath=False)
def _f_corners(
    ps: np.ndarray,
    dl: np.ndarray,
    dh: np.ndarray,
    t0: float,
    t1: float,
    u0: float,
    u1: float,
    v0: float,
    v1: float,
    corner_out: np.ndarray,
) -> None:
    """Outward-rounded F at the 8 corners of the box: ``corner[0 / 1, c, k]`` lo / hi of
    component k at corner c = 4 it + 2 iu + iv.

    ``ps[j, k]`` start positions of (a0, a1, b0, b1); ``[dl, dh][j, k]`` the interval of
    ``p_e - p_s``. F is multilinear in (t, u, v): its extremes (and those of any n . F) over the
    box are at the corners.
    """
    for k in range(3):
        for it in range(2):
            t = t0 if it == 0 else t1
            # end points at time t: p_j(t) = ps_j + t * d_j
            ml, mh = iv_scale_nonneg(t, dl[0, k], dh[0, k])
            a0l, a0h = iv_add(ps[0, k], ps[0, k], ml, mh)
            ml, mh = iv_scale_nonneg(t, dl[1, k], dh[1, k])
            a1l, a1h = iv_add(ps[1, k], ps[1, k], ml, mh)
            ml, mh = iv_scale_nonneg(t, dl[2, k], dh[2, k])
            b0l, b0h = iv_add(ps[2, k], ps[2, k], ml, mh)
            ml, mh = iv_scale_nonneg(t, dl[3, k], dh[3, k])
            b1l, b1h = iv_add(ps[3, k], ps[3, k], ml, mh)
            eal, eah = iv_sub(a1l, a1h, a0l, a0h)
            ebl, ebh = iv_sub(b1l, b1h, b0l, b0h)
            for iu in range(2):
                u = u0 if iu == 0 else u1
                ml, mh = iv_scale_nonneg(u, eal, eah)
                al, ah = iv_add(a0l, a0h, ml, mh)
                for iv in range(2):
                    v = v0 if iv == 0 else v1
                    ml, mh = iv_scale_nonneg(v, ebl, ebh)
                    bl, bh = iv_add(b0l, b0h, ml, mh)
                    c = 4 * it + 2 * iu + iv
                    corner_out[0, c, k], corner_out[1, c, k] = iv_sub(al, ah, bl, bh)


DISCARD, ACCEPT, SPLIT = 0, 1, 2
"""Outcomes of the proximity test of one box."""


@numba.njit(cache=True, fastmath=False)
def _positions_at(work_inout: np.ndarray, t: float, u0: float, u1: float, v0: float, v1: float) -> None:
    """work[4] = sub-segments a(t, u0) a(t, u1), b(t, v0) b(t, v1) in plain floating point."""
    for k in range(3):
        a0 = work_inout[0, 0, k] + t * (work_inout[1, 0, k] - work_inout[0, 0, k])
        a1 = work_inout[0, 1, k] + t * (work_inout[1, 1, k] - work_inout[0, 1, k])
        b0 = work_inout[0, 2, k] + t * (work_inout[1, 2, k] - work_inout[0, 2, k])
        b1 = work_inout[0, 3, k] + t * (work_inout[1, 3, k] - work_inout[0, 3, k])
        work_inout[4, 0, k] = a0 + u0 * (a1 - a0)
        work_inout[4, 1, k] = a0 + u1 * (a1 - a0)
        work_inout[4, 2, k] = b0 + v0 * (b1 - b0)
        work_inout[4, 3, k] = b0 + v1 * (b1 - b0)


@numba.njit(cache=True, fastmath=False, inline="always")
def _dot_lower(n0: float, n1: float, n2: float, corner: np.ndarray, c: int) -> float:
    """Lower bound of n . F at corner c, F in the intervals corner[0 / 1, c, :]."""
    p0 = n0 * corner[0, c, 0] if n0 >= 0.0 else n0 * corner[1, c, 0]
    p1 = n1 * corner[0, c, 1] if n1 >= 0.0 else n1 * corner[1, c, 1]
    p2 = n2 * corner[0, c, 2] if n2 >= 0.0 else n2 * corner[1, c, 2]
    return round_down(round_down(round_down(p0) + round_down(p1)) + round_down(p2))


@numba.njit(cache=True, fastmath=False)
def _proximity_status(
    work_inout: np.ndarray,
    corner_inout: np.ndarray,
    t0: float,
    t1: float,
    u0: float,
    u1: float,
    v0: float,
    v1: float,
    h: float,
    h2_up: float,
    h2_down: float,
    delta: float,
) -> tuple[int, float, float]:
    """(DISCARD, ACCEPT or SPLIT, t_free, d0) for the box T x U x V (tests 2-3 and acceptance of
    the module docstring): no point of the box with t < t_free is in contact (t0 <= t_free <= t1);
    d0 is the plain floating-point distance of the sub-segments at t0 (inf if not computed).

    ``work[0] / work[1]`` end points at step start / end, ``work[2:4]`` displacement intervals,
    ``work[4]`` scratch; ``corner`` (2, 8, 3) scratch for F at the box corners.
    ``h2_up >= h^2 >= h2_down``; ``delta`` the acceptance size of the hull of F [m].
    """
    _f_corners(work_inout[0], work_inout[2], work_inout[3], t0, t1, u0, u1, v0, v1, corner_inout)
    # 2. hull B of F over the box: discard when B misses the ball |x| <= h.
    gap2 = 0.0  # lower bound of min |x|^2 over B
    far2 = 0.0  # upper bound of max |x|^2 over B
    width = 0.0
    for k in range(3):
        lo = corner_inout[0, 0, k]
        hi = corner_inout[1, 0, k]
        for c in range(1, 8):
            lo = min(lo, corner_inout[0, c, k])
            hi = max(hi, corner_inout[1, c, k])
        gk = iv_gap_to_zero(lo, hi)  # exact, no rounding
        if gk > 0.0:
            gap2 = round_down(gap2 + round_down(gk * gk))
        fk = max(abs(lo), abs(hi))
        far2 = round_up(far2 + round_up(fk * fk))
        width = max(width, hi - lo)
    if gap2 > h2_up:
        return DISCARD, t1, math.inf
    # 3. separating direction n (closest points of the box's sub-segments at t0; rounding there
    # only weakens the bound): |F| >= n.F / |n|. For fixed (u, v), n.F is linear in t; for fixed
    # t it is bilinear in (u, v), so its minimum over U x V is at the 4 (u, v) corners. Hence
    # n.F >= min over corners c of (1 - s) l0[c] + s l1[c], s = (t - t0) / (t1 - t0), with
    # l0, l1 rounded-down values at t0, t1: no contact before the first s where that falls to
    # h |n| (conservative advancement).
    t_free = t0
    _positions_at(work_inout, t0, u0, u1, v0, v1)
    su, sv = segment_closest_params_rows(work_inout[4])
    n0 = (work_inout[4, 0, 0] + su * (work_inout[4, 1, 0] - work_inout[4, 0, 0])) - (
        work_inout[4, 2, 0] + sv * (work_inout[4, 3, 0] - work_inout[4, 2, 0])
    )
    n1 = (work_inout[4, 0, 1] + su * (work_inout[4, 1, 1] - work_inout[4, 0, 1])) - (
        work_inout[4, 2, 1] + sv * (work_inout[4, 3, 1] - work_inout[4, 2, 1])
    )
    n2 = (work_inout[4, 0, 2] + su * (work_inout[4, 1, 2] - work_inout[4, 0, 2])) - (
        work_inout[4, 2, 2] + sv * (work_inout[4, 3, 2] - work_inout[4, 2, 2])
    )
    d0 = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    n_sq = round_up(round_up(round_up(n0 * n0) + round_up(n1 * n1)) + round_up(n2 * n2))
    if n_sq > 0.0:
        bound = round_up(h * round_up(math.sqrt(n_sq)))
        s_free = math.inf
        for c in range(4):  # (u, v) corner c: corner c at t0, corner 4 + c at t1
            l0 = _dot_lower(n0, n1, n2, corner_inout, c)
            l1 = _dot_lower(n0, n1, n2, corner_inout, c + 4)
            if not l0 > bound:  # (also on NaN)
                s_free = 0.0
                break
            if l1 <= bound:
                s_c = round_down(round_down(l0 - bound) / round_up(l0 - l1))
                s_free = min(s_free, s_c)
            elif not l1 > bound:  # NaN
                s_free = 0.0
                break
        if s_free >= 1.0:
            return DISCARD, t1, d0  # the whole box is farther than h along n
        if s_free > 0.0:
            t_free = min(max(round_down(t0 + round_down(s_free * round_down(t1 - t0))), t0), t1)
    # acceptance: the hull of F is within the tolerance, or the box is entirely in contact.
    if width <= delta or far2 <= h2_down:
        return ACCEPT, t_free, d0
    return SPLIT, t_free, d0


@numba.njit(cache=True, fastmath=False)
def edge_edge_ccd_tol(
    a0s: np.ndarray,
    a1s: np.ndarray,
    b0s: np.ndarray,
    b1s: np.ndarray,
    a0e: np.ndarray,
    a1e: np.ndarray,
    b0e: np.ndarray,
    b1e: np.ndarray,
    thickness: float,
    delta_rel: float,
    max_boxes: int,
) -> tuple[bool, float]:
    """:func:`edge_edge_ccd_kernel` with explicit tolerances (``delta_rel``, ``max_boxes``)."""
    # work[0] / work[1]: end points (a0, a1, b0, b1) at step start / end; work[2] / work[3]:
    # lo / hi of the displacement pe - ps; work[4]: scratch segments. corner: F at box corners.
    work = np.empty((5, 4, 3))
    corner = np.empty((2, 8, 3))
    ps = work[0]
    pe = work[1]
    for k in range(3):
        ps[0, k] = a0s[k]
        ps[1, k] = a1s[k]
        ps[2, k] = b0s[k]
        ps[3, k] = b1s[k]
        pe[0, k] = a0e[k]
        pe[1, k] = a1e[k]
        pe[2, k] = b0e[k]
        pe[3, k] = b1e[k]
    h = max(thickness, 0.0)
    # Guard: a NaN/inf position cannot be reasoned about; report the conservative answer.
    if not math.isfinite(h):
        return True, 0.0
    scale = h
    for j in range(4):
        for k in range(3):
            if not (math.isfinite(ps[j, k]) and math.isfinite(pe[j, k])):
                return True, 0.0
            scale = max(scale, abs(ps[j, k]), abs(pe[j, k]))
            work[2, j, k], work[3, j, k] = iv_sub(pe[j, k], pe[j, k], ps[j, k], ps[j, k])
    delta = max(delta_rel * scale, 2.0**-1000)
    h2_up = round_up(h * h)
    h2_down = round_down(h * h)

    # Root box first: most candidate pairs are far apart and end here, before any set-up.
    root_status, root_t_free, root_d0 = _proximity_status(
        work, corner, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0, h, h2_up, h2_down, delta
    )
    if root_status == DISCARD:
        return False, NO_HIT_TIME

    # Coplanarity cubic 3 f(t) in Bernstein form and the bound |f| <= h |p x q| <= h N.
    coef = np.empty((4, 2))
    n_max = coplanarity_bernstein(ps, pe, coef)
    coplanar_bound = round_up(3.0 * round_up(h * n_max)) if h > 0.0 else 0.0

    # Lipschitz bounds of F (max-norm) in t, u, v: only steer the split choice.
    lip_t = 0.0
    for i in range(2):
        for j in range(2, 4):
            for k in range(3):
                lip_t = max(lip_t, abs((pe[i, k] - ps[i, k]) - (pe[j, k] - ps[j, k])))
    lip_u = 0.0
    lip_v = 0.0
    for k in range(3):
        lip_u = max(lip_u, abs(ps[1, k] - ps[0, k]), abs(pe[1, k] - pe[0, k]))
        lip_v = max(lip_v, abs(ps[3, k] - ps[2, k]), abs(pe[3, k] - pe[2, k]))

    # Best-first search: the box with the smallest T.lo comes out first (boxqueue). Row flag:
    # 1.0 when T already passed the cubic filter (only U or V were split since).
    heap = np.empty((64, ROW))
    heap = queue_push(heap, 0, 0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0)
    size = 1
    seq = 1
    box = np.empty(ROW)
    visited = 0
    while size > 0:
        queue_pop(heap, size, box)
        size -= 1
        t0, t1, u0, u1, v0, v1 = box[0], box[1], box[2], box[3], box[4], box[5]
        visited += 1
        if visited > max_boxes or size + 2 > MAX_QUEUE:
            return True, t0  # conservative: nothing before t0 was found
        # 1. coplanarity filter; depends on T only.
        if box[6] == 0.0:
            c_lo, c_hi = cubic_range(coef, t0, t1)
            # False on NaN, so an overflow never discards a box.
            if c_lo > coplanar_bound or c_hi < -coplanar_bound:
                continue
        # 2.-3. proximity: discard, accept, or split (after advancing T.lo to t_free).
        if visited == 1:  # the root box, tested above
            status, t_free, d0 = root_status, root_t_free, root_d0
        else:
            status, t_free, d0 = _proximity_status(
                work, corner, t0, t1, u0, u1, v0, v1, h, h2_up, h2_down, delta
            )
        if status == DISCARD:
            continue
        # Every point with t < t0 lies in a discarded box (the queue holds only T.lo >= t0), so
        # there is no contact before t0: if this box touches at t0, t0 is the answer.
        if status == ACCEPT or d0 <= h + delta:
            return True, t0
        if t_free - t0 >= ADVANCE_FRACTION * (t1 - t0):
            # [t0, t_free) is free: put the rest back instead of splitting.
            heap = queue_push(heap, size, seq, t_free, t1, u0, u1, v0, v1, 0.0)
            size += 1
            seq += 1
            continue
        t0 = t_free
        ct = (t1 - t0) * lip_t
        cu = (u1 - u0) * lip_u
        cv = (v1 - v0) * lip_v
        if ct > delta or (ct >= cu and ct >= cv):
            tm = 0.5 * (t0 + t1)
            heap = queue_push(heap, size, seq, tm, t1, u0, u1, v0, v1, 0.0)
            heap = queue_push(heap, size + 1, seq + 1, t0, tm, u0, u1, v0, v1, 0.0)
        elif cu >= cv:
            flag = 1.0 if t0 == box[0] else 0.0  # T unchanged: the cubic filter holds
            um = 0.5 * (u0 + u1)
            heap = queue_push(heap, size, seq, t0, t1, um, u1, v0, v1, flag)
            heap = queue_push(heap, size + 1, seq + 1, t0, t1, u0, um, v0, v1, flag)
        else:
            flag = 1.0 if t0 == box[0] else 0.0
            vm = 0.5 * (v0 + v1)
            heap = queue_push(heap, size, seq, t0, t1, u0, u1, vm, v1, flag)
            heap = queue_push(heap, size + 1, seq + 1, t0, t1, u0, u1, v0, vm, flag)
        size += 2
        seq += 2
    return False, NO_HIT_TIME


@numba.njit(cache=True, fastmath=False)
def edge_edge_ccd_kernel(
    a0s: np.ndarray,
    a1s: np.ndarray,
    b0s: np.ndarray,
    b1s: np.ndarray,
    a0e: np.ndarray,
    a1e: np.ndarray,
    b0e: np.ndarray,
    b1e: np.ndarray,
    thickness: float,
) -> tuple[bool, float]:
    """Edge-edge CCD kernel, callable from other numba kernels.

    Args (float64 arrays of shape (3,), positions [m]; scalar [m]):
        a0s, a1s, b0s, b1s: end points of segments a and b at the start of the step;
        a0e, a1e, b0e, b1e: the same end points at the end of the step;
        thickness: contact distance h between the centre lines [m] (0: actual intersection).

    Returns:
        (hit, t): hit is True if the segments come within ``thickness`` (up to the tolerance
        ``delta = DELTA_REL * scale``) at some t in [0, 1]; t is the earliest such time,
        conservative (never later than the true first contact; within thickness + delta at t),
        and 1.0 (NO_HIT_TIME) when there is no hit.
    """
    return edge_edge_ccd_tol(
        a0s, a1s, b0s, b1s, a0e, a1e, b0e, b1e, thickness, DELTA_REL, MAX_BOXES
    )


def edge_edge_ccd(
    x_start: np.ndarray, x_end: np.ndarray, thickness: float = 0.0
) -> tuple[bool, float]:
    """Continuous collision test of two linearly moving segments over one step.

    Args:
        x_start: positions at the step start [m], shape (4, 3), rows a0, a1, b0, b1.
        x_end: positions at the step end [m], shape (4, 3), same rows.
        thickness: contact distance between the centre lines [m], >= 0.

    Returns:
        (hit, t): t in [0, 1] is the earliest contact time when hit is True (conservative: never
        later than the true first contact); t = 1.0 when hit is False.

    See the module docstring for the method (Wang et al. 2021 interval inclusion over (t, u, v)
    boxes, with the Bridson et al. 2002 coplanarity cubic as an interval root filter).
    """
    xs = np.ascontiguousarray(x_start, dtype=np.float64)
    xe = np.ascontiguousarray(x_end, dtype=np.float64)
    if xs.shape != (4, 3) or xe.shape != (4, 3):
        raise ValueError(f"x_start and x_end must have shape (4, 3), got {xs.shape} and {xe.shape}")
    if not thickness >= 0.0:
        raise ValueError(f"thickness must be >= 0, got {thickness}")
    hit, t = edge_edge_ccd_kernel(
        xs[0], xs[1], xs[2], xs[3], xe[0], xe[1], xe[2], xe[3], float(thickness)
    )
    return bool(hit), float(t)


@numba.njit(cache=True, fastmath=False)
def edge_edge_ccd_many_kernel(
    x_start: np.ndarray, x_end: np.ndarray, thickness: float, hit_out: np.ndarray, t_out: np.ndarray
) -> None:
    """:func:`edge_edge_ccd_kernel` over Q queries: x_start, x_end (Q, 4, 3) -> hit_out, t_out (Q,)."""
    for q in range(x_start.shape[0]):
        xs = x_start[q]
        xe = x_end[q]
        hit_out[q], t_out[q] = edge_edge_ccd_kernel(
            xs[0], xs[1], xs[2], xs[3], xe[0], xe[1], xe[2], xe[3], thickness
        )


def edge_edge_ccd_many(
    x_start: np.ndarray, x_end: np.ndarray, thickness: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`edge_edge_ccd` for a batch: x_start, x_end (Q, 4, 3) [m] -> hit (Q,) bool, t (Q,)."""
    xs = np.ascontiguousarray(x_start, dtype=np.float64)
    xe = np.ascontiguousarray(x_end, dtype=np.float64)
    if xs.ndim != 3 or xs.shape[1:] != (4, 3) or xe.shape != xs.shape:
        raise ValueError(f"x_start and x_end must have shape (Q, 4, 3), got {xs.shape}, {xe.shape}")
    if not thickness >= 0.0:
        raise ValueError(f"thickness must be >= 0, got {thickness}")
    hit = np.zeros(xs.shape[0], dtype=np.bool_)
    t = np.empty(xs.shape[0])
    edge_edge_ccd_many_kernel(xs, xe, float(thickness), hit, t)
    return hit, t
