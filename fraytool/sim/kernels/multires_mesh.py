"""Coarse cells against triangle-mesh bodies (docs/multires.md, "Against a mesh").

A coarse cell's nodes are masses: they collide with a mesh like every free crossing
(fraytool.sim.kernels.mesh_contact). Its slaved crossings do not. They are points of the bilinear patch of
the nodes, convex combinations of them, so none is farther than D from any node, D being the largest
distance between two of the nodes; and the nodes are outside the mesh (contact keeps them there). Each
step, after contact, every slaved crossing is checked against each colliding mesh:

- on a **closed mesh without sharp edges** (tested by depth): a slaved crossing below the surface refines
  every coarse cell holding it. It becomes a mass, within the margin of the surface, and the next mass pass
  puts it back on the margin. One between the surface and the margin is left: the coarse cell rests on
  the mesh through its nodes. A point below the surface is at most D below it (the segment to an outside
  node crosses the surface within D), so a query that far finds its triangle; the nearest triangle, the
  most face-on of equally near ones, says which side;
- on an **open mesh** (a sheet has no inside), one with **sharp edges** (yarns catch on them at yarn
  resolution) or one with **thin parts** (a bend radius under 1.5 yarn segments: a rod or a needle can pass
  between the crossings with none inside it; fraytool.sim.multires.colliding_meshes): a slaved crossing
  within half a yarn segment plus the margin of the mesh refines its cells. A sharp edge, a thin part or a
  sheet that touches a yarn segment is within half its length of one of its ends, so the free ends of the
  segments with a slaved end (nodes, and crossings beside hanging nodes) are tested too: the mesh segment
  pass leaves those segments out.

It assumes what contact keeps: the nodes (free masses) are outside the mesh. The test is per mesh, so one
sharp edge anywhere on a mesh puts all of it under the distance test: cloth resting anywhere on it refines.

**Bounds.** The (signed) distance is 1-Lipschitz in the point and in the surface, as the clearance of the
mass pass (fraytool.sim.kernels.mesh_clearance): a crossing queried at distance v, at body-frame point
`reference`, is now at least v - |l - reference| - (the mesh's travel since) away, on the same side. While
that stays over the floor (0, or the unsigned threshold) it is not queried again. A cell keeps the least of its
crossings' bounds the same way, against its nodes' moves (a slaved crossing moves no farther than the farthest
node), and is passed over whole while that stays over the floor. Cloth resting on a body moves little from step
to step, so most cells are passed over and most slaved crossings are queried once in many steps.

So cloth that lies on a smooth body stays coarse; where it wraps round a tighter curve than its cells
can follow (the middle of a cell sags into the surface by about D^2 / 4R on a radius R), it refines.
"""
from __future__ import annotations

import math
from collections import namedtuple

import numba as nb
import numpy as np

from fraytool.geometry.frames import to_body
from fraytool.geometry.triangles import closest_on_triangle
from fraytool.sim.kernels.mesh_bvh import next_leaf, prim_overlaps


@nb.njit(cache=True, inline="always")
def signed_distance(m, meshes_in, l, reach_m, stack_out):
    """(distance [m] from body-frame point l to mesh m's surface at the step's end, True where l is inside
    the closed mesh m), from the nearest triangle within reach_m, the most face-on of equally near ones
    (ties to the lowest index); (reach_m, False) when no triangle is that near."""
    vb = meshes_in.vertex_end_m
    tris = meshes_in.triangles
    best_d2 = reach_m * reach_m
    best_align = -1.0
    best_tri = -1
    inside = False
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
                continue
            ia, ib, ic = tris[j, 0], tris[j, 1], tris[j, 2]
            ax, ay, az = vb[ia, 0], vb[ia, 1], vb[ia, 2]
            bx, by, bz = vb[ib, 0], vb[ib, 1], vb[ib, 2]
            cx, cy, cz = vb[ic, 0], vb[ic, 1], vb[ic, 2]
            qx, qy, qz, _, _, _ = closest_on_triangle(l[0], l[1], l[2], ax, ay, az, bx, by, bz, cx, cy, cz)
            ex, ey, ez = l[0] - qx, l[1] - qy, l[2] - qz
            d2 = ex * ex + ey * ey + ez * ez
            nx = (by - ay) * (cz - az) - (bz - az) * (cy - ay)
            ny = (bz - az) * (cx - ax) - (bx - ax) * (cz - az)
            nz = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
            nl = math.sqrt(nx * nx + ny * ny + nz * nz)
            side = ex * nx + ey * ny + ez * nz
            align = abs(side) / (nl * math.sqrt(d2)) if d2 > 0.0 and nl > 0.0 else 1.0
            tie = best_tri >= 0 and abs(d2 - best_d2) <= 1e-10 * best_d2
            if (d2 < best_d2 and not tie) or (tie and (align > best_align or (align == best_align and j < best_tri))):
                best_d2, best_align, best_tri = d2, align, j
                inside = side < 0.0
    if best_tri < 0:
        return reach_m, False
    return math.sqrt(best_d2), inside


