"""Kernels of the multi-resolution base model (fraytool.sim.multires, docs/multires.md).

All serial, so every sum is in a fixed order and the frames are deterministic.
"""
from __future__ import annotations

import math

import numba as nb

from fraytool.sim.kernels.forces import add_spring_force
from fraytool.kinds import SHAPE_BOX, SHAPE_PLANE
from fraytool.sim.kernels.rigid_contact import coulomb_friction, plane_distance, surface_contact


@nb.njit(cache=True, fastmath=False)
def add_listed_spring_forces(
    listed, share,
    spring_kind, spring_rest_length_m, particle_position_m, spring_particle_a, spring_particle_b,
    spring_alive, spring_stiffness_n_per_m,
    particle_force_n_inout,
):
    """Add the forces of the springs `listed` (live ones), each scaled by its `share` of the cells it
    borders, to particle_force_n (not zeroed): the Hooke springs of fraytool.sim.kernels.forces,
    shear springs in compression only."""
    for m in range(listed.shape[0]):
        s = listed[m]
        if spring_alive[s]:
            add_spring_force(s, share[m] * spring_stiffness_n_per_m[s], spring_kind, spring_rest_length_m,
                             particle_position_m, spring_particle_a, spring_particle_b, particle_force_n_inout)


@nb.njit(cache=True, fastmath=False)
def zero_rows(rows, values_inout):
    """values[rows] = 0 (a row per particle)."""
    for m in range(rows.shape[0]):
        for d in range(values_inout.shape[1]):
            values_inout[rows[m], d] = 0.0


@nb.njit(cache=True, fastmath=False)
def gather_slaved_forces(slaved, crossing_node, crossing_weight, particle_force_n_inout):
    """Move the force on each slaved crossing to its nodes with its interpolation weights (the
    transpose of the interpolation: total force and torque about any point are kept to first order)."""
    for m in range(slaved.shape[0]):
        s = slaved[m]
        fx = particle_force_n_inout[s, 0]
        fy = particle_force_n_inout[s, 1]
        fz = particle_force_n_inout[s, 2]
        if fx == 0.0 and fy == 0.0 and fz == 0.0:
            continue
        for q in range(4):
            w = crossing_weight[s, q]
            if w != 0.0:
                node = crossing_node[s, q]
                particle_force_n_inout[node, 0] += w * fx
                particle_force_n_inout[node, 1] += w * fy
                particle_force_n_inout[node, 2] += w * fz
        particle_force_n_inout[s, 0] = 0.0
        particle_force_n_inout[s, 1] = 0.0
        particle_force_n_inout[s, 2] = 0.0


@nb.njit(cache=True, fastmath=False)
def sync_slaved(slaved, crossing_node, crossing_weight, particle_position_m_inout):
    """Position of each slaved crossing = the weighted sum of its nodes' (in place; also used for the
    start-of-step positions). The step neither integrates slaved crossings nor makes their velocities:
    the stages sync them where they are read, and the frame's end gives them the velocity of their
    synced positions (fraytool.sim.stages.multires)."""
    for m in range(slaved.shape[0]):
        _sync_one(slaved[m], crossing_node, crossing_weight, particle_position_m_inout)


@nb.njit(cache=True, fastmath=False, parallel=True)
def sync_slaved_parallel(slaved, crossing_node, crossing_weight, particle_position_m_inout):
    """`sync_slaved` in parallel over the slaved crossings, the same bits on any number of threads (each row is
    one crossing's, from its nodes' rows: a node is never slaved). For the large lists (a garment's every
    slaved crossing before self-collision): on a small one, waking the threads costs more than the loop."""
    for m in nb.prange(slaved.shape[0]):
        _sync_one(slaved[m], crossing_node, crossing_weight, particle_position_m_inout)


@nb.njit(cache=True, fastmath=False, inline="always")
def _sync_one(s, crossing_node, crossing_weight, values_inout):
    """values[s] = the weighted sum of its nodes' values (the interpolation of slaved crossing s)."""
    for d in range(3):
        x = 0.0
        for q in range(4):
            x += crossing_weight[s, q] * values_inout[crossing_node[s, q], d]
        values_inout[s, d] = x


