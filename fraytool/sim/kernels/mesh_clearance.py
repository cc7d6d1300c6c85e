"""Clearance: a lower bound on each mass's distance from each mesh, kept across steps, so that the mesh
contact passes skip what cannot touch (docs/meshes.md, "Clearance").

The unsigned distance to a surface is 1-Lipschitz in the point and in the surface: if a mass was at
distance d from mesh m when its body-frame position was `reference` (the surface then at vertices V),
then wherever it is now (l), against the surface at any time since (each vertex within `travel` of
where it was: a point of a triangle is the same convex combination of vertices that moved at most that
far), its distance is at least

    d - |l - reference| - travel.

A mass moves over a step from l0 to l1 along a straight line (fraytool.sim.kernels.mesh_contact): every
point of that path is within max(|l0 - reference|, |l1 - reference|) of the reference, a ball being
convex. When the bound exceeds the margin the mass's pass would find nothing: no triangle within the
margin at the step's end, and no crossing (a crossing puts the mass on the surface at some time). The
pass skips it and the frames are those of the full pass, bit for bit.

A yarn segment between masses a and b: a point at parameter s is at distance at least
max(D_a - s L, D_b - (1 - s) L), with D the ends' bounds and L the segment's length (longest at the
step's start or end: |a(t) - b(t)| is convex in t); its least value over s is (D_a + D_b - L) / 2.

That bound is weak for a segment much longer than the margin: ends 1 mm off the surface clear a 4 mm
segment of nothing. So each segment also keeps a bound of its own (`SegmentClearanceInOut`): its exact
distance from the mesh when its end points were at `reference` (least over the triangles of the
distances from each end to the triangle, from the segment to each of the triangle's edges, and, where
the segment crosses the triangle's plane, from that crossing point: the closest points of a segment and
a triangle that do not meet lie on an end or an edge). Every point of the segment now is the same
combination of its ends as a point of the reference segment, each end within max(|a0 - a_ref|,
|a1 - a_ref|) of its reference over the step, so its distance is at least

    d_ref - max over both ends of that - travel.

Over the margin (with the CCD's tolerance), the segment's pass would move nothing, as above. Over the
rounding tolerance alone, the segment does not cross the surface, so a closed mesh's corner test
(fraytool.sim.kernels.mesh_contact._segment_through) would find nothing: cloth resting on a smooth body,
its segments just under the margin, runs the sharp edges' test only.

`travel_m[m]` is a running sum, per step, of the largest move of mesh m's vertices (body frame: a
static or rigidly moving mesh never travels); a reference taken during a step stores the sum at that
step's start, so the step's own motion is counted. Positions are read live, so a mass moved by
anything else (a split's placement, the strain limit) keeps a true bound.
"""
from __future__ import annotations

import math
from collections import namedtuple

import numba as nb
import numpy as np

from fraytool.geometry.segments import segment_closest_params
from fraytool.geometry.triangles import closest_on_triangle, triangle_normal
from fraytool.sim.kernels.mesh_bvh import next_leaf, prim_overlaps
from fraytool.sim.kernels.mesh_leaf_cache import next_query_leaf

SKIP_FACTOR = 1.01
"""A mass or segment is skipped when its bound exceeds the margin by 1 % (and the edge CCD's spatial
tolerance, fraytool.collision.ccd.DELTA_REL of the largest coordinate, ten times over)."""
NEAR_MARGINS = 4.0
"""A renewal looks within this many margins first, and out to the full reach only if nothing is that near."""
CCD_SCALE = 1e-5
"""Allowance for the edge CCD's tolerance, relative to the largest body-frame coordinate."""

