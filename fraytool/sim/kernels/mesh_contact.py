"""Cloth against triangle-mesh bodies: masses against triangles, yarn segments against sharp edges
(docs/meshes.md, "Contact"; one-way: a mesh is kinematic).

Everything is done in the body's frame, l = R^T (x - c), where a static or rigidly moving mesh stands
still; an animated mesh's vertices move linearly over the step from `vertex_start_m` to `vertex_end_m`.
A start-of-step position goes to the body's frame at the step's start, l0 = R0^T (x0 - c0), with R0 =
exp(-dt [omega]x) R the orientation before the step's turn (Rodrigues; R0 = R for a body that does not
turn, fraytool.sim.paths).

Masses (`collide_meshes`): a mass moves over the step from l0 (start-of-step position, body frame at
the step's start) to l1. Continuous test: the path crosses triangle j when its signed distances to j's
plane at the two ends, s0 and s1, differ in sign and the crossing point lies in the triangle (for a
moving triangle, the plane distance is taken as linear in t between the two ends: exact for a
translating triangle, the animated key's linear interpolation otherwise). The earliest crossing puts
the mass back on the side it came from, `margin` (half the yarn thickness) off the plane. Without a
crossing, a mass within `margin` of the mesh is moved out along the direction from its closest point:
for a closed mesh outward (inside/outside by the closest triangle's face normal, the most face-on of
equally close triangles: Baerentzen & Aanaes 2005, "Signed distance computation using the angle
weighted pseudonormal", whose sign this choice reproduces); for an open mesh (two-sided) away from the
surface on the mass's side. Up to PASSES passes per mass (a concave corner). Coulomb friction as for the
analytic bodies (fraytool.sim.kernels.rigid_contact): on the mass's displacement relative to the
surface point it touches, whose move over the step includes the animation's, limited by mu times the push
over all passes (a second pass that moves a mass left a rounding error inside the margin must not take
the first pass's push out of the friction: tests/test_mesh_magnitudes.py, the slope), along the deepest
push's normal, less the other passes' pushes (in a concave corner the wall's push is no sliding along the
floor).

Yarn segments (`collide_mesh_segments`): a segment between two masses against the mesh's sharp edges
(borders and creases, fraytool.meshes.SHARP_DEG), which can pass between two masses. Whether the edge
passes through the segment during the step is the interval edge-edge CCD of fraytool.collision.ccd
(Wang et al. 2021, with the Bridson, Fedkiw & Anderson 2002 coplanarity cubic: no false negatives). A
crossing puts the segment back on its start side along the two lines' common normal, `margin` from
the edge; without one, a segment within `margin` is pushed off. The move goes to the two masses by
their inverse masses and the closest point's parameter (a PBD distance constraint with one side
kinematic), in EDGE_ROUNDS rounds as the closest points slide. Against a closed mesh, a segment whose
middle cuts a corner (both ends outside) has its deepest point moved out (`_segment_through`). On one
thread (segments share masses), in up to SWEEPS sweeps over the segments while one moved; the first sweep's
tests, which find nothing for most segments, run in parallel beforehand (`segments_touching`).
"""
from __future__ import annotations

import math
from collections import namedtuple

import numba as nb
import numpy as np

from fraytool.collision.ccd import edge_edge_ccd_kernel
from fraytool.geometry.frames import rotate, to_body, to_world
from fraytool.geometry.segments import segment_closest_params
from fraytool.geometry.triangles import closest_on_triangle, triangle_normal
from fraytool.sim.kernels.mesh_bvh import next_leaf, overlaps, prim_overlaps
from fraytool.sim.kernels.mesh_clearance import (CCD_SCALE, SKIP_FACTOR, clearance_left, near_reach_m, point_box,
                                                  renew, segment_clearance, segment_clearance_left, segment_skip_m,
                                                  through_skip_m)
from fraytool.sim.kernels.mesh_leaf_cache import CACHE_MARGINS, cached_leaves, next_query_leaf
from fraytool.sim.kernels.rigid_contact import coulomb_friction

PASSES = 3
"""Resolution passes per mass (the second and third only where the first moved it)."""
SWEEPS = 8
"""Sweeps over the yarn segments per step: all of them, then those at a mass the sweep before moved (two
segments share a mass: one's move can undo another's)."""
EDGE_ROUNDS = 4
"""Rounds of a segment's move off one edge (the closest points slide as it moves)."""
STACK = 64
"""BVH traversal stack (trees are balanced: depth about log2(primitives / LEAF_SIZE) + 1)."""

Push = namedtuple("Push", ["moved", "x0", "x1", "x2", "nx", "ny", "nz", "depth", "triangle", "w0", "w1", "w2"])
"""A mass's push off a mesh in one pass (_resolve_point), body frame: moved, the new point (x0, x1, x2), the
unit normal, the depth moved along it [m], the triangle and the barycentric weights of the touched point."""
NO_LEAVES = np.zeros(0, np.int64)
"""The leaf list of a query that walks the tree (fraytool.sim.kernels.mesh_leaf_cache)."""
NO_PUSH = Push(False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1, 0.0, 0.0, 0.0)

MeshesIn = namedtuple("MeshesIn", [
    "body",            # (M,) int64: body index of mesh m
    "closed",          # (M,) bool
    "triangles",       # (T, 3) int32: global vertex indices
    "edges",           # (E, 2) int32: sharp edges, global vertex indices
    "vertex_start_m",  # (V, 3) body frame at the step's start
    "vertex_end_m",    # (V, 3) body frame at the step's end
    "tri_node_start", "tri_child", "tri_range", "tri_box", "tri_order",        # triangle trees (see below)
    "edge_node_start", "edge_child", "edge_range", "edge_box", "edge_order",   # sharp-edge trees
])
MeshesIn.__doc__ = """Mesh bodies' geometry and trees for the contact kernels (fraytool.sim.kernels.mesh_bvh). The box
arrays hold the N nodes' boxes, then each primitive's own (row N + j: `prim_overlaps`)."""


@nb.njit(cache=True, inline="always")
def _dot3(a, b):
    """a . b of two 3-vectors, written out: no BLAS (numba runs `@` on arrays through scipy's)."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@nb.njit(cache=True, inline="always")
def _dist2(a, b):
    """|b - a|^2 of two 3-vectors, without a temporary array."""
    return (b[0] - a[0]) ** 2 + (b[1] - a[1]) ** 2 + (b[2] - a[2]) ** 2


@nb.njit(cache=True, inline="always")
def _vertex(vertices, i):
    return vertices[i, 0], vertices[i, 1], vertices[i, 2]


@nb.njit(cache=True, inline="always")
def _path_box(l0, l1, reach_m):
    """The query box of a mass's pass from l0 to l1 looking within reach_m: (lo x, y, z, hi x, y, z)."""
    pad = reach_m * (1.0 + 1e-9)
    return (min(l0[0], l1[0]) - pad, min(l0[1], l1[1]) - pad, min(l0[2], l1[2]) - pad,
            max(l0[0], l1[0]) + pad, max(l0[1], l1[1]) + pad, max(l0[2], l1[2]) + pad)


