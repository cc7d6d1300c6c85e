"""Air drag and wind (docs/wind.md): the air's velocity at each crossing and the drag it exerts.

The drag law is the quadratic one of a body in a flow (Hoerner 1965, "Fluid-Dynamic Drag", ch. 3 for a flat
plate, ch. 3-9 for a cylinder across the flow): a pressure 1/2 rho C |v| v against the velocity v of the cloth
relative to the air, resolved along the cloth's local normal (coefficient drag_normal) and in its plane
(drag_tangential). A crossing whose weft and warp both still hold it is a patch of cloth of area spacing^2;
a mass on a loose yarn (a frayed end, a torn-off thread) is a length of cylinder of diameter thickness_m,
spacing / 2 per live yarn segment at it, across which the flow presses with drag_normal and along which it
rubs with drag_tangential.

Every crossing writes only its own masses' forces, so the kernels run in parallel over crossings with the same
sums, bit for bit, on any number of threads. A step's drag never more than stops a mass relative to the air:
the impulse of each part of the drag (along the normal and in the plane; along and across a yarn) is capped
at m |v| of that part, so explicit drag on a light mass in a strong wind cannot overshoot and oscillate,
whatever the step.
"""
from __future__ import annotations

import math

import numba as nb


@nb.njit(cache=True, fastmath=False, parallel=True)
def crossing_centres(crossing_count, particle_position_m, particle_mass_kg, particle_active, centre_m_out):
    """Mass-weighted position of each crossing's active masses (base mass, or weft and warp mass of a couple); a
    crossing with none keeps its last value."""
    for c in nb.prange(crossing_count):
        m = 0.0
        x0 = x1 = x2 = 0.0
        for half in range(2):
            p = c + half * crossing_count
            if not particle_active[p]:
                continue
            w = particle_mass_kg[p]
            m += w
            x0 += w * particle_position_m[p, 0]
            x1 += w * particle_position_m[p, 1]
            x2 += w * particle_position_m[p, 2]
        if m > 0.0:
            centre_m_out[c, 0], centre_m_out[c, 1], centre_m_out[c, 2] = x0 / m, x1 / m, x2 / m


@nb.njit(cache=True, fastmath=False, parallel=True)
def air_velocity(point_m, time_s, wind_m_s, gust_wave_per_m, gust_omega_rad_s, gust_phase_rad, gust_amplitude_m_s,
                 air_velocity_m_s_out):
    """The air's velocity at each point: the mean wind plus the gusts' random Fourier modes (fraytool.sim.air)
    u(x, t) = sum_k a_k cos(kappa_k . (x - W t) + omega_k t + phi_k), the field carried along by the mean wind
    W while it changes. No modes: the mean wind alone."""
    modes = gust_wave_per_m.shape[0]
    for n in nb.prange(point_m.shape[0]):
        x0 = point_m[n, 0] - wind_m_s[0] * time_s
        x1 = point_m[n, 1] - wind_m_s[1] * time_s
        x2 = point_m[n, 2] - wind_m_s[2] * time_s
        u0, u1, u2 = wind_m_s[0], wind_m_s[1], wind_m_s[2]
        for k in range(modes):
            c = math.cos(gust_wave_per_m[k, 0] * x0 + gust_wave_per_m[k, 1] * x1 + gust_wave_per_m[k, 2] * x2
                         + gust_omega_rad_s[k] * time_s + gust_phase_rad[k])
            u0 += gust_amplitude_m_s[k, 0] * c
            u1 += gust_amplitude_m_s[k, 1] * c
            u2 += gust_amplitude_m_s[k, 2] * c
        air_velocity_m_s_out[n, 0], air_velocity_m_s_out[n, 1], air_velocity_m_s_out[n, 2] = u0, u1, u2


@nb.njit(cache=True, fastmath=False, inline="always")
def _yarn_direction(c, p, crossing_count, springs_at, spring_alive, spring_particle_a, spring_particle_b,
                    particle_position_m, centre_m):
    """(direction x_next - x_prev along one yarn through crossing c, live segments): springs_at holds the
    crossing's two structural springs of that yarn (-1 for none); only springs whose end is mass p count (p < 0:
    either mass of the crossing). A missing side uses the crossing's centre."""
    d0 = d1 = d2 = 0.0
    live = 0
    for side in range(2):
        s = springs_at[c, side]
        if s < 0 or not spring_alive[s]:
            continue
        a = spring_particle_a[s]
        b = spring_particle_b[s]
        own = a if (a == c or a == crossing_count + c) else b
        if p >= 0 and own != p:
            continue
        other = b if own == a else a
        sign = 1.0 if side == 1 else -1.0
        d0 += sign * (particle_position_m[other, 0] - centre_m[c, 0])
        d1 += sign * (particle_position_m[other, 1] - centre_m[c, 1])
        d2 += sign * (particle_position_m[other, 2] - centre_m[c, 2])
        live += 1
    return d0, d1, d2, live


