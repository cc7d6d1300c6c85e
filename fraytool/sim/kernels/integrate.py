"""Explicit Euler updates of velocities and positions, and the PBD velocity post-process (§4).

Every update is per particle, so the kernels run in parallel over units of a list of particles
(fraytool.sim.kernels.work_split: `particles`, ascending slots, cut by `unit_bounds`; `all_slots`
for every slot), with the same result, bit for bit, on any number of threads; the post-process's
guard takes the lowest bad index over the units (a minimum: exact in any order)."""
from __future__ import annotations

import math

import numba as nb
import numpy as np


@nb.njit(cache=True, fastmath=False, parallel=True)
def integrate_velocities(particles, unit_bounds, particle_velocity_m_s_inout, particle_force_n, particle_inv_mass, gravity_m_s2, dt_s):
    """v += dt (g + f / m) for free particles (inverse mass > 0)."""
    for u in nb.prange(unit_bounds.shape[0] - 1):
        for i in range(unit_bounds[u], unit_bounds[u + 1]):
            p = particles[i]
            w = particle_inv_mass[p]
            if w == 0.0:
                continue  # inactive slot or held by a rigid body
            for d in range(3):
                particle_velocity_m_s_inout[p, d] += dt_s * (gravity_m_s2[d] + particle_force_n[p, d] * w)


@nb.njit(cache=True, fastmath=False, parallel=True)
def integrate_positions(particles, unit_bounds, particle_position_m_inout, particle_velocity_m_s, particle_active,
                        prev_position_m_out, dt_s):
    """For the particles listed: save the start-of-step position, then x += dt v if active. (The
    solver lists the moving particles: other slots' start-of-step positions are not read, or are set
    by whoever reads them: a split for the slot it activates, the multi-resolution stages for the
    slaved crossings.)"""
    for u in nb.prange(unit_bounds.shape[0] - 1):
        for i in range(unit_bounds[u], unit_bounds[u + 1]):
            p = particles[i]
            for d in range(3):
                prev_position_m_out[p, d] = particle_position_m_inout[p, d]
            if not particle_active[p]:
                continue
            for d in range(3):
                particle_position_m_inout[p, d] += dt_s * particle_velocity_m_s[p, d]


@nb.njit(cache=True, fastmath=False, parallel=True)
def velocities_from_positions(particles, unit_bounds, particle_position_m, prev_position_m, particle_active, particle_velocity_m_s_out,
                              dt_s, speed_limit_m_s):
    """PBD post-process v = (x - x_prev) / dt; returns the first particle that is non-finite or faster
    than speed_limit_m_s (the stability guard), or -1 when all are sane."""
    inv_dt = 1.0 / dt_s
    units = unit_bounds.shape[0] - 1
    first_bad = np.full(units, -1, np.int64)
    for u in nb.prange(units):
        for i in range(unit_bounds[u], unit_bounds[u + 1]):
            p = particles[i]
            if not particle_active[p]:
                continue
            s2 = 0.0
            for d in range(3):
                v = (particle_position_m[p, d] - prev_position_m[p, d]) * inv_dt
                particle_velocity_m_s_out[p, d] = v
                s2 += v * v
            if first_bad[u] < 0 and not (math.sqrt(s2) <= speed_limit_m_s):  # NaN fails the comparison too
                first_bad[u] = p
    for u in range(units):
        if first_bad[u] >= 0:
            return first_bad[u]
    return -1