@nb.njit(cache=True, fastmath=False)
def _mark_hot(listed, cells, rest_length_m, particle_position_m, spring_particle_a, spring_particle_b, spring_alive,
              refine_strain, hot_out):
    for m in range(listed.shape[0]):
        s = listed[m]
        if not spring_alive[s]:
            continue
        a = spring_particle_a[s]
        b = spring_particle_b[s]
        dx = particle_position_m[b, 0] - particle_position_m[a, 0]
        dy = particle_position_m[b, 1] - particle_position_m[a, 1]
        dz = particle_position_m[b, 2] - particle_position_m[a, 2]
        limit = rest_length_m[s] * (1.0 + refine_strain)
        if dx * dx + dy * dy + dz * dz > limit * limit:
            for q in range(cells.shape[1]):
                if cells[s, q] >= 0:
                    hot_out[cells[s, q]] = True


@nb.njit(cache=True, fastmath=False)
def cells_to_refine(
    # the fine and the coarse structural springs at work, each as (listed springs, their cells, rest
    # lengths, end a, end b, alive flags)
    fine_in, coarse_in,
    particle_position_m, refine_strain, band, cells_x, cells_y,
    # moving bodies: (centre, reach (bounding radius + band)) of each; nodes of each cell
    moving_bodies_in, cell_nodes,
    # in: refined cells; scratch: hot; out: new (cells to refine now)
    refined, hot_inout, new_inout,
):
    """Mark in `new` the coarse cells to refine now: those within `band` cells of a cell holding a
    structural spring strained past refine_strain (fine or coarse), and those with a node within a
    moving body's reach. Returns how many."""
    fine_listed, fine_cells, fine_rest_length_m, fine_a, fine_b, fine_alive = fine_in
    coarse_listed, coarse_cells, coarse_rest_length_m, coarse_a, coarse_b, coarse_alive = coarse_in
    body_centre_m, body_reach_m = moving_bodies_in
    for c in range(hot_inout.shape[0]):
        hot_inout[c] = False
        new_inout[c] = False
    _mark_hot(fine_listed, fine_cells, fine_rest_length_m, particle_position_m, fine_a, fine_b, fine_alive,
              refine_strain, hot_inout)
    _mark_hot(coarse_listed, coarse_cells, coarse_rest_length_m, particle_position_m, coarse_a, coarse_b,
              coarse_alive, refine_strain, hot_inout)
    mark_band(hot_inout, band, cells_x, cells_y, new_inout)
    count = 0
    for c in range(new_inout.shape[0]):
        if new_inout[c] and refined[c]:
            new_inout[c] = False
        elif new_inout[c]:
            count += 1
    for k in range(body_centre_m.shape[0]):
        r2 = body_reach_m[k] * body_reach_m[k]
        for c in range(refined.shape[0]):
            if refined[c] or new_inout[c]:
                continue
            for q in range(4):
                p = cell_nodes[c, q]
                dx = particle_position_m[p, 0] - body_centre_m[k, 0]
                dy = particle_position_m[p, 1] - body_centre_m[k, 1]
                dz = particle_position_m[p, 2] - body_centre_m[k, 2]
                if dx * dx + dy * dy + dz * dz <= r2:
                    new_inout[c] = True
                    count += 1
                    break
    return count