@nb.njit(cache=True, inline="always")
def _resolve_point(m, meshes_in, l0, l1, margin_m, reach_m, stack_out, leaves_in, leaf_count):
    """One pass for a mass going from l0 to l1 (body frame) against mesh m, looking for the nearest
    surface within reach_m (>= margin_m) of l1. Returns a Push: whether it moved, the new point, the unit
    normal, the depth (how far it was moved along the normal), the triangle and its barycentric weights.
    The tree's leaves come from the mass's cached list (leaf_count of leaves_in, for the query box
    `_path_box(l0, l1, reach_m)`: fraytool.sim.kernels.mesh_leaf_cache) or, leaf_count < 0, a walk."""
    va, vb = meshes_in.vertex_start_m, meshes_in.vertex_end_m
    tris = meshes_in.triangles
    box = meshes_in.tri_box
    closed = meshes_in.closed[m]
    pad = reach_m * (1.0 + 1e-9)
    query = _path_box(l0, l1, reach_m)
    lo0, lo1, lo2, hi0, hi1, hi2 = query
    best_t = 2.0
    cross_tri = -1
    cross_side = 0.0
    best_d2 = pad * pad  # only triangles within the query box's reach: beyond it, the nearest may be unseen
    best_align = -1.0
    best_tri = -1
    bq0 = bq1 = bq2 = 0.0
    bw0 = bw1 = bw2 = 0.0
    stack_out[0] = meshes_in.tri_node_start[m]
    top = 1
    k = 0
    while True:
        node, k, top = next_query_leaf(leaves_in, leaf_count, k, stack_out, top, (meshes_in.tri_child, box), query)
        if node < 0:
            break
        for q in range(meshes_in.tri_range[node, 0], meshes_in.tri_range[node, 1]):
            j = meshes_in.tri_order[q]
            if not prim_overlaps(meshes_in.tri_box, meshes_in.tri_child, j, lo0, lo1, lo2, hi0, hi1, hi2):
                continue
            ia, ib, ic = tris[j, 0], tris[j, 1], tris[j, 2]
            a1x, a1y, a1z = _vertex(vb, ia)
            b1x, b1y, b1z = _vertex(vb, ib)
            c1x, c1y, c1z = _vertex(vb, ic)
            a0x, a0y, a0z = _vertex(va, ia)
            b0x, b0y, b0z = _vertex(va, ib)
            c0x, c0y, c0z = _vertex(va, ic)
            # plane distances at both ends (unnormalised normals)
            n0x, n0y, n0z = triangle_normal(a0x, a0y, a0z, b0x, b0y, b0z, c0x, c0y, c0z)
            n1x, n1y, n1z = triangle_normal(a1x, a1y, a1z, b1x, b1y, b1z, c1x, c1y, c1z)
            s0 = (l0[0] - a0x) * n0x + (l0[1] - a0y) * n0y + (l0[2] - a0z) * n0z
            s1 = (l1[0] - a1x) * n1x + (l1[1] - a1y) * n1y + (l1[2] - a1z) * n1z
            if (s0 > 0.0 and s1 < 0.0) or (s0 < 0.0 and s1 > 0.0 and not closed):
                t = s0 / (s0 - s1)
                if t < best_t or (t == best_t and j < cross_tri):  # (ties: the lowest index, whatever the tree)
                    px = l0[0] + t * (l1[0] - l0[0])
                    py = l0[1] + t * (l1[1] - l0[1])
                    pz = l0[2] + t * (l1[2] - l0[2])
                    atx, aty, atz = a0x + t * (a1x - a0x), a0y + t * (a1y - a0y), a0z + t * (a1z - a0z)
                    btx, bty, btz = b0x + t * (b1x - b0x), b0y + t * (b1y - b0y), b0z + t * (b1z - b0z)
                    ctx_, cty, ctz = c0x + t * (c1x - c0x), c0y + t * (c1y - c0y), c0z + t * (c1z - c0z)
                    qx, qy, qz, _, _, _ = closest_on_triangle(px, py, pz, atx, aty, atz, btx, bty, btz,
                                                              ctx_, cty, ctz)
                    # in the triangle: the crossing point's closest point is itself (up to rounding)
                    scale = abs(btx - atx) + abs(bty - aty) + abs(btz - atz) + abs(ctx_ - atx) + abs(cty - aty) \
                        + abs(ctz - atz)
                    if (qx - px) ** 2 + (qy - py) ** 2 + (qz - pz) ** 2 <= (1e-9 * scale) ** 2:
                        best_t = t
                        cross_tri = j
                        cross_side = 1.0 if s0 > 0.0 else -1.0
            qx, qy, qz, w0, w1, w2 = closest_on_triangle(l1[0], l1[1], l1[2], a1x, a1y, a1z, b1x, b1y, b1z,
                                                         c1x, c1y, c1z)
            d2 = (l1[0] - qx) ** 2 + (l1[1] - qy) ** 2 + (l1[2] - qz) ** 2
            n1l = math.sqrt(n1x * n1x + n1y * n1y + n1z * n1z)
            align = abs((l1[0] - qx) * n1x + (l1[1] - qy) * n1y + (l1[2] - qz) * n1z) / (n1l * math.sqrt(d2)) \
                if d2 > 0.0 and n1l > 0.0 else 1.0
            tie = best_tri >= 0 and abs(d2 - best_d2) <= 1e-10 * best_d2
            if (d2 < best_d2 and not tie) or (tie and (align > best_align or (align == best_align and j < best_tri))):
                best_d2 = d2
                best_align = align
                best_tri = j
                bq0, bq1, bq2 = qx, qy, qz
                bw0, bw1, bw2 = w0, w1, w2
    if cross_tri >= 0:
        j = cross_tri
        a1x, a1y, a1z = _vertex(vb, tris[j, 0])
        b1x, b1y, b1z = _vertex(vb, tris[j, 1])
        c1x, c1y, c1z = _vertex(vb, tris[j, 2])
        nx, ny, nz = triangle_normal(a1x, a1y, a1z, b1x, b1y, b1z, c1x, c1y, c1z)
        nl = math.sqrt(nx * nx + ny * ny + nz * nz)
        nx, ny, nz = cross_side * nx / nl, cross_side * ny / nl, cross_side * nz / nl
        sd = (l1[0] - a1x) * nx + (l1[1] - a1y) * ny + (l1[2] - a1z) * nz
        depth = margin_m - sd
        x0, x1, x2 = l1[0] + depth * nx, l1[1] + depth * ny, l1[2] + depth * nz
        _, _, _, w0, w1, w2 = closest_on_triangle(x0, x1, x2, a1x, a1y, a1z, b1x, b1y, b1z, c1x, c1y, c1z)
        return Push(True, x0, x1, x2, nx, ny, nz, depth, j, w0, w1, w2)
    if best_tri < 0:
        return NO_PUSH
    d = math.sqrt(best_d2)
    j = best_tri
    a1x, a1y, a1z = _vertex(vb, tris[j, 0])
    b1x, b1y, b1z = _vertex(vb, tris[j, 1])
    c1x, c1y, c1z = _vertex(vb, tris[j, 2])
    fx, fy, fz = triangle_normal(a1x, a1y, a1z, b1x, b1y, b1z, c1x, c1y, c1z)
    fl = math.sqrt(fx * fx + fy * fy + fz * fz)
    fx, fy, fz = fx / fl, fy / fl, fz / fl
    ex, ey, ez = l1[0] - bq0, l1[1] - bq1, l1[2] - bq2
    tiny = 1e-12 * (abs(bq0) + abs(bq1) + abs(bq2) + margin_m)
    if closed:
        inside = ex * fx + ey * fy + ez * fz < 0.0
        sd = -d if inside else d
        if sd >= margin_m:
            return NO_PUSH
        if d > tiny:
            sign = -1.0 if inside else 1.0
            nx, ny, nz = sign * ex / d, sign * ey / d, sign * ez / d
        else:
            nx, ny, nz = fx, fy, fz
    else:
        if d >= margin_m:
            return NO_PUSH
        sd = d
        if d > tiny:
            nx, ny, nz = ex / d, ey / d, ez / d
        else:  # on the sheet: back to the side the mass came from
            a0x, a0y, a0z = _vertex(va, tris[j, 0])
            side = (l0[0] - a0x) * fx + (l0[1] - a0y) * fy + (l0[2] - a0z) * fz
            sign = -1.0 if side < 0.0 else 1.0
            nx, ny, nz = sign * fx, sign * fy, sign * fz
    return Push(True, bq0 + margin_m * nx, bq1 + margin_m * ny, bq2 + margin_m * nz, nx, ny, nz, margin_m - sd, j,
                bw0, bw1, bw2)