@nb.njit(cache=True, inline="always")
def _mark_holding(s, crossing_cells, refined, new_inout):
    """Mark every coarse cell holding crossing s; returns how many were newly marked."""
    count = 0
    for r in range(crossing_cells.shape[1]):
        t = crossing_cells[s, r]
        if t >= 0 and not refined[t] and not new_inout[t]:
            new_inout[t] = True
            count += 1
    return count


BoundsInOut = namedtuple("BoundsInOut", [
    "value_m",             # (M, C): the slaved crossing's distance from mesh m when last queried, signed
                           # (negative inside) on a mesh tested by depth; -inf: never queried
    "reference_m",         # (M, C, 3): where it was then, in the mesh body's frame
    "travel_at_m",         # (M, C): the mesh's travel then (MeshGeometry.clearance.travel_m)
    "group_value_m",       # (M, cells): the least of the bounds of a cell's slaved crossings when they were
                           # last gone through; -inf: never
    "group_reference_m",   # (M, cells, 4, 3): where the cell's nodes were then, in the mesh body's frame
    "group_travel_at_m",   # (M, cells): the mesh's travel then
])


def empty_bounds(meshes: int, crossings: int, cells: int) -> BoundsInOut:
    return BoundsInOut(np.full((meshes, crossings), -np.inf), np.zeros((meshes, crossings, 3)),
                       np.zeros((meshes, crossings)), np.full((meshes, cells), -np.inf),
                       np.zeros((meshes, cells, 4, 3)), np.zeros((meshes, cells)))


