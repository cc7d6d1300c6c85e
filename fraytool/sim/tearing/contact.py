"""Yarn contact at connected mass couples (docs/method.md §3.3), stage 5 of the step.

Only the springs of a couple's own masses are checked: its live weft structural springs (at most
2, on the weft mass) against its live warp structural springs (at most 2, on the warp mass), so at
most 4 pairs per couple, and only couples in the compact list of connected couples are visited.

Closest points. For weft spring p_a q_a and warp spring p_b q_b (each oriented along its yarn, i
then j increasing): a = (1 - t_a) p_a + t_a q_a, b = (1 - t_b) p_b + t_b q_b (Ericson, Real-Time
Collision Detection, §5.1.9), r = a - b, d = |r|.

Projection: mass-weighted and exact. Along a unit direction e (pointing from the warp to the weft
side) the constraint C = r.e - T = 0 is projected as in Bridson, Fedkiw & Anderson (2002):

    lambda = C / (w_pa (1-t_a)^2 + w_qa t_a^2 + w_pb (1-t_b)^2 + w_qb t_b^2)
    dp_a = -lambda w_pa (1 - t_a) e    dq_a = -lambda w_qa t_a e
    dp_b = +lambda w_pb (1 - t_b) e    dq_b = +lambda w_qb t_b e

after which r.e = T exactly at (t_a, t_b) (w = inverse masses; a held mass does not move). The
paper's plain form dp_a = (1 - t_a)(d - T) n_s ... moves the closest points by (d - T) times the sum
of the squared weights, which is 2 at the couple's own masses (t = 0 or 1): it overshoots there.

Cases (docs/tearing.md "Contact"), with nu = (q_a - p_a) x (q_b - p_b) / |...| the pair's crossing
normal (along the cloth normal n_c: weft direction x warp direction), s = +1 where the weft is on top
and h = s (r . nu) the signed separation across the cloth:
- Inside the weave, e = r / d, the paper's n_s: |a - b| -> T for all 4 pairs, closer or further. A
  pair whose closest points are not over each other (a yarn that slid along the other) is pulled
  back in the plane too, so a woven crossing holds its yarns together like the interlacing (and
  its friction) of real cloth does.
- At a free yarn end the contact is one-sided: a pair closer than T is pushed apart along n_s, a
  pair further apart is left alone, free to slide in the plane and to lift off. A couple is at a
  free end when its weft or warp mass has fewer than 2 live structural springs (a cut or the cloth
  border) or a neighbouring crossing along its weft or warp is a disconnected couple. This is what
  lets a cut yarn slip out of the weave crossing by crossing, i.e. fray. (Kept at T both ways, as
  before, the end stayed hooked on its last crossing, and its pull along a normal that turns with
  the free end jerked the yarn back every step: see the next case.)
- A pair that touches (d = 0), or has passed through in this step (h <= 0 now, h > 0 at the start
  of the step, both along today's nu at today's closest-point parameters) and is still closer
  than T, is corrected along s nu, back to its own side. A pair that was on the wrong side
  already, or is further apart than T, counts as on the side it is (the cases above): its springs'
  frame has turned (a sheared or folded crossing; nu flips as two springs turn through parallel),
  or it passed through long ago. A push of T + |h| there is a jump, which the velocity update turns
  into a speed (T + |h|) / dt: energy from nothing, growing as the step shrinks (measured: it made
  the yarn-level region boil at a quarter of the figure scenes' step, and fig5 at a sixteenth).
  Nearly parallel springs (|sin| < 1e-2) have no nu and count as on their side.

Disconnection. The weft-warp distance of a couple is the smallest d over its pairs, taken before
this step's projection. When it exceeds model.disconnect_distance_m (disconnect_factor x T), or
when the couple has no live weft or no live warp spring left, the couple is disconnected for good:
it is never corrected again, and the shear copies at it are cut (no woven cell left to keep).

Serial Gauss-Seidel over couples in crossing order and over pairs in slot order: deterministic.
The kernels take the argument groups of `groups.py` (model_in: TearModel; the State groups).
"""
from __future__ import annotations

import math

import numba as nb
import numpy as np

from fraytool.collision.ccd import edge_edge_ccd_kernel
from fraytool.geometry.segments import segment_closest_params
from fraytool.kinds import SHEAR

SIN_PARALLEL = 1e-2
"""Pairs whose springs are closer to parallel than this |sin(angle)| have no crossing normal."""


