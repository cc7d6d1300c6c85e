"""Cloth masses against rigid spheres, boxes and planes, with friction (docs/method.md §4.3); mesh
bodies have their own kernels (fraytool.sim.kernels.mesh_contact) and are never in contact here.

Bodies come as one argument group, `bodies_in` (fraytool.sim.kernels.bodies.BodiesIn): a kind and a
parameter vector per body; `surface_contact` and `bounding_radius` hold the one branch per kind.

A particle closer than `margin` (half the cloth thickness) to a body's surface is projected out
along the surface normal n by the penetration depth d. Friction acts on the tangential
displacement relative to the body over the step, Δt (position-based Coulomb friction, Macklin
et al. 2014 "Unified Particle Physics" §6.1): static when |Δt| < μ d (Δt removed), else kinetic
(Δt reduced by μ d). The body's surface point moves over the step by dt (v + ω × r), r from the body's
centre at the step's end to the contact (a turning kinematic body, fraytool.sim.paths; ω = 0 otherwise). Only masses are tested; a spring may dip into a body between its masses,
which the paper found acceptable. For dynamic bodies the impulse m Δx / dt given to each particle
is summed per body so the caller can apply the equal and opposite impulse (two-way coupling).
"""
from __future__ import annotations

import math

import numba as nb
import numpy as np

from fraytool.kinds import SHAPE_MESH, SHAPE_PLANE, SHAPE_SPHERE


@nb.njit(cache=True, fastmath=False, inline="always")
def surface_contact(shape, center, rotation, params, x, margin):
    """Signed distance (negative inside, margin included) and outward unit normal at point x, for a body
    of kind `shape` with parameter vector `params` (fraytool.sim.kernels.bodies)."""
    if shape == SHAPE_SPHERE:
        radius = params[0]
        dx = x[0] - center[0]
        dy = x[1] - center[1]
        dz = x[2] - center[2]
        r = math.sqrt(dx * dx + dy * dy + dz * dz)
        if r < 1e-15:
            return -(radius + margin), 0.0, 1.0, 0.0
        return r - radius - margin, dx / r, dy / r, dz / r
    if shape == SHAPE_MESH:
        return math.inf, 0.0, 1.0, 0.0  # meshes have their own pass (fraytool.sim.kernels.mesh_contact)
    if shape == SHAPE_PLANE:
        normal = params
        nx = rotation[0, 0] * normal[0] + rotation[0, 1] * normal[1] + rotation[0, 2] * normal[2]
        ny = rotation[1, 0] * normal[0] + rotation[1, 1] * normal[1] + rotation[1, 2] * normal[2]
        nz = rotation[2, 0] * normal[0] + rotation[2, 1] * normal[1] + rotation[2, 2] * normal[2]
        return plane_distance(rotation, normal, x[0] - center[0], x[1] - center[1], x[2] - center[2], margin), \
            nx, ny, nz
    # box: work in the body frame, local = R^T (x - c); scalars only (no allocation per call)
    half_extents = params
    l0 = rotation[0, 0] * (x[0] - center[0]) + rotation[1, 0] * (x[1] - center[1]) + rotation[2, 0] * (x[2] - center[2])
    l1 = rotation[0, 1] * (x[0] - center[0]) + rotation[1, 1] * (x[1] - center[1]) + rotation[2, 1] * (x[2] - center[2])
    l2 = rotation[0, 2] * (x[0] - center[0]) + rotation[1, 2] * (x[1] - center[1]) + rotation[2, 2] * (x[2] - center[2])
    outside = 0.0
    best_axis = 0
    best_gap = -1e300
    for d in range(3):
        ld = l0 if d == 0 else (l1 if d == 1 else l2)
        gap = abs(ld) - half_extents[d]
        if gap > 0.0:
            outside += gap * gap
        if gap > best_gap:
            best_gap = gap
            best_axis = d
    if outside > 0.0:
        # outside the box: normal from the closest point q of the box
        dist = math.sqrt(outside)
        n0 = (l0 - min(max(l0, -half_extents[0]), half_extents[0])) / dist
        n1 = (l1 - min(max(l1, -half_extents[1]), half_extents[1])) / dist
        n2 = (l2 - min(max(l2, -half_extents[2]), half_extents[2])) / dist
        return dist - margin, (rotation[0, 0] * n0 + rotation[0, 1] * n1 + rotation[0, 2] * n2), \
            (rotation[1, 0] * n0 + rotation[1, 1] * n1 + rotation[1, 2] * n2), \
            (rotation[2, 0] * n0 + rotation[2, 1] * n1 + rotation[2, 2] * n2)
    best_local = l0 if best_axis == 0 else (l1 if best_axis == 1 else l2)
    sign = 1.0 if best_local >= 0.0 else -1.0
    return best_gap - margin, sign * rotation[0, best_axis], sign * rotation[1, best_axis], sign * rotation[2, best_axis]