ClearanceInOut = namedtuple("ClearanceInOut", [
    "reference_m",       # (M, P, 3) body-frame position of particle p when its clearance from mesh m was taken
    "clearance_m",       # (M, P) distance from mesh m then, a lower bound [m]; negative: none (never skip)
    "travel_at_m",       # (M, P) the mesh's travel (travel_m) at the start of the step it was taken in
    "travel_m",          # (M,) mesh m's travel up to the end of the current step [m]
    "travel_start_m",    # (M,) ... up to its start
    "coordinate_scale_m",  # (M,) largest |body-frame coordinate| of mesh m's vertices [m]
    "reach_m",           # float: how far a refresh looks for the nearest triangle [m]
])
ClearanceInOut.__doc__ = "Per-mass clearance bounds from each mesh (module docstring), read and renewed by the passes."

SegmentClearanceInOut = namedtuple("SegmentClearanceInOut", [
    "reference_m",   # (M, S, 2, 3) body-frame end points of spring s when its distance from mesh m was taken
    "clearance_m",   # (M, S) that distance, a lower bound [m]; negative: none (never skip)
    "travel_at_m",   # (M, S) the mesh's travel at the start of the step it was taken in
])
SegmentClearanceInOut.__doc__ = """Per-segment clearance bounds from each mesh (module docstring), a row per spring slot
(the slots of the contact stage's yarn segments change as yarns are cut and cells refine; a slot keeps its bound
meanwhile: a bound is a fact about the reference segment, whatever particles the spring's ends are now); read and
renewed by fraytool.sim.kernels.mesh_contact.segments_touching."""

RENEW_MARGINS = 0.5
"""A segment's bound is taken afresh when it is too low to skip and its ends have moved (or the mesh
travelled) more than this many margins since it was taken: cloth at rest on a body keeps its bound."""


@nb.njit(cache=True, inline="always")
def _dist2(ax, ay, az, b, i):
    """|(ax, ay, az) - b[i]|^2. The bounds below take the largest of several distances as the square root of
    the largest square: the same number (a rounded square root never reverses an order), one root."""
    return (ax - b[i, 0]) ** 2 + (ay - b[i, 1]) ** 2 + (az - b[i, 2]) ** 2


@nb.njit(cache=True, inline="always")
def clearance_left(clear, m, p, x0, y0, z0, x1, y1, z1):
    """Lower bound [m] on particle p's distance from mesh m along its path from (x0, y0, z0) to
    (x1, y1, z1), body frame, against the surface at any time of the current step (module docstring);
    negative when there is none."""
    d = clear.clearance_m[m, p]
    if d < 0.0:
        return -1.0
    ref = clear.reference_m[m]
    r = math.sqrt(max(_dist2(x0, y0, z0, ref, p), _dist2(x1, y1, z1, ref, p)))
    return d - r - (clear.travel_m[m] - clear.travel_at_m[m, p])


@nb.njit(cache=True, inline="always")
def segment_skip_m(clear, m, margin_m, largest_coordinate_m):
    """The bound above which a segment's pass against mesh m cannot move it: the margin, and the edge
    CCD's tolerance (relative to the largest coordinate it sees, the mesh's or the segment's)."""
    return SKIP_FACTOR * margin_m + CCD_SCALE * max(clear.coordinate_scale_m[m], largest_coordinate_m)


@nb.njit(cache=True, inline="always")
def through_skip_m(clear, m, largest_coordinate_m):
    """The bound above which a segment does not cross mesh m's surface (module docstring): a rounding
    tolerance, as the edge CCD's in `segment_skip_m`."""
    return CCD_SCALE * max(clear.coordinate_scale_m[m], largest_coordinate_m)


@nb.njit(cache=True, inline="always")
def point_box(l, reach_m):
    """The query box of a point l (3,) looking within reach_m: (lo x, y, z, hi x, y, z)."""
    return l[0] - reach_m, l[1] - reach_m, l[2] - reach_m, l[0] + reach_m, l[1] + reach_m, l[2] + reach_m


@nb.njit(cache=True, inline="always")
def near_reach_m(clear, margin_m):
    """How far a renewal looks first (NEAR_MARGINS margins, at most the reach)."""
    return min(NEAR_MARGINS * margin_m, clear.reach_m)