@nb.njit(cache=True, fastmath=False)
def crossing_pair_correction(ends_in, starts_in, weights_in, side, thickness_m, slide):
    """The contact correction of one weft/warp spring pair (module docstring), as a pure function.

    ends_in = (pa, qa, pb, qb): weft spring ends, warp spring ends (3-vectors); starts_in = (pa0, qa0,
    pb0, qb0): the same ends at the start of the step (to tell a pass-through in this step from a pair
    that was already on the wrong side); weights_in = (w_pa, w_qa, w_pb, w_qb): inverse masses;
    side = +1.0 where the weft is on top, -1.0 otherwise; slide: correct along the crossing normal
    only (a couple at a free yarn end) instead of along the closest-point direction.
    Returns (d, t_a, t_b, k_pa, k_qa, k_pb, k_qb, n_x, n_y, n_z): closest distance, closest-point
    parameters, and the corrections dp_a = k_pa n, ... along the unit direction n (all k zero when
    nothing is to be corrected)."""
    pa, qa, pb, qb = ends_in
    pa0, qa0, pb0, qb0 = starts_in
    w_pa, w_qa, w_pb, w_qb = weights_in
    ta, tb = segment_closest_params(pa[0], pa[1], pa[2], qa[0], qa[1], qa[2], pb[0], pb[1], pb[2], qb[0], qb[1], qb[2])
    ga, gb = 1.0 - ta, 1.0 - tb
    rx = (ga * pa[0] + ta * qa[0]) - (gb * pb[0] + tb * qb[0])
    ry = (ga * pa[1] + ta * qa[1]) - (gb * pb[1] + tb * qb[1])
    rz = (ga * pa[2] + ta * qa[2]) - (gb * pb[2] + tb * qb[2])
    d = math.sqrt(rx * rx + ry * ry + rz * rz)
    denom = w_pa * ga * ga + w_qa * ta * ta + w_pb * gb * gb + w_qb * tb * tb
    if denom == 0.0:
        return d, ta, tb, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0  # every end held: nothing can move
    ux, uy, uz = qa[0] - pa[0], qa[1] - pa[1], qa[2] - pa[2]
    vx, vy, vz = qb[0] - pb[0], qb[1] - pb[1], qb[2] - pb[2]
    nx = uy * vz - uz * vy
    ny = uz * vx - ux * vz
    nz = ux * vy - uy * vx
    nl = math.sqrt(nx * nx + ny * ny + nz * nz)
    ul = math.sqrt(ux * ux + uy * uy + uz * uz)
    vl = math.sqrt(vx * vx + vy * vy + vz * vz)
    crossing = nl > SIN_PARALLEL * ul * vl and nl > 0.0
    if crossing:
        nx /= nl
        ny /= nl
        nz /= nl
        h = side * (rx * nx + ry * ny + rz * nz)  # signed separation, weft side positive
    else:
        h = d  # (nearly) parallel springs: no crossing normal, no side to keep
    passed = False
    if crossing and h <= 0.0 and d < thickness_m:
        # on its side at the start of the step, along today's normal, at the same parameters?
        h0 = side * (((ga * pa0[0] + ta * qa0[0]) - (gb * pb0[0] + tb * qb0[0])) * nx
                     + ((ga * pa0[1] + ta * qa0[1]) - (gb * pb0[1] + tb * qb0[1])) * ny
                     + ((ga * pa0[2] + ta * qa0[2]) - (gb * pb0[2] + tb * qb0[2])) * nz)
        passed = h0 > 0.0
    if d < 1e-15 or passed:
        # Touching (d = 0), or passed through in this step and still within T: back to its own side
        # along the crossing normal.
        if not crossing:
            return d, ta, tb, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0  # nothing defines a direction
        lam = (h - thickness_m) / denom
        sx, sy, sz = side * nx, side * ny, side * nz  # from the warp towards the weft
    elif slide and d >= thickness_m:
        # A free yarn end apart from the other yarn: free to slide off and to lift off.
        return d, ta, tb, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    else:
        # Along the closest-point direction (the paper's n_s, from b to a here): |a - b| -> T; at a
        # free end only when closer than T.
        lam = (d - thickness_m) / denom
        sx, sy, sz = rx / d, ry / d, rz / d
    return d, ta, tb, -lam * w_pa * ga, -lam * w_qa * ta, lam * w_pb * gb, lam * w_qb * tb, sx, sy, sz