@nb.njit(cache=True, inline="always")
def _turned(rot, rot0, row, l):
    """Component `row` of (R - R0) l: a body-frame point's move by the body's turn over the step."""
    return (rot[row, 0] - rot0[row, 0]) * l[0] + (rot[row, 1] - rot0[row, 1]) * l[1] + (rot[row, 2] - rot0[row, 2]) * l[2]


@nb.njit(cache=True)
def start_rotation(rot, omega, dt_s):
    """R0 = exp(-dt [omega]x) R: the orientation at the step's start of a body at orientation R at its end,
    which turned at angular velocity omega (world frame) over the step. Rodrigues' formula
    exp(theta [k]x) = I + sin theta [k]x + (1 - cos theta) [k]x^2; a body that does not turn gets R."""
    theta = dt_s * math.sqrt(omega[0] * omega[0] + omega[1] * omega[1] + omega[2] * omega[2])
    if theta == 0.0:
        return rot.copy()
    kx = -dt_s * omega[0] / theta
    ky = -dt_s * omega[1] / theta
    kz = -dt_s * omega[2] / theta
    s, c = math.sin(theta), 1.0 - math.cos(theta)
    turn = np.array([[1.0 - c * (ky * ky + kz * kz), -s * kz + c * kx * ky, s * ky + c * kx * kz],
                     [s * kz + c * kx * ky, 1.0 - c * (kx * kx + kz * kz), -s * kx + c * ky * kz],
                     [-s * ky + c * kx * kz, s * kx + c * ky * kz, 1.0 - c * (kx * kx + ky * ky)]])
    out = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            out[i, j] = turn[i, 0] * rot[0, j] + turn[i, 1] * rot[1, j] + turn[i, 2] * rot[2, j]
    return out