@nb.njit(cache=True, fastmath=False)
def collide_slaved(
    # the slaved crossings by cell: (cell_start, cell_slaved, cell_nodes, nodes, crossing_node, crossing_weight)
    cells_in,
    # model and state: the bodies (fraytool.sim.kernels.bodies.BodiesIn)
    bodies_in, margin_m, dt_s,
    # state in
    particle_inv_mass, prev_position_m,
    # state in/out; scratch
    particle_position_m_inout, point_inout, outside_inout,
):
    """Keep the slaved crossings out of the bodies by moving their nodes: where a slaved crossing's
    interpolated point x = sum w_q x_q lies inside a body by d along normal n, the nodes move by
    dx_q = w_q inv_q / sum(w^2 inv) (-d n), the smallest mass-weighted move that puts x on the
    surface (the projection of an embedded point), with the Coulomb friction of collide_rigid on the
    point's move relative to the body over the step. One Gauss-Seidel pass, cell by cell and crossings
    in index order inside a cell. The slaved crossings come grouped by the cell they interpolate
    (cell_slaved[cell_start[c]:cell_start[c + 1]]); a cell that cannot touch the body is skipped:
    - for a plane or a box, when all four of its nodes are outside one face plane (`_outside_faces`:
      its points are convex combinations of the nodes). The face bits of every node (`nodes`, the
      cells' corners) are set in `outside` (scratch, a byte per crossing) at the start of the body's
      pass, and again for the nodes of each crossing that moves them; a cell's test is the AND of its
      four nodes' bytes (asking each node per cell cost 0.6 ms of a 256 x 256 tablecloth step);
    - for any shape, when its nodes are farther from the body than the cell is wide (`_cell_far`).
    `point` is a scratch array of 3. Returns the number of contacts."""
    cell_start, cell_slaved, cell_nodes, nodes, crossing_node, crossing_weight = cells_in
    contacts = 0
    for k in range(bodies_in.shape.shape[0]):
        if not bodies_in.collide[k]:
            continue
        flat = bodies_in.shape[k] == SHAPE_PLANE or bodies_in.shape[k] == SHAPE_BOX
        if flat:
            for i in range(nodes.shape[0]):
                outside_inout[nodes[i]] = _outside_faces(k, nodes[i], bodies_in, margin_m, particle_position_m_inout)
        for c in range(cell_start.shape[0] - 1):
            if cell_start[c] == cell_start[c + 1]:
                continue
            if flat and (outside_inout[cell_nodes[c, 0]] & outside_inout[cell_nodes[c, 1]] & outside_inout[cell_nodes[c, 2]]
                         & outside_inout[cell_nodes[c, 3]]) != 0:
                continue
            if _cell_far(k, c, cell_nodes, bodies_in, margin_m, particle_position_m_inout):
                continue
            for m in range(cell_start[c], cell_start[c + 1]):
                s = cell_slaved[m]
                hit = _collide_slaved_one(s, k, crossing_node, crossing_weight, bodies_in, margin_m, dt_s,
                                          particle_inv_mass, prev_position_m, particle_position_m_inout, point_inout)
                contacts += hit
                if hit and flat:
                    for q in range(4):  # its nodes moved: their bits again
                        node = crossing_node[s, q]
                        outside_inout[node] = _outside_faces(k, node, bodies_in, margin_m,
                                                             particle_position_m_inout)
    return contacts


CLEAR_TOLERANCE_M = 1e-9
"""A node on a face plane to within this [m] counts as outside it: rigid contact leaves resting nodes
on the surface up to rounding, and a point of their cell is then inside by at most this much."""


@nb.njit(cache=True, fastmath=False, inline="always")
def _outside_faces(k, p, bodies_in, margin_m, particle_position_m):
    """Bits of the face planes of body k that particle p is outside of, margin included, to
    CLEAR_TOLERANCE_M: for a box, bit 2 axis for the face at -half_extents[axis] along the body's axis,
    bit 2 axis + 1 for the one at +half_extents[axis]; for a plane, bit 1. A cell's points are convex
    combinations of its four nodes (bilinear weights), so they lie in the nodes' convex hull: all four
    nodes outside the same (face) plane put every point of the cell outside the body. (A face's height
    along -n is minus the one along n, exactly: negation is exact, and rounds a sum symmetrically.)"""
    body_position_m, body_rotation = bodies_in.position_m, bodies_in.rotation
    ex = particle_position_m[p, 0] - body_position_m[k, 0]
    ey = particle_position_m[p, 1] - body_position_m[k, 1]
    ez = particle_position_m[p, 2] - body_position_m[k, 2]
    if bodies_in.shape[k] == SHAPE_PLANE:
        if plane_distance(body_rotation[k], bodies_in.params[k], ex, ey, ez, 0.0) >= margin_m - CLEAR_TOLERANCE_M:
            return 2
        return 0
    bits = 0
    for axis in range(3):
        h = ex * body_rotation[k, 0, axis] + ey * body_rotation[k, 1, axis] + ez * body_rotation[k, 2, axis]
        level = bodies_in.params[k, axis] + margin_m - CLEAR_TOLERANCE_M
        if -h >= level:
            bits |= 1 << (2 * axis)
        if h >= level:
            bits |= 1 << (2 * axis + 1)
    return bits