@nb.njit(cache=True, fastmath=False, inline="always")
def _add_drag_part(p, k, v0, v1, v2, share, dt_s, particle_mass_kg, particle_force_n_inout):
    """Add share x -(k |v| v) [N] to mass p for one part v of its velocity relative to the air (along the normal,
    in the plane, along or across a yarn), the step's impulse capped at m |v|: it can stop that part of the
    motion relative to the air, never reverse it."""
    speed = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    if speed == 0.0 or k == 0.0:
        return
    c = min(share * k * speed, particle_mass_kg[p] / dt_s)
    particle_force_n_inout[p, 0] -= c * v0
    particle_force_n_inout[p, 1] -= c * v1
    particle_force_n_inout[p, 2] -= c * v2


@nb.njit(cache=True, fastmath=False, inline="always")
def _add_drag(p, r0, r1, r2, n0, n1, n2, k_along, k_across, dt_s, particle_mass_kg, particle_force_n_inout):
    """The drag on mass p of relative velocity r split along the unit vector n (coefficient k_along, its share of
    the patch's included) and across it (k_across), each part capped on its own (_add_drag_part)."""
    vn = r0 * n0 + r1 * n1 + r2 * n2
    _add_drag_part(p, k_along, vn * n0, vn * n1, vn * n2, 1.0, dt_s, particle_mass_kg, particle_force_n_inout)
    _add_drag_part(p, k_across, r0 - vn * n0, r1 - vn * n1, r2 - vn * n2, 1.0, dt_s, particle_mass_kg,
                   particle_force_n_inout)


@nb.njit(cache=True, fastmath=False, parallel=True)
def accumulate_air_drag(air_in, particle_position_m, particle_velocity_m_s, particle_mass_kg, particle_active,
                        spring_alive, spring_particle_a, spring_particle_b, centre_m, air_velocity_m_s, dt_s,
                        particle_force_n_inout):
    """Add the air's drag to particle_force_n (module docstring). `air_in` (fraytool.sim.air.AirModel) holds the
    panels' coefficients and the crossings' structural springs; centre_m the crossings' centres
    (crossing_centres), air_velocity_m_s the air's velocity there."""
    n_cross = air_in.crossing_count
    half_rho = air_in.half_density_kg_m3
    sheet_area = air_in.spacing_m * air_in.spacing_m
    for c in nb.prange(n_cross):
        panel = air_in.crossing_panel[c]
        cn = air_in.panel_drag_normal[panel]
        ct = air_in.panel_drag_tangential[panel]
        if cn == 0.0 and ct == 0.0:
            continue
        w0, w1, w2, nw = _yarn_direction(c, -1, n_cross, air_in.crossing_weft_springs, spring_alive,
                                         spring_particle_a, spring_particle_b, particle_position_m, centre_m)
        p0, p1, p2, np_ = _yarn_direction(c, -1, n_cross, air_in.crossing_warp_springs, spring_alive,
                                          spring_particle_a, spring_particle_b, particle_position_m, centre_m)
        x0, x1, x2 = w1 * p2 - w2 * p1, w2 * p0 - w0 * p2, w0 * p1 - w1 * p0
        xl = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
        if nw > 0 and np_ > 0 and xl > 1e-30:  # a patch of cloth: drag on the crossing, shared by mass
            mass = 0.0
            for half in range(2):
                p = c + half * n_cross
                if particle_active[p]:
                    mass += particle_mass_kg[p]
            for half in range(2):
                p = c + half * n_cross
                if not particle_active[p]:
                    continue
                r0 = particle_velocity_m_s[p, 0] - air_velocity_m_s[c, 0]
                r1 = particle_velocity_m_s[p, 1] - air_velocity_m_s[c, 1]
                r2 = particle_velocity_m_s[p, 2] - air_velocity_m_s[c, 2]
                share = particle_mass_kg[p] / mass
                _add_drag(p, r0, r1, r2, x0 / xl, x1 / xl, x2 / xl, share * half_rho * cn * sheet_area,
                          share * half_rho * ct * sheet_area, dt_s, particle_mass_kg, particle_force_n_inout)
            continue
        for half in range(2):  # loose yarn: each mass a length of cylinder along its own yarn
            p = c + half * n_cross
            if not particle_active[p]:
                continue
            t0, t1, t2, nt = _yarn_direction(c, p, n_cross, air_in.crossing_weft_springs, spring_alive,
                                             spring_particle_a, spring_particle_b, particle_position_m, centre_m)
            if nt == 0:
                t0, t1, t2, nt = _yarn_direction(c, p, n_cross, air_in.crossing_warp_springs, spring_alive,
                                                 spring_particle_a, spring_particle_b, particle_position_m, centre_m)
            area = air_in.thickness_m * air_in.spacing_m * 0.5 * max(nt, 1)
            r0 = particle_velocity_m_s[p, 0] - air_velocity_m_s[c, 0]
            r1 = particle_velocity_m_s[p, 1] - air_velocity_m_s[c, 1]
            r2 = particle_velocity_m_s[p, 2] - air_velocity_m_s[c, 2]
            tl = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
            if tl > 1e-30:  # along the yarn: ct; across it: cn
                _add_drag(p, r0, r1, r2, t0 / tl, t1 / tl, t2 / tl, half_rho * ct * area, half_rho * cn * area,
                          dt_s, particle_mass_kg, particle_force_n_inout)
            else:  # a lone mass: pressed from every side alike
                _add_drag_part(p, half_rho * cn * area, r0, r1, r2, 1.0, dt_s, particle_mass_kg,
                               particle_force_n_inout)