@nb.njit(cache=True, inline="always")
def _mesh_range(span, frame, meshes_in, particles_in, particle_position_m_inout, clear, clearance_m_inout,
                reference_m_inout, travel_at_m_inout, leaves_inout, leaf_count_inout, leaf_centre_m_inout):
    """Particles particles[lo:hi] against mesh m (span = (particles, lo, hi)); `frame` = (m, margin [m],
    rotation (3, 3), centre at the step's end (3), centre at its start (3), friction, rotation at the step's
    start (3, 3)). A mass whose clearance bound (`clear`, fraytool.sim.kernels.mesh_clearance; its arrays the
    three after it, which the pass renews) is over the margin is skipped; the others' bounds are renewed. The
    last three: a LeafCacheInOut's arrays (fraytool.sim.kernels.mesh_leaf_cache), which the queries read and
    renew. Returns the number of masses in contact."""
    particles, lo, hi = span
    m, margin_m, rot, c1, c0, friction, rot0 = frame
    particle_inv_mass, prev_position_m = particles_in
    box = meshes_in.tri_box
    root = meshes_in.tri_node_start[m]
    pad = margin_m * (1.0 + 1e-9)
    half_m = CACHE_MARGINS * margin_m
    near_m = near_reach_m(clear, margin_m)
    va, vb = meshes_in.vertex_start_m, meshes_in.vertex_end_m
    tris = meshes_in.triangles
    stack_out = np.empty(STACK, np.int64)
    l0 = np.empty(3)
    l1 = np.empty(3)
    pass_normal = np.empty((PASSES, 3))
    hits = 0
    for i in range(lo, hi):
        p = particles[i]
        if particle_inv_mass[p] == 0.0:
            continue
        l1[0], l1[1], l1[2] = to_body(rot, c1, particle_position_m_inout[p, 0], particle_position_m_inout[p, 1],
                                      particle_position_m_inout[p, 2])
        l0[0], l0[1], l0[2] = to_body(rot0, c0, prev_position_m[p, 0], prev_position_m[p, 1], prev_position_m[p, 2])
        if not overlaps(box, root, min(l0[0], l1[0]) - pad, min(l0[1], l1[1]) - pad, min(l0[2], l1[2]) - pad,
                         max(l0[0], l1[0]) + pad, max(l0[1], l1[1]) + pad, max(l0[2], l1[2]) + pad):
            continue
        if clearance_left(clear, m, p, l0[0], l0[1], l0[2], l1[0], l1[1], l1[2]) > SKIP_FACTOR * margin_m:
            continue  # it cannot come within the margin this step: the passes would find nothing
        touched = False
        nx = ny = nz = depth = deepest = 0.0
        tri = -1
        w0 = w1 = w2 = 0.0
        passes = 0
        main_pass = 0
        for _ in range(PASSES):
            n = cached_leaves((m, p), meshes_in, _path_box(l0, l1, margin_m), half_m, leaves_inout, leaf_count_inout,
                              leaf_centre_m_inout, stack_out)
            push = _resolve_point(m, meshes_in, l0, l1, margin_m, margin_m, stack_out, leaves_inout[m, p], n)
            if not push.moved:
                break
            l1[0], l1[1], l1[2] = push.x0, push.x1, push.x2
            if not touched or push.depth > deepest:  # the friction's normal and surface point: the deepest push's
                nx, ny, nz, deepest, tri = push.nx, push.ny, push.nz, push.depth, push.triangle
                w0, w1, w2 = push.w0, push.w1, push.w2
                main_pass = passes
            pass_normal[passes, 0], pass_normal[passes, 1], pass_normal[passes, 2] = push.nx, push.ny, push.nz
            passes += 1
            touched = True
            depth += max(push.depth, 0.0)  # the push over every pass: a later pass may move it a rounding error only
        n = -1 if touched else cached_leaves((m, p), meshes_in, point_box(l1, near_m), half_m, leaves_inout,
                                             leaf_count_inout, leaf_centre_m_inout, stack_out)
        renew(clearance_m_inout, reference_m_inout, travel_at_m_inout, clear, (m, p), meshes_in, l1, touched, margin_m,
              stack_out, (leaves_inout[m, p], n))
        if not touched:
            continue
        hits += 1
        # the touched surface point's move over the step, in the body frame (animation) s, then the world:
        # c1 + R l1 - (c0 + R0 (l1 - s)) = c1 - c0 + R0 s + (R - R0) l1 (the last term zero without a turn)
        ia, ib, ic = tris[tri, 0], tris[tri, 1], tris[tri, 2]
        sx = w0 * (vb[ia, 0] - va[ia, 0]) + w1 * (vb[ib, 0] - va[ib, 0]) + w2 * (vb[ic, 0] - va[ic, 0])
        sy = w0 * (vb[ia, 1] - va[ia, 1]) + w1 * (vb[ib, 1] - va[ib, 1]) + w2 * (vb[ic, 1] - va[ic, 1])
        sz = w0 * (vb[ia, 2] - va[ia, 2]) + w1 * (vb[ib, 2] - va[ib, 2]) + w2 * (vb[ic, 2] - va[ic, 2])
        px, py, pz = to_world(rot, c1, l1[0], l1[1], l1[2])
        gx, gy, gz = rotate(rot, nx, ny, nz)
        mvx = c1[0] - c0[0] + rot0[0, 0] * sx + rot0[0, 1] * sy + rot0[0, 2] * sz + _turned(rot, rot0, 0, l1)
        mvy = c1[1] - c0[1] + rot0[1, 0] * sx + rot0[1, 1] * sy + rot0[1, 2] * sz + _turned(rot, rot0, 1, l1)
        mvz = c1[2] - c0[2] + rot0[2, 0] * sx + rot0[2, 1] * sy + rot0[2, 2] * sz + _turned(rot, rot0, 2, l1)
        # Coulomb friction on the displacement relative to the touched surface point
        rx = px - prev_position_m[p, 0] - mvx
        ry = py - prev_position_m[p, 1] - mvy
        rz = pz - prev_position_m[p, 2] - mvz
        for q in range(passes):  # another face's push (a concave corner) is no sliding along this one
            if q == main_pass:
                continue
            qx, qy, qz = rotate(rot, pass_normal[q, 0], pass_normal[q, 1], pass_normal[q, 2])
            rq = rx * qx + ry * qy + rz * qz
            rx -= rq * qx
            ry -= rq * qy
            rz -= rq * qz
        px, py, pz = coulomb_friction(px, py, pz, rx, ry, rz, gx, gy, gz, friction * max(depth, 0.0))
        particle_position_m_inout[p, 0] = px
        particle_position_m_inout[p, 1] = py
        particle_position_m_inout[p, 2] = pz
    return hits


@nb.njit(cache=True, fastmath=False, parallel=True)
def collide_meshes(
    # the free particles (ascending) and their units (fraytool.sim.kernels.work_split)
    particles, unit_bounds,
    # model and state: the meshes (MeshesIn) and the bodies (fraytool.sim.kernels.bodies.BodiesIn)
    meshes_in, bodies_in, margin_m, dt_s,
    # state in
    particle_inv_mass, prev_position_m,
    # state in/out: positions, the clearance bounds (fraytool.sim.kernels.mesh_clearance.ClearanceInOut) and the
    # leaf lists (fraytool.sim.kernels.mesh_leaf_cache.LeafCacheInOut)
    particle_position_m_inout, clear_inout, leaf_cache_inout,
):
    """Masses against every colliding mesh body, with friction; returns the number of contacts. Each
    mass is independent of the others (a mesh is kinematic; its clearance bounds are its own): parallel
    over the units."""
    contacts = 0
    particles_in = (particle_inv_mass, prev_position_m)
    # the bounds' arrays out of their named tuple (numba drops a parallel loop's writes through a tuple: numba
    # issues 7135, 10338), so that the pass can be inlined into the loop (a call per unit costs twice the work)
    clearance_m, reference_m, travel_at_m = clear_inout.clearance_m, clear_inout.reference_m, clear_inout.travel_at_m
    leaves, leaf_count, leaf_centre_m = leaf_cache_inout
    for m in range(meshes_in.body.shape[0]):
        k = meshes_in.body[m]
        if not bodies_in.collide[k]:
            continue
        c1 = bodies_in.position_m[k].copy()
        c0 = c1 - dt_s * bodies_in.velocity_m_s[k]
        frame = (m, margin_m, bodies_in.rotation[k], c1, c0, bodies_in.friction[k],
                 start_rotation(bodies_in.rotation[k], bodies_in.angular_velocity_rad_s[k], dt_s))
        hits = np.zeros(unit_bounds.shape[0] - 1, np.int64)  # (per unit: a reduction over the inlined pass
        for u in nb.prange(unit_bounds.shape[0] - 1):        # does not compile)
            hits[u] = _mesh_range((particles, unit_bounds[u], unit_bounds[u + 1]), frame, meshes_in, particles_in,
                                  particle_position_m_inout, clear_inout, clearance_m, reference_m, travel_at_m,
                                  leaves, leaf_count, leaf_centre_m)
        contacts += hits.sum()
    return contacts


@nb.njit(cache=True, inline="always")
def _closest_params(p0, p1, q0, q1):
    """(s, u) of the closest points of segments p0 p1 and q0 q1 (3-vectors): fraytool.geometry.segments."""
    return segment_closest_params(p0[0], p0[1], p0[2], p1[0], p1[1], p1[2], q0[0], q0[1], q0[2], q1[0], q1[1], q1[2])