@nb.njit(cache=True, fastmath=False)
def _pair_distance(pa, qa, pb, qb, particle_position_m):
    """Closest distance between springs (pa, qa) and (pb, qb) given by particle slots."""
    x = particle_position_m
    ta, tb = segment_closest_params(x[pa, 0], x[pa, 1], x[pa, 2], x[qa, 0], x[qa, 1], x[qa, 2],
                                    x[pb, 0], x[pb, 1], x[pb, 2], x[qb, 0], x[qb, 1], x[qb, 2])
    s2 = 0.0
    for d in range(3):
        r = (x[pa, d] + ta * (x[qa, d] - x[pa, d])) - (x[pb, d] + tb * (x[qb, d] - x[pb, d]))
        s2 += r * r
    return math.sqrt(s2)


@nb.njit(cache=True, fastmath=False)
def disconnect_couple(c, model_in, crossings_inout, springs_inout):
    """Disconnect couple c and cut the shear springs (both copies) at it: once weft and warp part
    there is no woven cell left for a diagonal to keep. Writes couple_connected and spring_alive."""
    spring_kind, spring_twin = model_in.spring_kind, model_in.spring_twin
    crossing_spring_start, crossing_spring_list = model_in.crossing_spring_start, model_in.crossing_spring_list
    couple_connected = crossings_inout.couple_connected
    spring_alive = springs_inout.spring_alive
    couple_connected[c] = False
    for k in range(crossing_spring_start[c], crossing_spring_start[c + 1]):
        s = crossing_spring_list[k]
        if spring_kind[s] == SHEAR:
            spring_alive[s] = False
            spring_alive[spring_twin[s]] = False


@nb.njit(cache=True, fastmath=False)
def project_couples(model_in, particles_inout, crossings_inout, springs_inout, couple_list_inout, couple_count,
                    prev_position_m):
    """Project the contact of every couple in couple_list_inout[:couple_count] (module docstring).
    Couples that disconnect are flagged in couple_connected (their shear copies cut) and dropped
    from the list, which is compacted in place (order kept). Returns the new couple_count.
    Writes particle_position_m, couple_connected and spring_alive (reads the other State arrays and
    prev_position_m, the positions at the start of the step)."""
    thickness_m, disconnect_distance_m = model_in.thickness_m, model_in.disconnect_distance_m
    crossing_weft_on_top = model_in.crossing_weft_on_top
    crossing_weft_springs, crossing_warp_springs = model_in.crossing_weft_springs, model_in.crossing_warp_springs
    spring_crossing_a, spring_crossing_b = model_in.spring_crossing_a, model_in.spring_crossing_b
    particle_inv_mass = particles_inout.particle_inv_mass
    crossing_yarn_level, couple_connected = crossings_inout.crossing_yarn_level, crossings_inout.couple_connected
    spring_particle_a, spring_particle_b = springs_inout.spring_particle_a, springs_inout.spring_particle_b
    spring_alive = springs_inout.spring_alive
    x = particles_inout.particle_position_m
    kept = 0
    weft = np.zeros(2, np.int64)
    warp = np.zeros(2, np.int64)
    for k in range(couple_count):
        c = couple_list_inout[k]
        if not couple_connected[c]:
            continue  # disconnected elsewhere: drop from the list
        n_weft = 0
        for e in range(2):
            s = crossing_weft_springs[c, e]
            if s >= 0 and spring_alive[s]:
                weft[n_weft] = s
                n_weft += 1
        n_warp = 0
        for e in range(2):
            s = crossing_warp_springs[c, e]
            if s >= 0 and spring_alive[s]:
                warp[n_warp] = s
                n_warp += 1
        if n_weft == 0 or n_warp == 0:
            # One yarn is cut on both sides here: nothing left to hold.
            disconnect_couple(c, model_in, crossings_inout, springs_inout)
            continue
        dmin = 1e300
        for u in range(n_weft):
            for v in range(n_warp):
                sa, sb = weft[u], warp[v]
                d = _pair_distance(spring_particle_a[sa], spring_particle_b[sa], spring_particle_a[sb],
                                   spring_particle_b[sb], x)
                if d < dmin:
                    dmin = d
        if not (dmin <= disconnect_distance_m):
            # Weft and warp have parted (or NaN): never corrected again.
            disconnect_couple(c, model_in, crossings_inout, springs_inout)
            continue
        side = 1.0 if crossing_weft_on_top[c] else -1.0
        slide = n_weft < 2 or n_warp < 2
        for e in range(n_weft):
            o = spring_crossing_a[weft[e]] + spring_crossing_b[weft[e]] - c
            if crossing_yarn_level[o] and not couple_connected[o]:
                slide = True  # the weft is no longer woven on that side: a free end
        for e in range(n_warp):
            o = spring_crossing_a[warp[e]] + spring_crossing_b[warp[e]] - c
            if crossing_yarn_level[o] and not couple_connected[o]:
                slide = True
        for u in range(n_weft):
            for v in range(n_warp):
                sa, sb = weft[u], warp[v]
                pa, qa = spring_particle_a[sa], spring_particle_b[sa]
                pb, qb = spring_particle_a[sb], spring_particle_b[sb]
                d, ta, tb, kpa, kqa, kpb, kqb, nx, ny, nz = crossing_pair_correction(
                    (x[pa], x[qa], x[pb], x[qb]),
                    (prev_position_m[pa], prev_position_m[qa], prev_position_m[pb], prev_position_m[qb]),
                    (particle_inv_mass[pa], particle_inv_mass[qa], particle_inv_mass[pb], particle_inv_mass[qb]),
                    side, thickness_m, slide)
                x[pa, 0] += kpa * nx
                x[pa, 1] += kpa * ny
                x[pa, 2] += kpa * nz
                x[qa, 0] += kqa * nx
                x[qa, 1] += kqa * ny
                x[qa, 2] += kqa * nz
                x[pb, 0] += kpb * nx
                x[pb, 1] += kpb * ny
                x[pb, 2] += kpb * nz
                x[qb, 0] += kqb * nx
                x[qb, 1] += kqb * ny
                x[qb, 2] += kqb * nz
        couple_list_inout[kept] = c
        kept += 1
    return kept


