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

from fraytool.geometry.triangles import closest_on_triangle
from fraytool.sim.kernels.mesh_bvh import next_leaf, prim_overlaps

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


@nb.njit(cache=True, inline="always")
def _dist(ax, ay, az, b, i):
    return math.sqrt((ax - b[i, 0]) ** 2 + (ay - b[i, 1]) ** 2 + (az - b[i, 2]) ** 2)


@nb.njit(cache=True, inline="always")
def clearance_left(clear, m, p, x0, y0, z0, x1, y1, z1):
    """Lower bound [m] on particle p's distance from mesh m along its path from (x0, y0, z0) to
    (x1, y1, z1), body frame, against the surface at any time of the current step (module docstring);
    negative when there is none."""
    d = clear.clearance_m[m, p]
    if d < 0.0:
        return -1.0
    ref = clear.reference_m[m]
    r = max(_dist(x0, y0, z0, ref, p), _dist(x1, y1, z1, ref, p))
    return d - r - (clear.travel_m[m] - clear.travel_at_m[m, p])


@nb.njit(cache=True, inline="always")
def segment_skip_m(clear, m, margin_m, largest_coordinate_m):
    """The bound above which a segment's pass against mesh m cannot move it: the margin, and the edge
    CCD's tolerance (relative to the largest coordinate it sees, the mesh's or the segment's)."""
    return SKIP_FACTOR * margin_m + CCD_SCALE * max(clear.coordinate_scale_m[m], largest_coordinate_m)


@nb.njit(cache=True, inline="always")
def nearest_distance(m, meshes_in, l, reach_m, stack_out):
    """Distance [m] from body-frame point l (3,) to mesh m's surface at the step's end, or reach_m when no
    triangle is nearer (every triangle within reach_m has its box inside the query box, so it is seen)."""
    vb = meshes_in.vertex_end_m
    tris = meshes_in.triangles
    best2 = reach_m * reach_m
    lo0, lo1, lo2 = l[0] - reach_m, l[1] - reach_m, l[2] - reach_m
    hi0, hi1, hi2 = l[0] + reach_m, l[1] + reach_m, l[2] + reach_m
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
            qx, qy, qz, _, _, _ = closest_on_triangle(l[0], l[1], l[2], vb[ia, 0], vb[ia, 1], vb[ia, 2],
                                                      vb[ib, 0], vb[ib, 1], vb[ib, 2], vb[ic, 0], vb[ic, 1], vb[ic, 2])
            best2 = min(best2, (l[0] - qx) ** 2 + (l[1] - qy) ** 2 + (l[2] - qz) ** 2)
    # rounding: the square root of a sum of squares may come out a few ulp above the true distance
    return math.sqrt(best2) * (1.0 - 1e-12)


@nb.njit(cache=True, inline="always")
def renew(clear_inout, m, p, meshes_in, l, touched, margin_m, stack_out):
    """After particle p's pass against mesh m: a mass it moved gets no bound (it touches, it will be tested
    again); another one's distance from its end point l is taken afresh."""
    if touched:
        clear_inout.clearance_m[m, p] = -1.0
        return
    near = min(NEAR_MARGINS * margin_m, clear_inout.reach_m)
    d = nearest_distance(m, meshes_in, l, near, stack_out)  # a small box first: most renewals are near
    if d >= near * (1.0 - 1e-9):
        d = nearest_distance(m, meshes_in, l, clear_inout.reach_m, stack_out)
    clear_inout.clearance_m[m, p] = d
    clear_inout.reference_m[m, p, 0] = l[0]
    clear_inout.reference_m[m, p, 1] = l[1]
    clear_inout.reference_m[m, p, 2] = l[2]
    clear_inout.travel_at_m[m, p] = clear_inout.travel_start_m[m]


def empty_clearance(meshes: int, particles: int, coordinate_scale_m: np.ndarray, reach_m: float) -> ClearanceInOut:
    """No bounds yet (every mass tested until its first pass finds its distance)."""
    return ClearanceInOut(np.zeros((meshes, particles, 3)), np.full((meshes, particles), -1.0),
                          np.zeros((meshes, particles)), np.zeros(meshes), np.zeros(meshes), np.asarray(coordinate_scale_m, np.float64),
                          float(reach_m))