@nb.njit(cache=True, inline="always")
def _largest_move(seg_start, seg_end, e0s, e1s, e0e, e1e):
    """The most a segment's end or an edge's end moves over the step (body frame), 3-vectors and (2, 3)s."""
    return max(math.sqrt(_dist2(seg_start[0], seg_end[0])), math.sqrt(_dist2(seg_start[1], seg_end[1]))) + max(
        math.sqrt(_dist2(e0s, e0e)), math.sqrt(_dist2(e1s, e1e)))


@nb.njit(cache=True, inline="always")
def _largest_abs(seg_start, seg_end, e0s, e1s, e0e, e1e):
    """The largest |coordinate| of a segment and an edge at the step's two ends (the CCD's scale)."""
    largest = 0.0
    for c in range(3):
        largest = max(largest, abs(seg_start[0, c]), abs(seg_start[1, c]), abs(seg_end[0, c]), abs(seg_end[1, c]),
                      abs(e0s[c]), abs(e1s[c]), abs(e0e[c]), abs(e1e[c]))
    return largest


@nb.njit(cache=True, inline="always")
def _segment_pass(m, meshes_in, seg_start, seg_end_inout, inverse_masses, margin_m, stack_out):
    """One pass of a yarn segment against mesh m's sharp edges, body frame: `seg_start` (2, 3) its ends at
    the step's start, `seg_end_inout` (2, 3) at its end (moved in place), `inverse_masses` (w_a, w_b).
    Returns the number of edges it was moved off."""
    va, vb = meshes_in.vertex_start_m, meshes_in.vertex_end_m
    box = meshes_in.edge_box
    la0, lb0 = seg_start[0], seg_start[1]
    la1, lb1 = seg_end_inout[0], seg_end_inout[1]
    wa, wb = inverse_masses
    pad = margin_m * (1.0 + 1e-9)
    lo0 = min(la0[0], lb0[0], la1[0], lb1[0]) - pad
    lo1 = min(la0[1], lb0[1], la1[1], lb1[1]) - pad
    lo2 = min(la0[2], lb0[2], la1[2], lb1[2]) - pad
    hi0 = max(la0[0], lb0[0], la1[0], lb1[0]) + pad
    hi1 = max(la0[1], lb0[1], la1[1], lb1[1]) + pad
    hi2 = max(la0[2], lb0[2], la1[2], lb1[2]) + pad
    contacts = 0
    stack_out[0] = meshes_in.edge_node_start[m]
    top = 1
    while True:
        node, top = next_leaf(stack_out, top, meshes_in.edge_child, box, lo0, lo1, lo2, hi0, hi1, hi2)
        if node < 0:
            break
        for q in range(meshes_in.edge_range[node, 0], meshes_in.edge_range[node, 1]):
            e = meshes_in.edge_order[q]
            if contacts == 0 and not prim_overlaps(meshes_in.edge_box, meshes_in.edge_child, e, lo0, lo1, lo2, hi0,
                                                   hi1, hi2):
                continue  # (once an edge has moved the segment, the query box is stale: test every edge met)
            e0s, e1s = va[meshes_in.edges[e, 0]], va[meshes_in.edges[e, 1]]
            e0e, e1e = vb[meshes_in.edges[e, 0]], vb[meshes_in.edges[e, 1]]
            s1, u1 = _closest_params(la1, lb1, e0e, e1e)
            wx = la1 + s1 * (lb1 - la1) - (e0e + u1 * (e1e - e0e))
            dist = math.sqrt(_dot3(wx, wx))
            # did the edge pass through the segment during the step? (interval CCD, no false negative). Not
            # when they stay apart: their distance at the end less the most any of the four ends moved over
            # the step bounds it at every time (1-Lipschitz), and the CCD reports only pairs that come within
            # its tolerance (DELTA_REL of the largest coordinate; ten times that here)
            crossed = False
            if dist - _largest_move(seg_start, seg_end_inout, e0s, e1s, e0e, e1e) <= CCD_SCALE * _largest_abs(
                    seg_start, seg_end_inout, e0s, e1s, e0e, e1e):
                crossed, _ = edge_edge_ccd_kernel(la0, lb0, e0s, e1s, la1, lb1, e0e, e1e, 0.0)
            if crossed:  # back to the side of the start: along the common normal, oriented by then
                s0, u0 = _closest_params(la0, lb0, e0s, e1s)
                w0 = la0 + s0 * (lb0 - la0) - (e0s + u0 * (e1s - e0s))
                n = np.cross(lb1 - la1, e1e - e0e)
                nl = math.sqrt(_dot3(n, n))
                if nl <= 1e-12 * math.sqrt(_dist2(la1, lb1)) * math.sqrt(_dist2(e0e, e1e)):
                    n = w0  # parallel: the start's closest-point direction
                    nl = math.sqrt(_dot3(n, n))
                if nl <= 0.0:
                    continue
                n = n / nl
                if _dot3(n, w0) < 0.0:
                    n = -n
                sep = _dot3(wx, n)
            elif 0.0 < dist < margin_m * (1.0 - 1e-6):  # (one pushed to the margin stays put)
                n = wx / dist
                sep = dist
            else:
                continue
            # move the segment along n until its gap to the edge along n is the margin: the closest points
            # slide as it moves (a rotating segment), so a few Newton-like rounds, each from the new ones
            for _ in range(EDGE_ROUNDS):
                ca = (1.0 - s1) * wa
                cb = s1 * wb
                denom = (1.0 - s1) * ca + s1 * cb
                if denom <= 0.0:
                    break
                lam = (margin_m - sep) / denom
                for c in range(3):
                    seg_end_inout[0, c] += ca * lam * n[c]
                    seg_end_inout[1, c] += cb * lam * n[c]
                s1, u1 = _closest_params(la1, lb1, e0e, e1e)
                wx = la1 + s1 * (lb1 - la1) - (e0e + u1 * (e1e - e0e))
                sep = _dot3(wx, n)
                if sep >= margin_m * (1.0 - 1e-6):
                    break
            contacts += 1
    return contacts