@nb.njit(cache=True, fastmath=False, inline="always")
def coulomb_friction(px, py, pz, rx, ry, rz, nx, ny, nz, limit):
    """Point p after position-based Coulomb friction (Macklin et al. 2014 §6.1): r is its displacement
    relative to the surface over the step, n the contact's unit normal, limit = mu x penetration depth.
    The tangential part t of r is removed when |t| <= limit (static), else shortened by limit (kinetic)."""
    rn = rx * nx + ry * ny + rz * nz
    tx = rx - rn * nx
    ty = ry - rn * ny
    tz = rz - rn * nz
    tl = math.sqrt(tx * tx + ty * ty + tz * tz)
    if tl > 0.0:
        scale = 1.0 if tl <= limit else limit / tl
        px -= scale * tx
        py -= scale * ty
        pz -= scale * tz
    return px, py, pz


@nb.njit(cache=True, fastmath=False, inline="always")
def plane_distance(rotation, normal, ex, ey, ez, margin):
    """Signed distance of the point centre + (ex, ey, ez) from a plane body (normal R n), margin included."""
    nx = rotation[0, 0] * normal[0] + rotation[0, 1] * normal[1] + rotation[0, 2] * normal[2]
    ny = rotation[1, 0] * normal[0] + rotation[1, 1] * normal[1] + rotation[1, 2] * normal[2]
    nz = rotation[2, 0] * normal[0] + rotation[2, 1] * normal[1] + rotation[2, 2] * normal[2]
    return ex * nx + ey * ny + ez * nz - margin


@nb.njit(cache=True, fastmath=False)
def bounding_radius(shape, params, margin):
    """Radius about the body centre beyond which no point is in contact (margin included, with a
    relative slack of 1e-9 so the skip never disagrees with `surface_contact` by a rounding);
    infinite for a plane."""
    if shape == SHAPE_SPHERE:
        return (params[0] + margin) * (1.0 + 1e-9)
    if shape == SHAPE_PLANE:
        return math.inf
    if shape == SHAPE_MESH:
        return (params[0] + margin) * (1.0 + 1e-9)  # params[0]: the farthest vertex over all keys
    he = math.sqrt(params[0] ** 2 + params[1] ** 2 + params[2] ** 2)
    return (he + margin) * (1.0 + 1e-9)


@nb.njit(cache=True, fastmath=False)
def surface_distances(k, bodies_in, x, distance_out):
    """distance_out[i] = signed distance [m] of point x[i] from body k's surface (negative inside; no
    margin), by `surface_contact`."""
    for i in range(x.shape[0]):
        d, _, _, _ = surface_contact(bodies_in.shape[k], bodies_in.position_m[k], bodies_in.rotation[k],
                                     bodies_in.params[k], x[i], 0.0)
        distance_out[i] = d


@nb.njit(cache=True, fastmath=False)
def project_out_of_body(k, bodies_in, margin_m, x_inout):
    """Move point x (in place) out of body k along the surface normal when it is inside (margin
    included). Returns (signed distance before, normal): d >= 0 means x was outside and is unchanged."""
    d, nx, ny, nz = surface_contact(bodies_in.shape[k], bodies_in.position_m[k], bodies_in.rotation[k],
                                    bodies_in.params[k], x_inout, margin_m)
    if d < 0.0:
        x_inout[0] -= d * nx
        x_inout[1] -= d * ny
        x_inout[2] -= d * nz
    return d, nx, ny, nz