@nb.njit(cache=True, inline="always")
def nearest_distance(m, meshes_in, l, reach_m, stack_out, leaves_in, leaf_count):
    """Distance [m] from body-frame point l (3,) to mesh m's surface at the step's end, or reach_m when no
    triangle is nearer (every triangle within reach_m has its box inside the query box, so it is seen). The
    tree's leaves come from a cached list (leaf_count of leaves_in, for the query box `point_box(l,
    reach_m)`: fraytool.sim.kernels.mesh_leaf_cache) or, leaf_count < 0, a walk."""
    vb = meshes_in.vertex_end_m
    tris = meshes_in.triangles
    best2 = reach_m * reach_m
    query = point_box(l, reach_m)
    lo0, lo1, lo2, hi0, hi1, hi2 = query
    stack_out[0] = meshes_in.tri_node_start[m]
    top = 1
    k = 0
    while True:
        node, k, top = next_query_leaf(leaves_in, leaf_count, k, stack_out, top,
                                       (meshes_in.tri_child, meshes_in.tri_box), query)
        if node < 0:
            break
        for q in range(meshes_in.tri_range[node, 0], meshes_in.tri_range[node, 1]):
            j = meshes_in.tri_order[q]
            if not prim_overlaps(meshes_in.tri_box, meshes_in.tri_child, j, lo0, lo1, lo2, hi0, hi1, hi2):
                continue  # (farther than the reach)
            ia, ib, ic = tris[j, 0], tris[j, 1], tris[j, 2]
            qx, qy, qz, _, _, _ = closest_on_triangle(l[0], l[1], l[2], vb[ia, 0], vb[ia, 1], vb[ia, 2],
                                                      vb[ib, 0], vb[ib, 1], vb[ib, 2], vb[ic, 0], vb[ic, 1], vb[ic, 2])
            best2 = min(best2, (l[0] - qx) ** 2 + (l[1] - qy) ** 2 + (l[2] - qz) ** 2)
    # rounding: the square root of a sum of squares may come out a few ulp above the true distance
    return math.sqrt(best2) * (1.0 - 1e-12)


@nb.njit(cache=True, inline="always")
def renew(clearance_m_inout, reference_m_inout, travel_at_m_inout, clear, which, meshes_in, l, touched, margin_m,
          stack_out, near_leaves_in):
    """After particle p's pass against mesh m (which = (m, p)): a mass it moved gets no bound (it touches, it
    will be tested again); another one's distance from its end point l is taken afresh. The first three: the
    ClearanceInOut `clear`'s arrays (plain arrays: a parallel loop's writes through a tuple are lost, numba
    issues 7135 and 10338). near_leaves_in: (leaves, count) for the near query's box (`nearest_distance`)."""
    m, p = which
    if touched:
        clearance_m_inout[m, p] = -1.0
        return
    near = near_reach_m(clear, margin_m)
    leaves, count = near_leaves_in
    d = nearest_distance(m, meshes_in, l, near, stack_out, leaves, count)  # a small box first: most are near
    if d >= near * (1.0 - 1e-9):
        d = nearest_distance(m, meshes_in, l, clear.reach_m, stack_out, leaves, -1)
    clearance_m_inout[m, p] = d
    reference_m_inout[m, p, 0] = l[0]
    reference_m_inout[m, p, 1] = l[1]
    reference_m_inout[m, p, 2] = l[2]
    travel_at_m_inout[m, p] = clear.travel_start_m[m]


@nb.njit(cache=True, inline="always")
def segment_clearance_left(seg_reference_m, seg_clearance_m, seg_travel_at_m, clear, m, s, start, end):
    """Lower bound [m] on segment s's distance from mesh m over the step: `start` and `end` (2, 3) its end
    points at the step's start and end, body frame; the first three, a SegmentClearanceInOut's arrays
    (module docstring). Negative when there is none."""
    d = seg_clearance_m[m, s]
    if d < 0.0:
        return -1.0
    ref = seg_reference_m[m, s]
    r2 = 0.0
    for e in range(2):
        r2 = max(r2, _dist2(start[e, 0], start[e, 1], start[e, 2], ref, e),
                 _dist2(end[e, 0], end[e, 1], end[e, 2], ref, e))
    r = math.sqrt(r2)
    return d - r - (clear.travel_m[m] - seg_travel_at_m[m, s])