@nb.njit(cache=True, inline="always")
def _segment_through(m, meshes_in, seg_end_inout, inverse_masses, margin_m, stack_out):
    """A yarn segment whose two ends are outside closed mesh m but whose middle runs through it (it cuts
    a corner): the deepest point, half way between where it enters and leaves the surface, is moved out
    to `margin_m` from the nearest surface, the move shared by the two ends as in `_segment_pass`.
    Returns 1 if it moved the segment, else 0."""
    vb = meshes_in.vertex_end_m
    tris = meshes_in.triangles
    la1, lb1 = seg_end_inout[0], seg_end_inout[1]
    pad = margin_m * (1.0 + 1e-9)
    lo0, lo1, lo2 = min(la1[0], lb1[0]) - pad, min(la1[1], lb1[1]) - pad, min(la1[2], lb1[2]) - pad
    hi0, hi1, hi2 = max(la1[0], lb1[0]) + pad, max(la1[1], lb1[1]) + pad, max(la1[2], lb1[2]) + pad
    first = 2.0
    last = -1.0
    stack_out[0] = meshes_in.tri_node_start[m]
    top = 1
    while True:
        node, top = next_leaf(stack_out, top, meshes_in.tri_child, meshes_in.tri_box, lo0, lo1, lo2, hi0, hi1, hi2)
        if node < 0:
            break
        for q in range(meshes_in.tri_range[node, 0], meshes_in.tri_range[node, 1]):
            j = meshes_in.tri_order[q]
            if not prim_overlaps(meshes_in.tri_box, meshes_in.tri_child, j, lo0, lo1, lo2, hi0, hi1, hi2):
                continue
            ax, ay, az = _vertex(vb, tris[j, 0])
            bx, by, bz = _vertex(vb, tris[j, 1])
            cx, cy, cz = _vertex(vb, tris[j, 2])
            nx, ny, nz = triangle_normal(ax, ay, az, bx, by, bz, cx, cy, cz)
            da = (la1[0] - ax) * nx + (la1[1] - ay) * ny + (la1[2] - az) * nz
            db = (lb1[0] - ax) * nx + (lb1[1] - ay) * ny + (lb1[2] - az) * nz
            if not ((da > 0.0 and db < 0.0) or (da < 0.0 and db > 0.0)):
                continue
            t = da / (da - db)
            px = la1[0] + t * (lb1[0] - la1[0])
            py = la1[1] + t * (lb1[1] - la1[1])
            pz = la1[2] + t * (lb1[2] - la1[2])
            qx, qy, qz, _, _, _ = closest_on_triangle(px, py, pz, ax, ay, az, bx, by, bz, cx, cy, cz)
            scale = abs(bx - ax) + abs(by - ay) + abs(bz - az) + abs(cx - ax) + abs(cy - ay) + abs(cz - az)
            if (qx - px) ** 2 + (qy - py) ** 2 + (qz - pz) ** 2 <= (1e-9 * scale) ** 2:
                first = min(first, t)
                last = max(last, t)
    if last <= first:
        return 0  # no surface crossed, or one: an end is inside, which the masses' pass handles
    sm = 0.5 * (first + last)
    deep = la1 + sm * (lb1 - la1)
    reach = 0.5 * (last - first) * math.sqrt(_dist2(la1, lb1)) + margin_m
    push = _resolve_point(m, meshes_in, deep, deep, margin_m, reach, stack_out, NO_LEAVES, -1)
    if not push.moved:
        return 0
    x0, x1, x2 = push.x0, push.x1, push.x2
    wa, wb = inverse_masses
    ca = (1.0 - sm) * wa
    cb = sm * wb
    denom = (1.0 - sm) * ca + sm * cb
    if denom <= 0.0:
        return 0
    seg_end_inout[0, 0] += ca / denom * (x0 - deep[0])
    seg_end_inout[0, 1] += ca / denom * (x1 - deep[1])
    seg_end_inout[0, 2] += ca / denom * (x2 - deep[2])
    seg_end_inout[1, 0] += cb / denom * (x0 - deep[0])
    seg_end_inout[1, 1] += cb / denom * (x1 - deep[1])
    seg_end_inout[1, 2] += cb / denom * (x2 - deep[2])
    return 1


@nb.njit(cache=True, inline="always")
def _segment_in_body(segments, s, rot, rot0, c0, c1, prev_position_m, particle_position_m, start_out, end_out):
    """Segment s's ends at the step's start and end in the body frame (module docstring) into start_out and
    end_out, (2, 3) each."""
    for end_ in range(2):
        p = segments[s, end_]
        end_out[end_, 0], end_out[end_, 1], end_out[end_, 2] = to_body(
            rot, c1, particle_position_m[p, 0], particle_position_m[p, 1], particle_position_m[p, 2])
        start_out[end_, 0], start_out[end_, 1], start_out[end_, 2] = to_body(
            rot0, c0, prev_position_m[p, 0], prev_position_m[p, 1], prev_position_m[p, 2])


@nb.njit(cache=True, inline="always")
def _segment_near(box, root, start, end, pad):
    """Whether the segment's swept box, grown by pad, overlaps the mesh's root box."""
    return overlaps(box, root, min(start[0, 0], start[1, 0], end[0, 0], end[1, 0]) - pad,
                     min(start[0, 1], start[1, 1], end[0, 1], end[1, 1]) - pad,
                     min(start[0, 2], start[1, 2], end[0, 2], end[1, 2]) - pad,
                     max(start[0, 0], start[1, 0], end[0, 0], end[1, 0]) + pad,
                     max(start[0, 1], start[1, 1], end[0, 1], end[1, 1]) + pad,
                     max(start[0, 2], start[1, 2], end[0, 2], end[1, 2]) + pad)


@nb.njit(cache=True, inline="always")
def _segment_hits(m, meshes_in, sharp, closed, start, end_inout, inverse_masses, margin_m, stack_out):
    """One pass of a segment against mesh m: its sharp edges, then (closed mesh) a corner it cuts."""
    hits = _segment_pass(m, meshes_in, start, end_inout, inverse_masses, margin_m, stack_out) if sharp else 0
    if closed:
        hits += _segment_through(m, meshes_in, end_inout, inverse_masses, margin_m, stack_out)
    return hits


@nb.njit(cache=True, inline="always")
def _mesh_frame(m, meshes_in, bodies_in, dt_s):
    """Mesh m's body frame over the step: (rotation at the end, at the start, centre at the start, at the end),
    and whether it has sharp edges."""
    k = meshes_in.body[m]
    rot = bodies_in.rotation[k]
    rot0 = start_rotation(rot, bodies_in.angular_velocity_rad_s[k], dt_s)
    c1 = bodies_in.position_m[k].copy()
    c0 = c1 - dt_s * bodies_in.velocity_m_s[k]
    sharp = meshes_in.edge_range[meshes_in.edge_node_start[m], 1] > meshes_in.edge_range[meshes_in.edge_node_start[m], 0]
    return rot, rot0, c0, c1, sharp


@nb.njit(cache=True, inline="always")
def _largest_coordinate(start, end):
    """The largest |body-frame coordinate| of a segment's ends over the step."""
    largest = 0.0
    for end_ in range(2):
        for c in range(3):
            largest = max(largest, abs(start[end_, c]), abs(end[end_, c]))
    return largest