@nb.njit(cache=True, fastmath=False)
def settle_crosses_yarns(x_start, x_end, spring_particle_a, spring_particle_b, segments):
    """Would moving the particles from x_start to x_end (linearly) carry one of `segments` (yarn
    springs) through another? Only segments with a moved end are tested, against every segment
    whose box meets their swept box, with the exact edge-edge CCD (fraytool.collision.ccd, centre
    lines, thickness 0); pairs sharing an end are skipped. For YarnTearing.settle, which moves
    masses after this step's self-collision pass and so must not undo what that pass ensured."""
    n = segments.shape[0]
    box = np.empty((n, 6))
    moving = np.zeros(n, np.bool_)
    union = np.empty(6)
    for k in range(3):
        union[k] = np.inf
        union[3 + k] = -np.inf
    any_moving = False
    for q in range(n):
        pa = spring_particle_a[segments[q]]
        pb = spring_particle_b[segments[q]]
        for k in range(3):
            lo = min(min(x_start[pa, k], x_start[pb, k]), min(x_end[pa, k], x_end[pb, k]))
            hi = max(max(x_start[pa, k], x_start[pb, k]), max(x_end[pa, k], x_end[pb, k]))
            box[q, k] = lo
            box[q, 3 + k] = hi
            if x_start[pa, k] != x_end[pa, k] or x_start[pb, k] != x_end[pb, k]:
                moving[q] = True
        if moving[q]:
            any_moving = True
            for k in range(3):
                union[k] = min(union[k], box[q, k])
                union[3 + k] = max(union[3 + k], box[q, 3 + k])
    if not any_moving:
        return False
    near = np.empty(n, np.int64)
    count = 0
    for q in range(n):
        if moving[q] or (box[q, 0] <= union[3] and box[q, 3] >= union[0] and box[q, 1] <= union[4]
                         and box[q, 4] >= union[1] and box[q, 2] <= union[5] and box[q, 5] >= union[2]):
            near[count] = q
            count += 1
    for i in range(n):
        if not moving[i]:
            continue
        a1 = spring_particle_a[segments[i]]
        b1 = spring_particle_b[segments[i]]
        for r in range(count):
            j = near[r]
            if moving[j] and j <= i:
                continue  # each moving pair once
            if (box[i, 0] > box[j, 3] or box[j, 0] > box[i, 3] or box[i, 1] > box[j, 4] or box[j, 1] > box[i, 4]
                    or box[i, 2] > box[j, 5] or box[j, 2] > box[i, 5]):
                continue
            a2 = spring_particle_a[segments[j]]
            b2 = spring_particle_b[segments[j]]
            if a1 == a2 or a1 == b2 or b1 == a2 or b1 == b2:
                continue
            hit, _ = edge_edge_ccd_kernel(x_start[a1], x_start[b1], x_start[a2], x_start[b2],
                                          x_end[a1], x_end[b1], x_end[a2], x_end[b2], 0.0)
            if hit:
                return True
    return False