@nb.njit(cache=True, inline="always")
def _to_segment(ax, ay, az, bx, by, bz, px, py, pz, qx, qy, qz):
    """Distance between segments ab and pq."""
    s, u = segment_closest_params(ax, ay, az, bx, by, bz, px, py, pz, qx, qy, qz)
    dx = ax + s * (bx - ax) - px - u * (qx - px)
    dy = ay + s * (by - ay) - py - u * (qy - py)
    dz = az + s * (bz - az) - pz - u * (qz - pz)
    return math.sqrt(dx * dx + dy * dy + dz * dz)


@nb.njit(cache=True, inline="always")
def _to_triangle(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz):
    """Distance from point p to triangle abc."""
    qx, qy, qz, _, _, _ = closest_on_triangle(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz)
    return math.sqrt((px - qx) ** 2 + (py - qy) ** 2 + (pz - qz) ** 2)


@nb.njit(cache=True)
def segment_distance(m, meshes_in, a, b, reach_m, stack_out):
    """Distance [m] from the segment ab (body-frame end points, (3,) each) to mesh m's surface at the
    step's end, or reach_m when no triangle is nearer (module docstring: ends, edges, plane crossing)."""
    vb = meshes_in.vertex_end_m
    tris = meshes_in.triangles
    best = reach_m
    lo0, lo1, lo2 = min(a[0], b[0]) - reach_m, min(a[1], b[1]) - reach_m, min(a[2], b[2]) - reach_m
    hi0, hi1, hi2 = max(a[0], b[0]) + reach_m, max(a[1], b[1]) + reach_m, max(a[2], b[2]) + reach_m
    stack_out[0] = meshes_in.tri_node_start[m]
    top = 1
    while True:
        node, top = next_leaf(stack_out, top, meshes_in.tri_child, meshes_in.tri_box, lo0, lo1, lo2, hi0, hi1, hi2)
        if node < 0:
            break
        for q in range(meshes_in.tri_range[node, 0], meshes_in.tri_range[node, 1]):
            j = meshes_in.tri_order[q]
            if not prim_overlaps(meshes_in.tri_box, meshes_in.tri_child, j, lo0, lo1, lo2, hi0, hi1, hi2):
                continue  # (farther than the reach)
            ia, ib, ic = tris[j, 0], tris[j, 1], tris[j, 2]
            ax, ay, az = vb[ia, 0], vb[ia, 1], vb[ia, 2]
            bx, by, bz = vb[ib, 0], vb[ib, 1], vb[ib, 2]
            cx, cy, cz = vb[ic, 0], vb[ic, 1], vb[ic, 2]
            d = min(_to_triangle(a[0], a[1], a[2], ax, ay, az, bx, by, bz, cx, cy, cz),
                    _to_triangle(b[0], b[1], b[2], ax, ay, az, bx, by, bz, cx, cy, cz),
                    _to_segment(a[0], a[1], a[2], b[0], b[1], b[2], ax, ay, az, bx, by, bz),
                    _to_segment(a[0], a[1], a[2], b[0], b[1], b[2], bx, by, bz, cx, cy, cz),
                    _to_segment(a[0], a[1], a[2], b[0], b[1], b[2], cx, cy, cz, ax, ay, az))
            nx, ny, nz = triangle_normal(ax, ay, az, bx, by, bz, cx, cy, cz)
            da = (a[0] - ax) * nx + (a[1] - ay) * ny + (a[2] - az) * nz
            db = (b[0] - ax) * nx + (b[1] - ay) * ny + (b[2] - az) * nz
            if (da > 0.0 and db < 0.0) or (da < 0.0 and db > 0.0):  # through the plane: where, off the triangle
                t = da / (da - db)
                d = min(d, _to_triangle(a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]), a[2] + t * (b[2] - a[2]),
                                        ax, ay, az, bx, by, bz, cx, cy, cz))
            best = min(best, d)
    return best * (1.0 - 1e-12)