@nb.njit(cache=True, inline="always")
def _ends_clear(da, db, start, end, skip_m):
    """Whether a segment's ends' clearance bounds over the step, da and db (`clearance_left`), keep every point of
    it over skip_m (`segment_skip_m`) through the step (fraytool.sim.kernels.mesh_clearance: (D_a + D_b - L) / 2);
    start and end: its end points at the step's start and end (2, 3)."""
    if da < 0.0 or db < 0.0:
        return False
    length = math.sqrt(max(_dist2(start[0], start[1]), _dist2(end[0], end[1])))
    return 0.5 * (da + db - length) > skip_m


@nb.njit(cache=True, inline="always")
def _ends_in_body(ends, lo, hi, frame, clear, particles_in, end_body_m_out, end_left_m_out):
    """Segment ends ends[lo:hi] in mesh m's body frame at the step's start and end (end_body_m_out[p, 0] and [p,
    1], as `_segment_in_body` puts them) and their clearance bounds over the step (end_left_m_out[p],
    `clearance_left`); frame = (m, rot, rot0, c0, c1)."""
    m, rot, rot0, c0, c1 = frame
    prev_position_m, particle_position_m = particles_in
    for i in range(lo, hi):
        p = ends[i]
        end_body_m_out[p, 1, 0], end_body_m_out[p, 1, 1], end_body_m_out[p, 1, 2] = to_body(
            rot, c1, particle_position_m[p, 0], particle_position_m[p, 1], particle_position_m[p, 2])
        end_body_m_out[p, 0, 0], end_body_m_out[p, 0, 1], end_body_m_out[p, 0, 2] = to_body(
            rot0, c0, prev_position_m[p, 0], prev_position_m[p, 1], prev_position_m[p, 2])
        end_left_m_out[p] = clearance_left(clear, m, p, end_body_m_out[p, 0, 0], end_body_m_out[p, 0, 1],
                                           end_body_m_out[p, 0, 2], end_body_m_out[p, 1, 0], end_body_m_out[p, 1, 1],
                                           end_body_m_out[p, 1, 2])


@nb.njit(cache=True, fastmath=False, parallel=True)
def segments_touching(segments_in, meshes_in, bodies_in, margin_m, dt_s, particles_in, clear, seg_clear_inout,
                      touching_out, end_body_m_out, end_left_m_out):
    """touching_out[m, s]: whether segment s's first pass against colliding mesh m would move it, from the
    positions as they are (nothing is written but the flags, the segments' bounds and the ends' scratch).
    segments_in = (segments (S, 3): the end particles and the spring slot of each (its row of the bounds), their
    units, the segments' end particles (ascending, each once), their units); particles_in = (inverse masses,
    start-of-step positions, positions). Parallel over the units: the costly part of collide_mesh_segments' first
    sweep, which then runs only the flagged segments and those at a mass moved before them in the sweep; a segment
    neither flagged nor moved would have met nothing, so the result is the serial sweep's, bit for bit, on any
    number of threads.
    A segment whose ends' clearance bounds (`clear`) or its own (`seg_clear_inout`, renewed here: each
    segment's by one thread) keep all of it over the margin is not tested; one kept off the surface skips
    the corner test (fraytool.sim.kernels.mesh_clearance). Each end's body-frame points and bound are taken
    once per mesh, before the segments (end_body_m_out (P, 2, 3), end_left_m_out (P,), scratch): an end
    belongs to up to four segments."""
    segments, unit_bounds, ends, end_units = segments_in
    particle_inv_mass, prev_position_m, particle_position_m = particles_in
    # the bounds' arrays taken out of their named tuple: numba drops writes made through a tuple in a
    # parallel loop (numba issues 7135, 10338)
    seg_reference_m, seg_clearance_m, seg_travel_at_m = seg_clear_inout
    pad = margin_m * (1.0 + 1e-9)
    for m in range(meshes_in.body.shape[0]):
        if not bodies_in.collide[meshes_in.body[m]]:
            continue
        rot, rot0, c0, c1, sharp = _mesh_frame(m, meshes_in, bodies_in, dt_s)
        for u in nb.prange(end_units.shape[0] - 1):
            _ends_in_body(ends, end_units[u], end_units[u + 1], (m, rot, rot0, c0, c1), clear,
                          (prev_position_m, particle_position_m), end_body_m_out, end_left_m_out)
        for u in nb.prange(unit_bounds.shape[0] - 1):
            stack = np.empty(STACK, np.int64)
            start = np.empty((2, 3))
            end = np.empty((2, 3))
            for s in range(unit_bounds[u], unit_bounds[u + 1]):
                touching_out[m, s] = False
                inverse_masses = (particle_inv_mass[segments[s, 0]], particle_inv_mass[segments[s, 1]])
                if inverse_masses[0] == 0.0 and inverse_masses[1] == 0.0:
                    continue
                for end_ in range(2):
                    p = segments[s, end_]
                    for c in range(3):
                        start[end_, c] = end_body_m_out[p, 0, c]
                        end[end_, c] = end_body_m_out[p, 1, c]
                if not _segment_near(meshes_in.tri_box, meshes_in.tri_node_start[m], start, end, pad):
                    continue
                largest = _largest_coordinate(start, end)
                skip_m = segment_skip_m(clear, m, margin_m, largest)
                if _ends_clear(end_left_m_out[segments[s, 0]], end_left_m_out[segments[s, 1]], start, end, skip_m):
                    continue
                left = segment_clearance(seg_reference_m, seg_clearance_m, seg_travel_at_m, clear, (m, segments[s, 2]),
                                         meshes_in, start, end, margin_m, skip_m, stack)
                if left > skip_m:
                    continue
                # the sharp edges' pass comes first: when it moves nothing, the segment is where its bound holds
                through = meshes_in.closed[m] and left <= through_skip_m(clear, m, largest)
                touching_out[m, s] = _segment_hits(m, meshes_in, sharp, through, start, end, inverse_masses,
                                                   margin_m, stack) > 0


