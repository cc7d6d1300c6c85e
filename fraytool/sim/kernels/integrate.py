"""Explicit Euler updates of velocities and positions, and the PBD velocity post-process (§4)."""
from __future__ import annotations

import math

import numba as nb


@nb.njit(cache=True, fastmath=False)
def integrate_velocities(particle_velocity_m_s, particle_force_n, particle_inv_mass, gravity_m_s2, dt_s):
    """v += dt (g + f / m) for free particles (inverse mass > 0)."""
    for p in range(particle_velocity_m_s.shape[0]):
        w = particle_inv_mass[p]
        if w == 0.0:
            continue  # inactive slot or held by a rigid body
        for d in range(3):
            particle_velocity_m_s[p, d] += dt_s * (gravity_m_s2[d] + particle_force_n[p, d] * w)


@nb.njit(cache=True, fastmath=False)
def integrate_positions(particle_position_m, particle_velocity_m_s, particle_active, prev_position_m_out, dt_s):
    """Save the start-of-step positions, then x += dt v for active particles."""
    prev_position_m_out[:] = particle_position_m
    for p in range(particle_position_m.shape[0]):
        if not particle_active[p]:
            continue
        for d in range(3):
            particle_position_m[p, d] += dt_s * particle_velocity_m_s[p, d]


@nb.njit(cache=True, fastmath=False)
def velocities_from_positions(particle_position_m, prev_position_m, particle_active, particle_velocity_m_s,
                              dt_s, speed_limit_m_s):
    """PBD post-process v = (x - x_prev) / dt; returns the first particle that is non-finite or faster
    than speed_limit_m_s (the stability guard), or -1 when all are sane."""
    bad = -1
    inv_dt = 1.0 / dt_s
    for p in range(particle_position_m.shape[0]):
        if not particle_active[p]:
            continue
        s2 = 0.0
        for d in range(3):
            v = (particle_position_m[p, d] - prev_position_m[p, d]) * inv_dt
            particle_velocity_m_s[p, d] = v
            s2 += v * v
        if bad < 0 and not (math.sqrt(s2) <= speed_limit_m_s):  # NaN fails the comparison too
            bad = p
    return bad