@nb.njit(cache=True, fastmath=False, inline="always")
def _contact_range(particles, lo, hi, k, frame, dynamic, dt_s, bodies_in, margin_m, particles_in,
                   particle_position_m_inout, body_impulse_out):
    """Particles particles[lo:hi] against body k: each one in contact is moved out with friction, and for a
    dynamic body its impulse m dx / dt is added to body_impulse_out[k] in index order. `frame` holds the
    body's constants of the call (collide_rigid): (plane, sphere, world normal x, y, z of a plane, centre
    x, y, z, squared reach, the body's move over the step x, y, z, friction, its turn over the step
    dt omega x, y, z); `particles_in` the particles' (inverse mass, mass, start-of-step position). Returns
    the number of contacts."""
    plane, sphere, pnx, pny, pnz, cx, cy, cz, reach2, step_x, step_y, step_z, friction, turn_x, turn_y, turn_z = frame
    particle_inv_mass, particle_mass_kg, prev_position_m = particles_in
    hits = 0
    for i in range(lo, hi):
        p = particles[i]
        if particle_inv_mass[p] == 0.0:
            continue  # inactive or held: held particles follow their body, not contacts
        ex = particle_position_m_inout[p, 0] - cx
        ey = particle_position_m_inout[p, 1] - cy
        ez = particle_position_m_inout[p, 2] - cz
        if plane:
            if ex * pnx + ey * pny + ez * pnz - margin_m >= 0.0:
                continue  # above the plane: the signed distance `surface_contact` computes
        elif ex * ex + ey * ey + ez * ez > reach2:
            continue  # beyond the body's bounding sphere: no contact (the test below would say so)
        x0 = particle_position_m_inout[p, 0]
        x1 = particle_position_m_inout[p, 1]
        x2 = particle_position_m_inout[p, 2]
        if plane:  # `surface_contact` for a plane, inlined: the same expressions
            d = ex * pnx + ey * pny + ez * pnz - margin_m
            nx, ny, nz = pnx, pny, pnz
        elif sphere:  # likewise for a sphere
            r = math.sqrt(ex * ex + ey * ey + ez * ez)
            if r < 1e-15:
                d, nx, ny, nz = -(bodies_in.params[k, 0] + margin_m), 0.0, 1.0, 0.0
            else:
                d, nx, ny, nz = r - bodies_in.params[k, 0] - margin_m, ex / r, ey / r, ez / r
        else:
            d, nx, ny, nz = surface_contact(bodies_in.shape[k], bodies_in.position_m[k], bodies_in.rotation[k],
                                            bodies_in.params[k], particle_position_m_inout[p], margin_m)
        if d >= 0.0:
            continue
        # out along the normal (`project_out_of_body`), in registers until written back
        px = x0 - d * nx
        py = x1 - d * ny
        pz = x2 - d * nz
        hits += 1
        # friction on the displacement relative to the body's surface point over the step: its move
        # dt v, then its turn dt omega x r (exactly zero for a body that does not turn)
        rx = px - prev_position_m[p, 0] - step_x - (turn_y * (pz - cz) - turn_z * (py - cy))
        ry = py - prev_position_m[p, 1] - step_y - (turn_z * (px - cx) - turn_x * (pz - cz))
        rz = pz - prev_position_m[p, 2] - step_z - (turn_x * (py - cy) - turn_y * (px - cx))
        px, py, pz = coulomb_friction(px, py, pz, rx, ry, rz, nx, ny, nz, friction * (-d))
        particle_position_m_inout[p, 0] = px
        particle_position_m_inout[p, 1] = py
        particle_position_m_inout[p, 2] = pz
        if dynamic:
            m = particle_mass_kg[p] / dt_s
            body_impulse_out[k, 0] += m * (px - x0)
            body_impulse_out[k, 1] += m * (py - x1)
            body_impulse_out[k, 2] += m * (pz - x2)
    return hits