@nb.njit(cache=True, fastmath=False)
def collide_mesh_segments(
    # yarn segments: (S, 3) end particles and spring slot, and which would move in a first pass (segments_touching)
    segments, touching,
    # model and state: the meshes (MeshesIn) and the bodies (BodiesIn)
    meshes_in, bodies_in, margin_m, dt_s,
    # state in
    particle_inv_mass, prev_position_m,
    # state in/out
    particle_position_m_inout,
    # the masses' and the segments' clearance bounds (ClearanceInOut, SegmentClearanceInOut), read only
    bounds_in,
):
    """Yarn segments against the meshes' sharp edges, and through closed meshes (module docstring), up to
    PASSES passes per segment (a corner where edges meet); returns the number of contacts. The first sweep
    visits the segments `touching` flags and those at a mass an earlier segment of the sweep moved. A pass
    whose segment's own bound (`bounds_in`, as in segments_touching, from the positions as they are then)
    clears it of the margin is not made, and one that clears it of the surface makes no corner test."""
    clear, seg_clear = bounds_in
    seg_reference_m, seg_clearance_m, seg_travel_at_m = seg_clear
    contacts = 0
    stack = np.empty(STACK, np.int64)
    start = np.empty((2, 3))
    end = np.empty((2, 3))
    pad = margin_m * (1.0 + 1e-9)
    # segments share masses: sweep again, over the segments at a mass moved in the sweep before
    moved_before = np.zeros(particle_inv_mass.shape[0], np.bool_)
    moved_now = np.zeros(particle_inv_mass.shape[0], np.bool_)
    for sweep in range(SWEEPS):
        swept = 0
        for m in range(meshes_in.body.shape[0]):
            if not bodies_in.collide[meshes_in.body[m]]:
                continue
            rot, rot0, c0, c1, sharp = _mesh_frame(m, meshes_in, bodies_in, dt_s)
            closed = meshes_in.closed[m]
            for s in range(segments.shape[0]):
                a, b = segments[s, 0], segments[s, 1]
                if sweep > 0 and not (moved_before[a] or moved_before[b]):
                    continue
                if sweep == 0 and not (touching[m, s] or moved_now[a] or moved_now[b]):
                    continue  # nothing to meet (segments_touching), and nothing moved it since
                inverse_masses = (particle_inv_mass[a], particle_inv_mass[b])
                if inverse_masses[0] == 0.0 and inverse_masses[1] == 0.0:
                    continue
                _segment_in_body(segments, s, rot, rot0, c0, c1, prev_position_m, particle_position_m_inout,
                                 start, end)
                if not _segment_near(meshes_in.tri_box, meshes_in.tri_node_start[m], start, end, pad):
                    continue
                moved = 0
                for _ in range(PASSES):
                    largest = _largest_coordinate(start, end)
                    left = segment_clearance_left(seg_reference_m, seg_clearance_m, seg_travel_at_m, clear, m,
                                                  segments[s, 2], start, end)
                    if left > segment_skip_m(clear, m, margin_m, largest):
                        break  # the pass would move nothing
                    hits = _segment_pass(m, meshes_in, start, end, inverse_masses, margin_m, stack) if sharp else 0
                    if closed:
                        if hits:  # moved off an edge: the bound from where it is now
                            largest = _largest_coordinate(start, end)
                            left = segment_clearance_left(seg_reference_m, seg_clearance_m, seg_travel_at_m, clear,
                                                          m, segments[s, 2], start, end)
                        if left <= through_skip_m(clear, m, largest):
                            hits += _segment_through(m, meshes_in, end, inverse_masses, margin_m, stack)
                    moved += hits
                    if hits == 0:
                        break
                if moved:
                    swept += moved
                    for end_ in range(2):
                        p = segments[s, end_]
                        moved_now[p] = True
                        particle_position_m_inout[p, 0], particle_position_m_inout[p, 1], \
                            particle_position_m_inout[p, 2] = to_world(rot, c1, end[end_, 0], end[end_, 1], end[end_, 2])
        contacts += swept
        if swept == 0:
            break
        moved_before, moved_now = moved_now, moved_before
        moved_now[:] = False
    return contacts


@nb.njit(cache=True)
def mesh_distances(m, meshes_in, bodies_in, reach_m, x, distance_out):
    """distance_out[i] = unsigned distance [m] of point x[i] from mesh m (at the step's end), or inf
    beyond reach_m."""
    k = meshes_in.body[m]
    rot = bodies_in.rotation[k]
    c = bodies_in.position_m[k]
    stack = np.empty(STACK, np.int64)
    l1 = np.empty(3)
    for i in range(x.shape[0]):
        l1[0], l1[1], l1[2] = to_body(rot, c, x[i, 0], x[i, 1], x[i, 2])
        best = np.inf
        stack[0] = meshes_in.tri_node_start[m]
        top = 1
        while True:
            node, top = next_leaf(stack, top, meshes_in.tri_child, meshes_in.tri_box, l1[0] - reach_m, l1[1] - reach_m,
                                  l1[2] - reach_m, l1[0] + reach_m, l1[1] + reach_m, l1[2] + reach_m)
            if node < 0:
                break
            for q in range(meshes_in.tri_range[node, 0], meshes_in.tri_range[node, 1]):
                j = meshes_in.tri_order[q]
                vb = meshes_in.vertex_end_m
                t = meshes_in.triangles
                qx, qy, qz, _, _, _ = closest_on_triangle(l1[0], l1[1], l1[2], vb[t[j, 0], 0], vb[t[j, 0], 1],
                                                          vb[t[j, 0], 2], vb[t[j, 1], 0], vb[t[j, 1], 1],
                                                          vb[t[j, 1], 2], vb[t[j, 2], 0], vb[t[j, 2], 1],
                                                          vb[t[j, 2], 2])
                best = min(best, math.sqrt((l1[0] - qx) ** 2 + (l1[1] - qy) ** 2 + (l1[2] - qz) ** 2))
        distance_out[i] = best if best <= reach_m else np.inf


@nb.njit(cache=True, fastmath=False)
def place_outside_meshes(
    # model and state: the meshes (MeshesIn) and the bodies (BodiesIn)
    meshes_in, bodies_in, margin_m,
    # state in
    particles, particle_inv_mass,
    # state in/out
    particle_position_m_inout,
):
    """Move each free particle of `particles` within `margin_m` of a colliding mesh (or just inside a
    closed one) out to the margin, without friction: a placement, as rigid_contact.place_outside_bodies
    (masses a split puts into a mesh)."""
    stack = np.empty(STACK, np.int64)
    local = np.empty(3)
    for m in range(meshes_in.body.shape[0]):
        k = meshes_in.body[m]
        if not bodies_in.collide[k]:
            continue
        rot = bodies_in.rotation[k]
        c = bodies_in.position_m[k]
        for i in range(particles.shape[0]):
            p = particles[i]
            if particle_inv_mass[p] == 0.0:
                continue
            local[0], local[1], local[2] = to_body(rot, c, particle_position_m_inout[p, 0],
                                                   particle_position_m_inout[p, 1], particle_position_m_inout[p, 2])
            push = _resolve_point(m, meshes_in, local, local, margin_m, margin_m, stack, NO_LEAVES, -1)
            if push.moved:
                particle_position_m_inout[p, 0], particle_position_m_inout[p, 1], particle_position_m_inout[p, 2] = \
                    to_world(rot, c, push.x0, push.x1, push.x2)