@nb.njit(cache=True, inline="always")
def segment_clearance(seg_reference_m_inout, seg_clearance_m_inout, seg_travel_at_m_inout, clear, which, meshes_in,
                      start, end, margin_m, skip_m, stack_out):
    """Segment s's bound from mesh m over the step (`segment_clearance_left`; which = (m, s)), taken afresh
    first, at its end points `end`, when it is not over skip_m (`segment_skip_m`) and the ends have moved
    more than RENEW_MARGINS since it was taken. The first three: a SegmentClearanceInOut's arrays (plain
    arrays: a parallel loop's writes through a tuple are lost, numba issues 7135 and 10338)."""
    m, s = which
    left = segment_clearance_left(seg_reference_m_inout, seg_clearance_m_inout, seg_travel_at_m_inout, clear, m, s,
                                  start, end)
    if left > skip_m:
        return left
    taken = seg_clearance_m_inout[m, s]
    if taken >= 0.0:
        ref = seg_reference_m_inout[m, s]
        moved = math.sqrt(max(_dist2(end[0, 0], end[0, 1], end[0, 2], ref, 0),
                              _dist2(end[1, 0], end[1, 1], end[1, 2], ref, 1)))
        if moved + clear.travel_start_m[m] - seg_travel_at_m_inout[m, s] <= RENEW_MARGINS * margin_m:
            return left  # taken afresh, it would be about as low: what is left is the step's own sweep
    near = min(NEAR_MARGINS * margin_m, clear.reach_m)
    d = segment_distance(m, meshes_in, end[0], end[1], near, stack_out)  # a small box first, as `renew`
    if d >= near * (1.0 - 1e-9):
        d = segment_distance(m, meshes_in, end[0], end[1], clear.reach_m, stack_out)
    seg_clearance_m_inout[m, s] = d
    for e in range(2):
        for c in range(3):
            seg_reference_m_inout[m, s, e, c] = end[e, c]
    seg_travel_at_m_inout[m, s] = clear.travel_start_m[m]
    return segment_clearance_left(seg_reference_m_inout, seg_clearance_m_inout, seg_travel_at_m_inout, clear, m, s,
                                  start, end)


def empty_segment_clearance(meshes: int, segments: int) -> SegmentClearanceInOut:
    """No segment bounds yet."""
    return SegmentClearanceInOut(np.zeros((meshes, segments, 2, 3)), np.full((meshes, segments), -1.0),
                                 np.zeros((meshes, segments)))


def grown_segment_clearance(old: SegmentClearanceInOut, slots: int) -> SegmentClearanceInOut:
    """`old` with rows for at least `slots` spring slots: its own rows kept, new ones without a bound."""
    have = old.clearance_m.shape[1]
    if have >= slots:
        return old
    out = empty_segment_clearance(old.clearance_m.shape[0], slots)
    out.reference_m[:, :have] = old.reference_m
    out.clearance_m[:, :have] = old.clearance_m
    out.travel_at_m[:, :have] = old.travel_at_m
    return out


def empty_clearance(meshes: int, particles: int, coordinate_scale_m: np.ndarray, reach_m: float) -> ClearanceInOut:
    """No bounds yet (every mass tested until its first pass finds its distance)."""
    return ClearanceInOut(np.zeros((meshes, particles, 3)), np.full((meshes, particles), -1.0),
                          np.zeros((meshes, particles)), np.zeros(meshes), np.zeros(meshes), np.asarray(coordinate_scale_m, np.float64),
                          float(reach_m))