@nb.njit(cache=True, fastmath=False, parallel=True)
def collide_rigid(
    # the particles in contact with bodies (the free ones, ascending) and their units
    # (fraytool.sim.kernels.work_split)
    particles, unit_bounds,
    # model and state: the bodies (fraytool.sim.kernels.bodies.BodiesIn)
    bodies_in, margin_m, dt_s,
    # state in
    particle_inv_mass, particle_mass_kg, prev_position_m,
    # state in/out
    particle_position_m_inout,
    # out
    body_impulse_out,
):
    """Push particles out of bodies with friction; returns the number of contacts.

    Body by body (each particle still meets the bodies in index order: the same arithmetic as
    particle by particle), so the body's constants are computed once per call. Against a body that
    does not move with the cloth (scripted or static) the particles are independent and run in
    parallel over the units (numba prange; the contact count is an integer sum); against a dynamic
    body they run in index order on one thread, so that the body's impulse m dx / dt sums in the same
    order on any number of threads."""
    contacts = 0
    body_impulse_out[:] = 0.0
    particles_in = (particle_inv_mass, particle_mass_kg, prev_position_m)
    hits = np.zeros(unit_bounds.shape[0] - 1, np.int64)  # contacts per unit, against one body
    for k in range(bodies_in.shape.shape[0]):
        if not bodies_in.collide[k]:
            continue
        shape = bodies_in.shape[k]
        reach = bounding_radius(shape, bodies_in.params[k], margin_m)
        rotation = bodies_in.rotation[k]
        normal = bodies_in.params[k]  # (read as a plane's normal only where the body is a plane)
        pnx = rotation[0, 0] * normal[0] + rotation[0, 1] * normal[1] + rotation[0, 2] * normal[2]
        pny = rotation[1, 0] * normal[0] + rotation[1, 1] * normal[1] + rotation[1, 2] * normal[2]
        pnz = rotation[2, 0] * normal[0] + rotation[2, 1] * normal[1] + rotation[2, 2] * normal[2]
        position, velocity, omega = bodies_in.position_m, bodies_in.velocity_m_s, bodies_in.angular_velocity_rad_s
        frame = (shape == SHAPE_PLANE, shape == SHAPE_SPHERE, pnx, pny, pnz, position[k, 0], position[k, 1],
                 position[k, 2], reach * reach,
                 dt_s * velocity[k, 0], dt_s * velocity[k, 1], dt_s * velocity[k, 2],  # the body's move over the step
                 bodies_in.friction[k],
                 dt_s * omega[k, 0], dt_s * omega[k, 1], dt_s * omega[k, 2])  # and its turn
        if bodies_in.dynamic[k]:
            contacts += _contact_range(particles, 0, particles.shape[0], k, frame, True, dt_s, bodies_in, margin_m,
                                       particles_in, particle_position_m_inout, body_impulse_out)
        else:  # (inlined into the loop: a call per unit costs more than its work; counts per unit, as a
            # reduction over the inlined code does not compile)
            hits[:] = 0
            for u in nb.prange(unit_bounds.shape[0] - 1):
                hits[u] = _contact_range(particles, unit_bounds[u], unit_bounds[u + 1], k, frame, False, dt_s,
                                         bodies_in, margin_m, particles_in, particle_position_m_inout, body_impulse_out)
            contacts += hits.sum()
    return contacts


@nb.njit(cache=True, fastmath=False)
def place_outside_bodies(
    # model and state: the bodies (fraytool.sim.kernels.bodies.BodiesIn)
    bodies_in, margin_m,
    # state in
    particles, particle_inv_mass,
    # state in/out
    particle_position_m_inout,
):
    """Move each free particle of `particles` that lies inside a colliding body out along the surface
    normal, without friction and without a reaction on the body: a placement, not a collision (the
    caller keeps velocities by moving the previous positions with it). Used for masses a split puts
    inside a body (docs/tearing.md, "Transition")."""
    for i in range(particles.shape[0]):
        p = particles[i]
        if particle_inv_mass[p] == 0.0:
            continue
        for k in range(bodies_in.shape.shape[0]):
            if not bodies_in.collide[k]:
                continue
            project_out_of_body(k, bodies_in, margin_m, particle_position_m_inout[p])