@nb.njit(cache=True, fastmath=False)
def _cell_far(k, c, cell_nodes, bodies_in, margin_m, particle_position_m):
    """True when all four nodes of cell c are farther from body k than the cell's widest node-to-node
    distance: then no point of the cell is inside (margin included; the distance to a body changes by
    at most the distance moved). For any shape; planes and boxes try their faces first (collide_slaved)."""
    shape = bodies_in.shape[k]
    near = 1e300
    widest = 0.0
    for q in range(4):
        p = cell_nodes[c, q]
        dq, _, _, _ = surface_contact(shape, bodies_in.position_m[k], bodies_in.rotation[k], bodies_in.params[k],
                                      particle_position_m[p], margin_m)
        near = min(near, dq)
        for r in range(q + 1, 4):
            o = cell_nodes[c, r]
            ex = particle_position_m[p, 0] - particle_position_m[o, 0]
            ey = particle_position_m[p, 1] - particle_position_m[o, 1]
            ez = particle_position_m[p, 2] - particle_position_m[o, 2]
            widest = max(widest, ex * ex + ey * ey + ez * ez)
    return near > math.sqrt(widest)


@nb.njit(cache=True, fastmath=False, inline="always")
def _collide_slaved_one(s, k, crossing_node, crossing_weight, bodies_in, margin_m, dt_s, particle_inv_mass,
                        prev_position_m, particle_position_m_inout, point_inout):
    """collide_slaved for slaved crossing s and body k; returns 1 on a contact, else 0."""
    for d in range(3):
        x = 0.0
        for q in range(4):
            x += crossing_weight[s, q] * particle_position_m_inout[crossing_node[s, q], d]
        point_inout[d] = x
    body_velocity_m_s = bodies_in.velocity_m_s
    dist, nx, ny, nz = surface_contact(bodies_in.shape[k], bodies_in.position_m[k], bodies_in.rotation[k],
                                       bodies_in.params[k], point_inout, margin_m)
    if dist >= 0.0:
        return 0
    norm = 0.0
    for q in range(4):
        w = crossing_weight[s, q]
        norm += w * w * particle_inv_mass[crossing_node[s, q]]
    if norm <= 0.0:
        return 0  # every node held by a body
    # the point's correction: out along the normal, then friction on its move relative to the body's
    # surface point over the step, dt (v + omega x r), r from the body's centre (rigid_contact)
    cx = -dist * nx
    cy = -dist * ny
    cz = -dist * nz
    wx, wy, wz = (dt_s * bodies_in.angular_velocity_rad_s[k, 0], dt_s * bodies_in.angular_velocity_rad_s[k, 1],
                  dt_s * bodies_in.angular_velocity_rad_s[k, 2])
    ex = point_inout[0] + cx - bodies_in.position_m[k, 0]
    ey = point_inout[1] + cy - bodies_in.position_m[k, 1]
    ez = point_inout[2] + cz - bodies_in.position_m[k, 2]
    rx = point_inout[0] + cx - dt_s * body_velocity_m_s[k, 0] - (wy * ez - wz * ey)
    ry = point_inout[1] + cy - dt_s * body_velocity_m_s[k, 1] - (wz * ex - wx * ez)
    rz = point_inout[2] + cz - dt_s * body_velocity_m_s[k, 2] - (wx * ey - wy * ex)
    for q in range(4):
        w = crossing_weight[s, q]
        node = crossing_node[s, q]
        rx -= w * prev_position_m[node, 0]
        ry -= w * prev_position_m[node, 1]
        rz -= w * prev_position_m[node, 2]
    cx, cy, cz = coulomb_friction(cx, cy, cz, rx, ry, rz, nx, ny, nz, bodies_in.friction[k] * (-dist))
    for q in range(4):
        node = crossing_node[s, q]
        g = crossing_weight[s, q] * particle_inv_mass[node] / norm
        particle_position_m_inout[node, 0] += g * cx
        particle_position_m_inout[node, 1] += g * cy
        particle_position_m_inout[node, 2] += g * cz
    return 1