@nb.njit(cache=True, fastmath=False)
def cells_on_meshes(
    # the colliding meshes as (meshes, for each the least distance [m] a slaved crossing may come to (0 on a
    # closed mesh without sharp edges, tested by depth: below the surface is below 0), whether it is unsigned)
    tested_in,
    # fraytool.sim.kernels.mesh_contact.MeshesIn (at the step's end), BodiesIn, each mesh's travel so far
    meshes_in, bodies_in, travel_m,
    # (the slaved crossings by the cell they interpolate: cell_start, cell_slaved; the cells' nodes; each
    # crossing's cells, nodes and weights; the yarn segments with one free and one slaved end, as (free
    # ends, slaved ends): fraytool.sim.multires.mixed_segments)
    cells_in,
    # state in; in: refined cells; in/out: the bounds (BoundsInOut); scratch: (BVH stack, a point, the
    # nodes of a cell (4, 3))
    particle_position_m, refined, bounds_inout, scratch_inout,
    # in/out: cells to refine now (the ones found are added)
    new_inout,
):
    """Mark in `new` the coarse cells that a mesh makes refine now (module docstring); returns how many.

    A cell's slaved crossings are convex combinations of its nodes, so none has moved farther than the
    farthest node: while the least of their bounds, less that move and the mesh's travel, stays over the
    floor, the cell is passed over whole."""
    meshes, threshold_m, unsigned = tested_in
    cell_start, cell_slaved, cell_nodes, crossing_cells, crossing_node, crossing_weight, mixed = cells_in
    mixed_free, mixed_slaved = mixed
    stack_out, point_out, nodes_out = scratch_inout
    count = 0
    for c in range(cell_start.shape[0] - 1):
        if cell_start[c] == cell_start[c + 1]:
            continue
        for mi in range(meshes.shape[0]):
            m = meshes[mi]
            k = meshes_in.body[m]
            rot, centre = bodies_in.rotation[k], bodies_in.position_m[k]
            floor = threshold_m[mi]
            moved2 = 0.0
            for q in range(4):
                p = cell_nodes[c, q]
                l0, l1, l2 = to_body(rot, centre, particle_position_m[p, 0], particle_position_m[p, 1],
                                     particle_position_m[p, 2])
                nodes_out[q, 0], nodes_out[q, 1], nodes_out[q, 2] = l0, l1, l2
                moved2 = max(moved2, (l0 - bounds_inout.group_reference_m[mi, c, q, 0]) ** 2
                             + (l1 - bounds_inout.group_reference_m[mi, c, q, 1]) ** 2
                             + (l2 - bounds_inout.group_reference_m[mi, c, q, 2]) ** 2)
            if bounds_inout.group_value_m[mi, c] - math.sqrt(moved2) \
                    - (travel_m[m] - bounds_inout.group_travel_at_m[mi, c]) > floor:
                continue  # no slaved crossing of the cell can have come nearer than the floor
            # the cell's size: a slaved point below the surface is within it of the surface (an outside node
            # is that near), so a query this far finds its triangle
            size2 = 0.0
            for a in range(4):
                for b in range(a + 1, 4):
                    size2 = max(size2, (nodes_out[b, 0] - nodes_out[a, 0]) ** 2 + (nodes_out[b, 1] - nodes_out[a, 1]) ** 2
                                + (nodes_out[b, 2] - nodes_out[a, 2]) ** 2)
            size = math.sqrt(size2) * (1.0 + 1e-12)
            reach = (max(size, floor) + floor) * (1.0 + 1e-9) + 1e-12
            least = np.inf
            for i in range(cell_start[c], cell_start[c + 1]):
                s = cell_slaved[i]
                x0 = x1 = x2 = 0.0
                for q in range(4):
                    w, p = crossing_weight[s, q], crossing_node[s, q]
                    x0 += w * particle_position_m[p, 0]
                    x1 += w * particle_position_m[p, 1]
                    x2 += w * particle_position_m[p, 2]
                l0, l1, l2 = to_body(rot, centre, x0, x1, x2)
                e0 = l0 - bounds_inout.reference_m[mi, s, 0]
                e1 = l1 - bounds_inout.reference_m[mi, s, 1]
                e2 = l2 - bounds_inout.reference_m[mi, s, 2]
                left = bounds_inout.value_m[mi, s] - math.sqrt(e0 * e0 + e1 * e1 + e2 * e2) \
                    - (travel_m[m] - bounds_inout.travel_at_m[mi, s])
                if left > floor:
                    least = min(least, left)
                    continue  # it cannot have come nearer than the floor since it was last queried
                point_out[0], point_out[1], point_out[2] = l0, l1, l2
                d, inside = signed_distance(m, meshes_in, point_out, reach, stack_out)
                value = -d if inside and not unsigned[mi] else d
                if value <= floor:
                    count += _mark_holding(s, crossing_cells, refined, new_inout)  # (free from the next step)
                    bounds_inout.value_m[mi, s] = -np.inf
                else:
                    value *= 1.0 - 1e-12
                    least = min(least, value)
                    bounds_inout.value_m[mi, s] = value
                    bounds_inout.reference_m[mi, s, 0] = l0
                    bounds_inout.reference_m[mi, s, 1] = l1
                    bounds_inout.reference_m[mi, s, 2] = l2
                    bounds_inout.travel_at_m[mi, s] = travel_m[m]
            bounds_inout.group_value_m[mi, c] = least
            for q in range(4):
                for r in range(3):
                    bounds_inout.group_reference_m[mi, c, q, r] = nodes_out[q, r]
            bounds_inout.group_travel_at_m[mi, c] = travel_m[m]
    # on a mesh tested by distance, a sharp edge or thin part touching a segment with a slaved end is within
    # half the segment of one of its ends: the free one too (the segment pass leaves such segments out)
    for mi in range(meshes.shape[0]):
        if not unsigned[mi]:
            continue
        m = meshes[mi]
        k = meshes_in.body[m]
        rot, centre = bodies_in.rotation[k], bodies_in.position_m[k]
        floor = threshold_m[mi]
        reach = 2.0 * floor * (1.0 + 1e-9)
        for i in range(mixed_free.shape[0]):
            f = mixed_free[i]
            l0, l1, l2 = to_body(rot, centre, particle_position_m[f, 0], particle_position_m[f, 1],
                                 particle_position_m[f, 2])
            e0 = l0 - bounds_inout.reference_m[mi, f, 0]
            e1 = l1 - bounds_inout.reference_m[mi, f, 1]
            e2 = l2 - bounds_inout.reference_m[mi, f, 2]
            if bounds_inout.value_m[mi, f] - math.sqrt(e0 * e0 + e1 * e1 + e2 * e2) \
                    - (travel_m[m] - bounds_inout.travel_at_m[mi, f]) > floor:
                continue
            point_out[0], point_out[1], point_out[2] = l0, l1, l2
            d, _ = signed_distance(m, meshes_in, point_out, reach, stack_out)
            if d <= floor:
                count += _mark_holding(mixed_slaved[i], crossing_cells, refined, new_inout)
                bounds_inout.value_m[mi, f] = -np.inf
            else:
                bounds_inout.value_m[mi, f] = d * (1.0 - 1e-12)
                bounds_inout.reference_m[mi, f, 0] = l0
                bounds_inout.reference_m[mi, f, 1] = l1
                bounds_inout.reference_m[mi, f, 2] = l2
                bounds_inout.travel_at_m[mi, f] = travel_m[m]
    return count