@nb.njit(cache=True, fastmath=False)
def cell_shares(cells, weight, weighted, refined, at_fine, out_out):
    """out[r] = the share of row r's cells (-1 padded) that are at the resolution asked: refined
    (at_fine) or coarse; each cell counts 1, or weight[r, q] when `weighted`. fraytool.sim.multires.share."""
    for r in range(cells.shape[0]):
        valid = 0.0
        mine = 0.0
        for q in range(cells.shape[1]):
            c = cells[r, q]
            if c < 0:
                continue
            w = weight[r, q] if weighted else 1.0
            valid += w
            if refined[c] == at_fine:
                mine += w
        out_out[r] = mine / valid if valid > 0.0 else 0.0


@nb.njit(cache=True, fastmath=False)
def free_mask(crossing_cells, crossing_is_node, refined, out_out):
    """out[c] = crossing c is a node or every cell holding it is refined. fraytool.sim.multires.free_crossings."""
    for c in range(crossing_cells.shape[0]):
        free = True
        if not crossing_is_node[c]:
            for q in range(crossing_cells.shape[1]):
                cell = crossing_cells[c, q]
                if cell >= 0 and not refined[cell]:
                    free = False
                    break
        out_out[c] = free


@nb.njit(cache=True, fastmath=False)
def lump_masses(crossing_mass_kg, free, crossing_node, crossing_weight, out_inout):
    """out = each crossing's own mass where free (0 where slaved), plus the weighted masses of the
    slaved crossings that interpolate it (crossings in index order). fraytool.sim.multires.lumped_masses."""
    for c in range(crossing_mass_kg.shape[0]):
        out_inout[c] = crossing_mass_kg[c] if free[c] else 0.0
    for c in range(crossing_mass_kg.shape[0]):
        if free[c]:
            continue
        for q in range(4):
            out_inout[crossing_node[c, q]] += crossing_weight[c, q] * crossing_mass_kg[c]


@nb.njit(cache=True, fastmath=False)
def mark_band(hot, band, cells_x, cells_y, near_inout):
    """near[t] = True for every cell t within `band` cells (square band) of a hot cell; others False."""
    for c in range(near_inout.shape[0]):
        near_inout[c] = False
    for c in range(hot.shape[0]):
        if not hot[c]:
            continue
        ci = c % cells_x
        cj = c // cells_x
        for j in range(max(0, cj - band), min(cells_y, cj + band + 1)):
            for i in range(max(0, ci - band), min(cells_x, ci + band + 1)):
                near_inout[j * cells_x + i] = True


@nb.njit(cache=True, fastmath=False)
def sync_near_hot(hot, reach, cells_x, cells_y, cell_start, cell_slaved, crossing_node, crossing_weight,
                  near_inout, particle_position_m_inout, prev_position_m_inout):
    """`sync_slaved` (positions and start-of-step positions, the same sums) for the slaved crossings of
    the cells within `reach` cells (square band) of a hot cell: the ones a split in a hot cell may read
    (its neighbours, the yarn segments near its settle). `cell_slaved[cell_start[c]:cell_start[c + 1]]`:
    the slaved crossings interpolating cell c; `near`: scratch, one per cell."""
    mark_band(hot, reach, cells_x, cells_y, near_inout)
    for t in range(near_inout.shape[0]):
        if not near_inout[t]:
            continue
        for m in range(cell_start[t], cell_start[t + 1]):
            _sync_one(cell_slaved[m], crossing_node, crossing_weight, particle_position_m_inout)
            _sync_one(cell_slaved[m], crossing_node, crossing_weight, prev_position_m_inout)
